// Streaming readers and writers for the stream files of a scene (docs/scene-format.md):
// <device>/audio.wav, imu.csv, ble.csv, sync.csv and truth.csv.
//
// Every reader streams: it holds one block (or one CSV row) in memory, never the whole file, so hours
// of recording replay with bounded memory. Readers are strict about what the format requires and
// tolerant of what it allows; every problem is thrown as a SceneError (scene.hpp) whose issue names
// the file and the line:column (CSV) or byte offset (WAV) and what was expected.
//
// Threading: each object is single-threaded; distinct objects are independent. None of this is
// real-time safe (file I/O); the replay backend reads ahead on a non-RT thread.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "locus/events.hpp"
#include "locus/scene/scene.hpp"
#include "locus/signal.hpp"

namespace locus::scene {

// ---------------------------------------------------------------------------------------------------
// WAV

/// Sample encodings accepted in audio.wav (PCM int16/int24/int32, IEEE float32).
enum class WavSampleFormat { Int16, Int24, Int32, Float32 };

/// "int16", "int24", "int32", "float32".
const char* to_string(WavSampleFormat f) noexcept;
/// Bytes per sample of one channel (2, 3, 4, 4).
int bytes_per_sample(WavSampleFormat f) noexcept;

/// What a WAV header says, as validated by read_wav_info().
struct WavInfo {
  int channels = 0;
  double sample_rate_hz = 0.0;
  std::uint64_t frames = 0;               ///< frames actually present in the file (after truncation)
  WavSampleFormat sample_format = WavSampleFormat::Float32;
  bool extensible = false;                ///< fmt tag was WAVE_FORMAT_EXTENSIBLE (0xFFFE)
  std::uint64_t fmt_offset = 0;           ///< byte offset of the fmt chunk body (format tag)
  std::uint64_t data_offset = 0;          ///< byte offset of the first sample
  std::uint64_t declared_data_bytes = 0;  ///< data chunk size as declared in the header
  bool truncated = false;                 ///< the file ends before the declared data chunk does
};

/// Validates the RIFF/WAVE/fmt /data headers of `path` without reading samples (cheap). Throws
/// SceneError naming the file, the byte offset and what was expected. A data chunk that is shorter
/// than declared is not an error here: it is reported through WavInfo::truncated / frames.
///
/// Integer samples convert to float as v / 2^(bits−1) (int16: v/32768), exactly what WavWriter
/// inverts, so float → int → float round trips are exact for values on the quantisation grid.
WavInfo read_wav_info(const std::string& path);

/// Streams interleaved float samples out of a WAV file, block by block.
///
/// Truncated files (data chunk shorter than its header declares, e.g. a recorder that crashed): the
/// frames that are present are delivered, truncated() is true and truncation_message() says what was
/// expected; a trailing partial frame is dropped. It does not throw mid-stream for this, so no
/// accepted data is lost; callers that require complete files check truncated() after open.
class WavReader {
 public:
  /// Opens and validates the header (read_wav_info). Throws SceneError.
  explicit WavReader(const std::string& path);
  ~WavReader();
  WavReader(const WavReader&) = delete;
  WavReader& operator=(const WavReader&) = delete;
  WavReader(WavReader&&) noexcept;
  WavReader& operator=(WavReader&&) noexcept;

  const WavInfo& info() const noexcept { return info_; }
  const std::string& path() const noexcept { return path_; }
  bool truncated() const noexcept { return info_.truncated; }
  /// "" unless truncated(): "file: byte N: data chunk declares X bytes, file holds Y (Z frames kept)".
  std::string truncation_message() const;

  /// Reads up to `max_frames` frames into `interleaved` (room for max_frames·channels floats).
  /// Returns the number of frames read; 0 at the end. Throws SceneError on an I/O error.
  std::size_t read(float* interleaved, std::size_t max_frames);
  /// Next frame to be read (0-based).
  std::uint64_t position() const noexcept { return position_; }
  /// Moves to `frame` (clamped to frames()). Throws SceneError if the file cannot seek.
  void seek(std::uint64_t frame);

 private:
  std::string path_;
  WavInfo info_;
  void* sndfile_ = nullptr;  // SNDFILE*
  std::uint64_t position_ = 0;
};

/// Streams interleaved float samples into a RIFF/WAVE file (PCM int16/24/32 or IEEE float32).
/// Integers are quantised as clamp(round(x·2^(bits−1)), −2^(bits−1), 2^(bits−1)−1); float32 is
/// written as is. Sizes in the header are updated by close() (also called by the destructor, which
/// swallows errors: call close() to see them).
class WavWriter {
 public:
  /// Creates/truncates `path`. Throws std::runtime_error naming the file on failure, and
  /// std::invalid_argument for channels < 1 or a rate that is not a positive integer.
  WavWriter(const std::string& path, int channels, double sample_rate_hz,
            WavSampleFormat fmt = WavSampleFormat::Float32);
  ~WavWriter();
  WavWriter(const WavWriter&) = delete;
  WavWriter& operator=(const WavWriter&) = delete;

  /// Appends `frames` frames (frames·channels floats). Throws std::runtime_error on I/O failure.
  void write(const float* interleaved, std::size_t frames);
  /// Finalises the header and closes the file. Idempotent.
  void close();
  std::uint64_t frames_written() const noexcept { return frames_; }
  int channels() const noexcept { return channels_; }

 private:
  std::string path_;
  int channels_ = 0;
  WavSampleFormat fmt_;
  void* sndfile_ = nullptr;  // SNDFILE*
  std::uint64_t frames_ = 0;
  std::vector<int> ibuf_;    // integer conversion block
};

// ---------------------------------------------------------------------------------------------------
// CSV

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

  std::string path_;
  std::FILE* file_ = nullptr;
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
/// BLE addresses "AA:BB:CC:DD:EE:FF": one parser and formatter, with the signal description
/// (locus/signal.hpp), where a ble signal's address is checked.
using locus::format_ble_address;
using locus::parse_ble_address;

/// imu.csv: t, ax, ay, az, gx, gy, gz required; mx, my, mz optional (all three or none; a row with
/// all three cells empty has has_mag = false). Rows must be in non-decreasing t.
class ImuCsvReader {
 public:
  ImuCsvReader(const std::string& path, DeviceId device);
  /// Next sample; false at the end. Throws SceneError.
  bool next(ImuSample& out);
  bool has_mag_columns() const noexcept { return mag_[0].has_value(); }

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, a_[3], g_[3];
  std::optional<std::size_t> mag_[3];
  double last_t_ = -1e300;
  int last_line_ = 0;
};

/// ble.csv: t, address, rssi required; tx_power (empty cell = absent), channel (0 or 37..39; empty =
/// unknown) optional. Row order is not required by the format and not checked.
class BleCsvReader {
 public:
  BleCsvReader(const std::string& path, DeviceId device);
  bool next(BleAdvertisement& out);

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, address_, rssi_;
  std::optional<std::size_t> tx_power_, channel_;
};

/// sync.csv: t, source (a non-empty id of at most NameTag::max_size() characters).
class SyncCsvReader {
 public:
  SyncCsvReader(const std::string& path, DeviceId device);
  bool next(RadioSync& out);

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, source_;
};

/// One row of truth.csv: true time, object id, world position, attitude (unit quaternion w,x,y,z).
struct TruthRow {
  double t_s = 0.0;
  std::string id;
  Vec3 position_m{};
  std::array<double, 4> q_wxyz{1.0, 0.0, 0.0, 0.0};
};

/// truth.csv: t, id, x, y, z, qw, qx, qy, qz; rows sorted by t. The quaternion must have a norm within
/// 1e-3 of 1 (it is returned normalised).
class TruthCsvReader {
 public:
  explicit TruthCsvReader(const std::string& path);
  bool next(TruthRow& out);

 private:
  CsvReader csv_;
  std::size_t t_, id_, p_[3], q_[4];
  double last_t_ = -1e300;
  int last_line_ = 0;
};

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

/// Writes imu.csv (t, ax..gz, and mx,my,mz when `with_mag`; samples without has_mag get empty cells).
class ImuCsvWriter : public CsvWriter {
 public:
  ImuCsvWriter(const std::string& path, bool with_mag);
  void write(const ImuSample& s);

 private:
  bool with_mag_;
};

/// Writes ble.csv (t, address, rssi, tx_power, channel; tx_power empty when !has_tx_power).
class BleCsvWriter : public CsvWriter {
 public:
  explicit BleCsvWriter(const std::string& path);
  void write(const BleAdvertisement& a);
};

/// Writes sync.csv (t, source).
class SyncCsvWriter : public CsvWriter {
 public:
  explicit SyncCsvWriter(const std::string& path);
  void write(const RadioSync& s);
};

/// Writes truth.csv (t, id, x, y, z, qw, qx, qy, qz). Rows must be written in non-decreasing t.
class TruthCsvWriter : public CsvWriter {
 public:
  explicit TruthCsvWriter(const std::string& path);
  void write(const TruthRow& r);
};

// ---------------------------------------------------------------------------------------------------
// Ground-truth trajectories

struct Pose {
  Vec3 position_m{};
  std::array<double, 4> q_wxyz{1.0, 0.0, 0.0, 0.0};
};

/// All trajectories of a truth.csv, in memory (evaluation only; ~100 bytes per row).
/// pose_at() interpolates position linearly and attitude by slerp (shortest arc), and holds the first
/// or last pose outside the recorded time range; an object with one row is static.
class TruthTrajectories {
 public:
  TruthTrajectories() = default;
  /// Loads truth.csv. Throws SceneError.
  static TruthTrajectories load(const std::string& path);
  /// Adds a row (rows of one id must come in non-decreasing t; throws std::invalid_argument otherwise).
  void add(const TruthRow& row);

  bool has(const std::string& id) const;
  std::vector<std::string> ids() const;
  /// Pose of `id` at true time `t_true_s`. Throws std::out_of_range for an unknown id.
  Pose pose_at(const std::string& id, double t_true_s) const;
  /// Time range over all ids ({0,0} when empty).
  double t_begin_s() const noexcept { return t_begin_; }
  double t_end_s() const noexcept { return t_end_; }
  /// Time range of one id. Throws std::out_of_range for an unknown id.
  std::pair<double, double> time_range(const std::string& id) const;

 private:
  struct Track {
    std::vector<double> t;
    std::vector<Pose> pose;
  };
  std::map<std::string, Track> tracks_;
  double t_begin_ = 0.0, t_end_ = 0.0;
};

/// Spherical linear interpolation of unit quaternions (w,x,y,z), shortest arc, u in [0,1].
std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u) noexcept;

}  // namespace locus::scene
