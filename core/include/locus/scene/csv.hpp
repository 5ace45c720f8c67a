// The CSV layer of the scene's stream files (docs/scene-format.md): a strict streaming RFC 4180
// reader that tracks line:column for its errors, a writer, and the shortest round-trip number
// formatting every writer uses. The typed files are imu_csv.hpp, ble_csv.hpp, sync_csv.hpp and
// truth.hpp. Single-threaded, file I/O (not real-time).
#pragma once

#include <cstddef>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "locus/scene/scene.hpp"

namespace locus::scene {

/// A strict streaming RFC 4180 CSV reader with a header row.
///
/// Columns are found by name (order free, unknown columns ignored). Tolerated: a UTF-8 BOM, CRLF or LF
/// line ends, blank lines at the end of the file, spaces around numbers. Every row must have as many
/// fields as the header. Quoted fields may contain commas, doubled quotes and line breaks.
/// Errors: "file:line:column: column 'ax': expected a number, got 'abc'".
class CsvReader {
 public:
  /// Opens the file and reads the header row. Throws SceneError (missing file, empty file, empty or
  /// duplicate column names).
  explicit CsvReader(const std::string& path);
  ~CsvReader();
  CsvReader(const CsvReader&) = delete;
  CsvReader& operator=(const CsvReader&) = delete;

  const std::string& path() const noexcept { return path_; }
  const std::vector<std::string>& header() const noexcept { return header_; }
  /// Index of the column named `name`, if the header has it.
  std::optional<std::size_t> find_column(std::string_view name) const;
  /// Index of the column named `name`; throws SceneError at the header ("file:1:1: missing required
  /// column 'ax' (header has: t, ay, ...)").
  std::size_t require_column(std::string_view name) const;

  /// Advances to the next data row; false at the end of the file. Throws SceneError for a malformed
  /// row (wrong field count, bad quoting).
  bool next_row();
  /// Raw text of field `col` of the current row (unquoted).
  std::string_view field(std::size_t col) const;
  /// 1-based line and column where field `col` of the current row starts.
  int line(std::size_t col) const;
  int column(std::size_t col) const;
  /// Line where the current row starts.
  int row_line() const noexcept { return row_line_; }

  /// Field `col` as a finite double (surrounding blanks allowed). Throws SceneError otherwise.
  double number(std::size_t col) const;
  /// Field `col` as an integer in [lo, hi]. Throws SceneError otherwise.
  long long integer(std::size_t col, long long lo, long long hi) const;
  /// True when field `col` is empty or blank.
  bool blank(std::size_t col) const;
  /// Throws a SceneError located at field `col` of the current row: "column 'name': <message>".
  [[noreturn]] void fail(std::size_t col, const std::string& message) const;
  /// A SceneIssue located at field `col` of the current row.
  SceneIssue issue(std::size_t col, const std::string& message) const;

 private:
  bool fill();  // refills buf_; false at EOF
  int get();    // next byte or -1
  int peek();
  bool read_record(bool header);  // parses one record into fields_; false at EOF

  struct FileCloser {
    void operator()(std::FILE* f) const noexcept { std::fclose(f); }
  };
  std::string path_;
  // Owned, so that every exception out of the constructor (a malformed header row) closes it too.
  std::unique_ptr<std::FILE, FileCloser> file_;
  std::vector<char> buf_;
  std::size_t pos_ = 0, len_ = 0;
  bool eof_ = false;
  int cur_line_ = 1, cur_col_ = 1;
  std::vector<std::string> header_;
  std::vector<std::string> fields_;
  std::vector<std::pair<int, int>> where_;  // line, column of each field
  int row_line_ = 0;
};

/// Formats a double in the shortest form that parses back to the same value ("0.1", "1e-09").
std::string format_double(double v);
/// Formats a float in the shortest form that parses back to the same float.
std::string format_float(float v);

/// Common part of the CSV writers: creates/truncates the file, writes the header, LF line ends.
class CsvWriter {
 public:
  CsvWriter(const std::string& path, const std::vector<std::string>& header);
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;
  /// Writes one row of already formatted fields (quoted when they need it).
  void row(const std::vector<std::string>& fields);
  /// Flushes and closes; throws std::runtime_error naming the file on I/O failure. Idempotent.
  void close();
  const std::string& path() const noexcept { return path_; }

 protected:
  void put(std::string_view s);
  void end_row();

 private:
  std::string path_;
  std::FILE* file_ = nullptr;
  std::size_t columns_ = 0;
};

}  // namespace locus::scene
