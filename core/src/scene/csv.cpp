// The CSV layer (csv.hpp): a hand-written byte-level RFC 4180 parser over a 64 KiB buffer, tracking
// line:column for every error, the writer, and shortest round-trip number formatting.
#include "locus/scene/csv.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "stream_detail.hpp"

namespace locus::scene {

using detail::shown;
using detail::throw_file;
using detail::trim;

CsvReader::CsvReader(const std::string& path) : path_(path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw_file(path, "no such file (expected a CSV file)");
  file_.reset(std::fopen(path.c_str(), "rb"));
  if (!file_) throw_file(path, std::string("cannot open: ") + std::strerror(errno));
  buf_.resize(64 * 1024);
  // UTF-8 byte order mark
  if (peek() == 0xEF) {
    fill();
    if (len_ - pos_ >= 3 && static_cast<unsigned char>(buf_[pos_ + 1]) == 0xBB &&
        static_cast<unsigned char>(buf_[pos_ + 2]) == 0xBF) {
      pos_ += 3;
    }
  }
  if (!read_record(true)) {
    SceneIssue is{path_, 1, 1, -1, "empty file (expected a header row)"};
    file_.reset();
    throw SceneError({is});
  }
  header_.assign(fields_.begin(), fields_.end());
  for (std::size_t i = 0; i < header_.size(); ++i) {
    std::string& h = header_[i];
    const auto b = h.find_first_not_of(" \t");
    const auto e = h.find_last_not_of(" \t");
    h = b == std::string::npos ? std::string() : h.substr(b, e - b + 1);
    auto fail_header = [&](const std::string& msg) {
      SceneIssue is{path_, where_[i].first, where_[i].second, -1, msg};
      file_.reset();
      throw SceneError({is});
    };
    if (h.empty()) fail_header("empty column name in the header (column " + std::to_string(i + 1) + ")");
    for (std::size_t j = 0; j < i; ++j)
      if (header_[j] == h) fail_header("duplicate column name '" + h + "' in the header");
  }
}

CsvReader::~CsvReader() = default;

bool CsvReader::fill() {
  if (pos_ < len_) return true;
  if (eof_ || !file_) return false;
  len_ = std::fread(buf_.data(), 1, buf_.size(), file_.get());
  pos_ = 0;
  if (len_ == 0) {
    if (std::ferror(file_.get())) throw_file(path_, "read error at line " + std::to_string(cur_line_));
    eof_ = true;
    return false;
  }
  return true;
}

int CsvReader::peek() {
  if (pos_ >= len_ && !fill()) return -1;
  return static_cast<unsigned char>(buf_[pos_]);
}

int CsvReader::get() {
  if (pos_ >= len_ && !fill()) return -1;
  const int c = static_cast<unsigned char>(buf_[pos_++]);
  if (c == '\n') {
    ++cur_line_;
    cur_col_ = 1;
  } else {
    ++cur_col_;
  }
  return c;
}

bool CsvReader::read_record(bool header) {
  // skip blank lines; they are allowed only at the end of the file
  int blank_line = 0;
  while (true) {
    const int c = peek();
    if (c == -1) return false;
    if (c == '\r' || c == '\n') {
      if (blank_line == 0) blank_line = cur_line_;
      get();
      continue;
    }
    break;
  }
  if (blank_line != 0 && !header) {
    SceneIssue is{path_, blank_line, 1, -1,
                  "blank line inside the data (blank lines are allowed only at the end of the file)"};
    throw SceneError({is});
  }
  row_line_ = cur_line_;
  std::size_t nf = 0;
  while (true) {
    if (fields_.size() <= nf) fields_.emplace_back();
    if (where_.size() <= nf) where_.emplace_back();
    std::string& f = fields_[nf];
    f.clear();
    where_[nf] = {cur_line_, cur_col_};
    ++nf;
    int c = peek();
    if (c == '"') {
      get();
      while (true) {
        c = get();
        if (c == -1) {
          SceneIssue is{path_, where_[nf - 1].first, where_[nf - 1].second, -1,
                        "unterminated quoted field (expected a closing '\"' before the end of the file)"};
          throw SceneError({is});
        }
        if (c == '"') {
          if (peek() == '"') {
            get();
            f.push_back('"');
            continue;
          }
          break;
        }
        f.push_back(static_cast<char>(c));
      }
      c = peek();
      if (c != ',' && c != '\r' && c != '\n' && c != -1) {
        SceneIssue is{path_, cur_line_, cur_col_, -1,
                      std::string("expected ',' or the end of the line after a closing quote, got '") +
                          static_cast<char>(c) + "'"};
        throw SceneError({is});
      }
    } else {
      while (true) {
        c = peek();
        if (c == ',' || c == '\r' || c == '\n' || c == -1) break;
        if (c == '"') {
          SceneIssue is{path_, cur_line_, cur_col_, -1,
                        "quote inside an unquoted field (expected the whole field quoted, RFC 4180)"};
          throw SceneError({is});
        }
        f.push_back(static_cast<char>(c));
        get();
      }
    }
    if (c == ',') {
      get();
      continue;
    }
    // end of record
    if (c == '\r') {
      get();
      if (peek() == '\n') get();
    } else if (c == '\n') {
      get();
    }
    break;
  }
  if (!header && nf != header_.size()) {
    SceneIssue is{path_, row_line_, 1, -1,
                  "expected " + std::to_string(header_.size()) + " fields (as in the header), got " +
                      std::to_string(nf)};
    throw SceneError({is});
  }
  if (header) {
    fields_.resize(nf);
    where_.resize(nf);
  }
  return true;
}

std::optional<std::size_t> CsvReader::find_column(std::string_view name) const {
  for (std::size_t i = 0; i < header_.size(); ++i)
    if (header_[i] == name) return i;
  return std::nullopt;
}

std::size_t CsvReader::require_column(std::string_view name) const {
  if (auto i = find_column(name)) return *i;
  std::string have;
  for (const auto& h : header_) have += (have.empty() ? "" : ", ") + h;
  SceneIssue is{path_, 1, 1, -1, "missing required column '" + std::string(name) + "' (header has: " + have + ")"};
  throw SceneError({is});
}

bool CsvReader::next_row() { return read_record(false); }

std::string_view CsvReader::field(std::size_t col) const { return fields_.at(col); }
int CsvReader::line(std::size_t col) const { return where_.at(col).first; }
int CsvReader::column(std::size_t col) const { return where_.at(col).second; }

SceneIssue CsvReader::issue(std::size_t col, const std::string& message) const {
  SceneIssue is;
  is.file = path_;
  is.line = col < where_.size() ? where_[col].first : row_line_;
  is.column = col < where_.size() ? where_[col].second : 1;
  is.message = "column '" + (col < header_.size() ? header_[col] : std::string("?")) + "': " + message;
  return is;
}

void CsvReader::fail(std::size_t col, const std::string& message) const { throw SceneError({issue(col, message)}); }

bool CsvReader::blank(std::size_t col) const { return trim(field(col)).empty(); }

double CsvReader::number(std::size_t col) const {
  const std::string_view s = trim(field(col));
  if (s.empty()) fail(col, "expected a number, got an empty field");
  std::string_view p = s;
  if (p.front() == '+') p.remove_prefix(1);
  double v = 0.0;
  const auto r = std::from_chars(p.data(), p.data() + p.size(), v);
  if (r.ec == std::errc::result_out_of_range) fail(col, "number " + shown(s) + " is out of range");
  if (r.ec != std::errc() || r.ptr != p.data() + p.size()) fail(col, "expected a number, got " + shown(s));
  if (!std::isfinite(v)) fail(col, "expected a finite number, got " + shown(s));
  return v;
}

long long CsvReader::integer(std::size_t col, long long lo, long long hi) const {
  const std::string_view s = trim(field(col));
  if (s.empty()) fail(col, "expected an integer, got an empty field");
  std::string_view p = s;
  if (p.front() == '+') p.remove_prefix(1);
  long long v = 0;
  const auto r = std::from_chars(p.data(), p.data() + p.size(), v);
  if (r.ec != std::errc() || r.ptr != p.data() + p.size()) fail(col, "expected an integer, got " + shown(s));
  if (v < lo || v > hi)
    fail(col, "integer " + std::string(s) + " out of range (expected " + std::to_string(lo) + ".." + std::to_string(hi) + ")");
  return v;
}

std::string format_double(double v) {
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v);
  return std::string(b, r.ptr);
}

std::string format_float(float v) {
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v);
  return std::string(b, r.ptr);
}

CsvWriter::CsvWriter(const std::string& path, const std::vector<std::string>& header)
    : path_(path), columns_(header.size()) {
  file_ = std::fopen(path.c_str(), "wb");
  if (!file_) throw std::runtime_error(path + ": cannot create: " + std::strerror(errno));
  std::setvbuf(file_, nullptr, _IOFBF, 1 << 16);
  row(header);
}

CsvWriter::~CsvWriter() {
  try {
    close();
  } catch (...) {
  }
}

void CsvWriter::put(std::string_view s) {
  if (!file_) throw std::runtime_error(path_ + ": write after close");
  if (std::fwrite(s.data(), 1, s.size(), file_) != s.size())
    throw std::runtime_error(path_ + ": write failed: " + std::strerror(errno));
}

void CsvWriter::end_row() { put("\n"); }

void CsvWriter::row(const std::vector<std::string>& fields) {
  if (fields.size() != columns_)
    throw std::invalid_argument(path_ + ": row of " + std::to_string(fields.size()) + " fields, header has " +
                                std::to_string(columns_));
  for (std::size_t i = 0; i < fields.size(); ++i) {
    if (i) put(",");
    const std::string& f = fields[i];
    if (f.find_first_of(",\"\r\n") != std::string::npos) {
      std::string q = "\"";
      for (char c : f) {
        if (c == '"') q += '"';
        q += c;
      }
      q += '"';
      put(q);
    } else {
      put(f);
    }
  }
  end_row();
}

void CsvWriter::close() {
  if (!file_) return;
  std::FILE* f = file_;
  file_ = nullptr;
  const bool bad = std::fflush(f) != 0 || std::ferror(f);
  if (std::fclose(f) != 0 || bad) throw std::runtime_error(path_ + ": write failed on close");
}

}  // namespace locus::scene
