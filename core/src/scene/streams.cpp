// Streaming WAV and CSV I/O of the scene format.
//
// WAV: the RIFF/WAVE/fmt /data headers are parsed here (so errors can name byte offsets and the value
// expected); samples are then read and written with libsndfile. Integer conversion is done here on the
// write side because libsndfile's float→int scaling (0x7FFF) is not the inverse of its int→float
// scaling (1/0x8000); with v/2^(bits−1) both ways, quantised values round-trip exactly.
// CSV: a hand-written byte-level RFC 4180 parser over a 64 KiB buffer, tracking line:column.
#include "locus/scene/streams.hpp"

#include <sndfile.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <system_error>

namespace locus::scene {

namespace {

[[noreturn]] void throw_at_byte(const std::string& file, long long byte, const std::string& msg) {
  SceneIssue is;
  is.file = file;
  is.byte_offset = byte;
  is.message = msg;
  throw SceneError({is});
}

[[noreturn]] void throw_file(const std::string& file, const std::string& msg) {
  SceneIssue is;
  is.file = file;
  is.message = msg;
  throw SceneError({is});
}

std::uint32_t le32(const unsigned char* p) {
  return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[3]) << 24);
}
std::uint16_t le16(const unsigned char* p) { return std::uint16_t(p[0] | (p[1] << 8)); }

std::string fourcc_text(const unsigned char* p) {
  std::string s;
  for (int i = 0; i < 4; ++i) {
    const unsigned char c = p[i];
    if (c >= 32 && c < 127) {
      s += char(c);
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02X", c);
      s += b;
    }
  }
  return "'" + s + "'";
}

struct FileCloser {
  void operator()(std::FILE* f) const noexcept {
    if (f) std::fclose(f);
  }
};
using FilePtr = std::unique_ptr<std::FILE, FileCloser>;

// KSDATAFORMAT_SUBTYPE_* GUID tail shared by PCM (1) and IEEE float (3).
constexpr unsigned char kGuidTail[14] = {0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80,
                                         0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71};

}  // namespace

const char* to_string(WavSampleFormat f) noexcept {
  switch (f) {
    case WavSampleFormat::Int16: return "int16";
    case WavSampleFormat::Int24: return "int24";
    case WavSampleFormat::Int32: return "int32";
    case WavSampleFormat::Float32: return "float32";
  }
  return "?";
}

int bytes_per_sample(WavSampleFormat f) noexcept {
  switch (f) {
    case WavSampleFormat::Int16: return 2;
    case WavSampleFormat::Int24: return 3;
    case WavSampleFormat::Int32: return 4;
    case WavSampleFormat::Float32: return 4;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------------
// WAV header

WavInfo read_wav_info(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw_file(path, "no such file (expected a RIFF/WAVE audio file)");
  const auto size_u = std::filesystem::file_size(path, ec);
  if (ec) throw_file(path, "cannot read file size: " + ec.message());
  const long long file_size = static_cast<long long>(size_u);
  FilePtr f(std::fopen(path.c_str(), "rb"));
  if (!f) throw_file(path, std::string("cannot open: ") + std::strerror(errno));

  auto read_at = [&](long long off, unsigned char* dst, std::size_t n) -> std::size_t {
    if (std::fseek(f.get(), static_cast<long>(off), SEEK_SET) != 0) return 0;
    return std::fread(dst, 1, n, f.get());
  };

  unsigned char h[12];
  const std::size_t got = read_at(0, h, 12);
  if (got < 12)
    throw_at_byte(path, static_cast<long long>(got),
                  "truncated header: file ends after " + std::to_string(file_size) +
                      " bytes (expected a 12-byte RIFF/WAVE header)");
  if (std::memcmp(h, "RIFF", 4) != 0)
    throw_at_byte(path, 0, "expected 'RIFF', got " + fourcc_text(h) + " (not a RIFF/WAVE file)");
  if (std::memcmp(h + 8, "WAVE", 4) != 0) throw_at_byte(path, 8, "expected 'WAVE', got " + fourcc_text(h + 8));

  WavInfo info;
  bool have_fmt = false;
  int bits = 0;
  int block_align = 0;
  long long off = 12;
  while (true) {
    unsigned char ch[8];
    const std::size_t n = off < file_size ? read_at(off, ch, 8) : 0;
    if (n < 8) {
      throw_at_byte(path, off,
                    std::string("truncated header: expected a chunk header (") + (have_fmt ? "'data'" : "'fmt '") +
                        "), file ends at byte " + std::to_string(file_size));
    }
    const std::uint32_t csize = le32(ch + 4);
    const long long body = off + 8;
    if (std::memcmp(ch, "fmt ", 4) == 0) {
      if (have_fmt) throw_at_byte(path, off, "second 'fmt ' chunk (expected exactly one)");
      if (csize < 16) throw_at_byte(path, off + 4, "fmt chunk size " + std::to_string(csize) + ", expected >= 16");
      unsigned char fm[40] = {};
      const std::size_t want = std::min<std::size_t>(csize, 40);
      if (read_at(body, fm, want) < want)
        throw_at_byte(path, body, "truncated header: fmt chunk declares " + std::to_string(csize) +
                                      " bytes, file ends at byte " + std::to_string(file_size));
      std::uint16_t tag = le16(fm);
      const int channels = le16(fm + 2);
      const std::uint32_t rate = le32(fm + 4);
      block_align = le16(fm + 12);
      bits = le16(fm + 14);
      if (tag == 0xFFFE) {
        info.extensible = true;
        if (csize < 40)
          throw_at_byte(path, off + 4, "WAVE_FORMAT_EXTENSIBLE fmt chunk size " + std::to_string(csize) +
                                           ", expected >= 40");
        if (std::memcmp(fm + 26, kGuidTail, 14) != 0 || fm[25] != 0)
          throw_at_byte(path, body + 24,
                        "unsupported WAVE_FORMAT_EXTENSIBLE sub-format GUID (expected PCM or IEEE float)");
        tag = le16(fm + 24);
        if (tag != 1 && tag != 3) {
          char b[64];
          std::snprintf(b, sizeof b, "unsupported sub-format 0x%04X", tag);
          throw_at_byte(path, body + 24, std::string(b) + " (expected 0x0001 PCM or 0x0003 IEEE float)");
        }
      } else if (tag != 1 && tag != 3) {
        char b[64];
        std::snprintf(b, sizeof b, "unsupported format tag 0x%04X", tag);
        throw_at_byte(path, body,
                      std::string(b) + " (expected 0x0001 PCM, 0x0003 IEEE float or 0xFFFE extensible)");
      }
      if (channels < 1) throw_at_byte(path, body + 2, "channel count 0, expected >= 1");
      if (rate == 0) throw_at_byte(path, body + 4, "sample rate 0, expected > 0");
      if (tag == 1) {
        if (bits == 16) info.sample_format = WavSampleFormat::Int16;
        else if (bits == 24) info.sample_format = WavSampleFormat::Int24;
        else if (bits == 32) info.sample_format = WavSampleFormat::Int32;
        else
          throw_at_byte(path, body + 14, "PCM with " + std::to_string(bits) +
                                             " bits per sample, expected 16, 24 or 32");
      } else {
        if (bits != 32)
          throw_at_byte(path, body + 14, "IEEE float with " + std::to_string(bits) +
                                             " bits per sample, expected 32 (float64 is not supported)");
        info.sample_format = WavSampleFormat::Float32;
      }
      const int expect_align = channels * bits / 8;
      if (block_align != expect_align)
        throw_at_byte(path, body + 12, "block align " + std::to_string(block_align) + ", expected " +
                                           std::to_string(expect_align) + " (channels x bytes per sample)");
      info.channels = channels;
      info.sample_rate_hz = static_cast<double>(rate);
      info.fmt_offset = static_cast<std::uint64_t>(body);
      have_fmt = true;
      off = body + static_cast<long long>(csize) + (csize & 1u);
    } else if (std::memcmp(ch, "data", 4) == 0) {
      if (!have_fmt) throw_at_byte(path, off, "'data' chunk before the 'fmt ' chunk (expected 'fmt ' first)");
      info.data_offset = static_cast<std::uint64_t>(body);
      info.declared_data_bytes = csize;
      const std::uint64_t avail = static_cast<std::uint64_t>(std::max<long long>(0, file_size - body));
      std::uint64_t usable = csize;
      if (csize == 0xFFFFFFFFu) {
        usable = avail;  // streaming writers: size unknown, data runs to the end of the file
      } else if (csize > avail) {
        usable = avail;
        info.truncated = true;
      }
      info.frames = usable / static_cast<std::uint64_t>(block_align);
      return info;
    } else {
      // any other chunk (LIST, fact, PEAK, JUNK, ...) is skipped; chunks are padded to even sizes
      const long long next = body + static_cast<long long>(csize) + (csize & 1u);
      if (next > file_size)
        throw_at_byte(path, off, "truncated header: chunk " + fourcc_text(ch) + " declares " + std::to_string(csize) +
                                     " bytes, file ends at byte " + std::to_string(file_size) +
                                     " (expected a 'data' chunk)");
      off = next;
    }
  }
}

// ---------------------------------------------------------------------------------------------------
// WavReader

WavReader::WavReader(const std::string& path) : path_(path), info_(read_wav_info(path)) {
  SF_INFO sfi{};
  SNDFILE* sf = sf_open(path.c_str(), SFM_READ, &sfi);
  if (!sf) throw_at_byte(path, 0, std::string("libsndfile cannot read the file: ") + sf_strerror(nullptr));
  if (sfi.channels != info_.channels) {
    sf_close(sf);
    throw_at_byte(path, static_cast<long long>(info_.fmt_offset) + 2, "libsndfile reads " + std::to_string(sfi.channels) + " channels, header says " +
                                std::to_string(info_.channels));
  }
  sf_command(sf, SFC_SET_NORM_FLOAT, nullptr, SF_TRUE);
  // libsndfile may count a different number of frames for odd files; never read past either count.
  if (sfi.frames >= 0 && static_cast<std::uint64_t>(sfi.frames) < info_.frames) {
    info_.frames = static_cast<std::uint64_t>(sfi.frames);
  }
  sndfile_ = sf;
}

WavReader::~WavReader() {
  if (sndfile_) sf_close(static_cast<SNDFILE*>(sndfile_));
}

WavReader::WavReader(WavReader&& o) noexcept
    : path_(std::move(o.path_)), info_(o.info_), sndfile_(o.sndfile_), position_(o.position_) {
  o.sndfile_ = nullptr;
}

WavReader& WavReader::operator=(WavReader&& o) noexcept {
  if (this != &o) {
    if (sndfile_) sf_close(static_cast<SNDFILE*>(sndfile_));
    path_ = std::move(o.path_);
    info_ = o.info_;
    sndfile_ = o.sndfile_;
    position_ = o.position_;
    o.sndfile_ = nullptr;
  }
  return *this;
}

std::string WavReader::truncation_message() const {
  if (!info_.truncated) return "";
  const std::uint64_t bytes_present = info_.frames * static_cast<std::uint64_t>(info_.channels) *
                                      static_cast<std::uint64_t>(bytes_per_sample(info_.sample_format));
  SceneIssue is;
  is.file = path_;
  is.byte_offset = static_cast<long long>(info_.data_offset - 4);
  is.message = "truncated data chunk: header declares " + std::to_string(info_.declared_data_bytes) +
               " bytes, the file holds " + std::to_string(bytes_present) + " (" + std::to_string(info_.frames) +
               " whole frames kept)";
  return is.format();
}

std::size_t WavReader::read(float* interleaved, std::size_t max_frames) {
  if (!sndfile_ || position_ >= info_.frames || max_frames == 0) return 0;
  const std::uint64_t want = std::min<std::uint64_t>(max_frames, info_.frames - position_);
  const sf_count_t got = sf_readf_float(static_cast<SNDFILE*>(sndfile_), interleaved, static_cast<sf_count_t>(want));
  if (got < 0 || static_cast<std::uint64_t>(got) != want) {
    const std::uint64_t frame = position_ + static_cast<std::uint64_t>(std::max<sf_count_t>(got, 0));
    const std::uint64_t block = static_cast<std::uint64_t>(info_.channels) * bytes_per_sample(info_.sample_format);
    throw_at_byte(path_, static_cast<long long>(info_.data_offset + frame * block),
                  "read error at frame " + std::to_string(frame) + " (expected " + std::to_string(info_.frames) +
                      " frames): " + sf_strerror(static_cast<SNDFILE*>(sndfile_)));
  }
  position_ += static_cast<std::uint64_t>(got);
  return static_cast<std::size_t>(got);
}

void WavReader::seek(std::uint64_t frame) {
  if (!sndfile_) return;
  frame = std::min(frame, info_.frames);
  if (sf_seek(static_cast<SNDFILE*>(sndfile_), static_cast<sf_count_t>(frame), SEEK_SET) < 0)
    throw_file(path_, "cannot seek to frame " + std::to_string(frame) + ": " +
                          sf_strerror(static_cast<SNDFILE*>(sndfile_)));
  position_ = frame;
}

// ---------------------------------------------------------------------------------------------------
// WavWriter

WavWriter::WavWriter(const std::string& path, int channels, double sample_rate_hz, WavSampleFormat fmt)
    : path_(path), channels_(channels), fmt_(fmt) {
  if (channels < 1) throw std::invalid_argument(path + ": WAV channel count must be >= 1");
  if (!(sample_rate_hz > 0.0) || sample_rate_hz != std::floor(sample_rate_hz) || sample_rate_hz > 4.0e9)
    throw std::invalid_argument(path + ": WAV sample rate must be a positive integer (got " +
                                format_double(sample_rate_hz) + ")");
  SF_INFO sfi{};
  sfi.channels = channels;
  sfi.samplerate = static_cast<int>(sample_rate_hz);
  int sub = SF_FORMAT_FLOAT;
  switch (fmt) {
    case WavSampleFormat::Int16: sub = SF_FORMAT_PCM_16; break;
    case WavSampleFormat::Int24: sub = SF_FORMAT_PCM_24; break;
    case WavSampleFormat::Int32: sub = SF_FORMAT_PCM_32; break;
    case WavSampleFormat::Float32: sub = SF_FORMAT_FLOAT; break;
  }
  sfi.format = SF_FORMAT_WAV | sub;
  SNDFILE* sf = sf_open(path.c_str(), SFM_WRITE, &sfi);
  if (!sf) throw std::runtime_error(path + ": cannot create WAV file: " + sf_strerror(nullptr));
  sf_command(sf, SFC_SET_ADD_PEAK_CHUNK, nullptr, SF_FALSE);
  sndfile_ = sf;
}

WavWriter::~WavWriter() {
  try {
    close();
  } catch (...) {
  }
}

void WavWriter::write(const float* interleaved, std::size_t frames) {
  if (!sndfile_) throw std::runtime_error(path_ + ": write after close");
  auto* sf = static_cast<SNDFILE*>(sndfile_);
  if (fmt_ == WavSampleFormat::Float32) {
    const sf_count_t n = sf_writef_float(sf, interleaved, static_cast<sf_count_t>(frames));
    if (n != static_cast<sf_count_t>(frames)) throw std::runtime_error(path_ + ": write failed: " + sf_strerror(sf));
    frames_ += frames;
    return;
  }
  // libsndfile's int API is left-justified 32-bit: the target width's value goes in the top bits.
  const int bits = bytes_per_sample(fmt_) * 8;
  const double scale = std::ldexp(1.0, bits - 1);
  const double lo = -scale, hi = scale - 1.0;
  const int shift = 32 - bits;
  constexpr std::size_t kBlock = 4096;
  ibuf_.resize(kBlock * static_cast<std::size_t>(channels_));
  std::size_t done = 0;
  while (done < frames) {
    const std::size_t n = std::min(kBlock, frames - done);
    const float* src = interleaved + done * static_cast<std::size_t>(channels_);
    const std::size_t count = n * static_cast<std::size_t>(channels_);
    for (std::size_t i = 0; i < count; ++i) {
      double v = static_cast<double>(src[i]) * scale;
      if (std::isnan(v)) v = 0.0;
      v = std::nearbyint(std::clamp(v, lo, hi));
      const auto q = static_cast<std::int64_t>(v);
      ibuf_[i] = static_cast<int>(static_cast<std::uint32_t>(q) << shift);
    }
    const sf_count_t w = sf_writef_int(sf, ibuf_.data(), static_cast<sf_count_t>(n));
    if (w != static_cast<sf_count_t>(n)) throw std::runtime_error(path_ + ": write failed: " + sf_strerror(sf));
    done += n;
  }
  frames_ += frames;
}

void WavWriter::close() {
  if (!sndfile_) return;
  auto* sf = static_cast<SNDFILE*>(sndfile_);
  sndfile_ = nullptr;
  if (sf_close(sf) != 0) throw std::runtime_error(path_ + ": error closing WAV file");
}

// ---------------------------------------------------------------------------------------------------
// CSV reader

CsvReader::CsvReader(const std::string& path) : path_(path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw_file(path, "no such file (expected a CSV file)");
  file_ = std::fopen(path.c_str(), "rb");
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
    if (file_) std::fclose(file_);
    file_ = nullptr;
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
      std::fclose(file_);
      file_ = nullptr;
      throw SceneError({is});
    };
    if (h.empty()) fail_header("empty column name in the header (column " + std::to_string(i + 1) + ")");
    for (std::size_t j = 0; j < i; ++j)
      if (header_[j] == h) fail_header("duplicate column name '" + h + "' in the header");
  }
}

CsvReader::~CsvReader() {
  if (file_) std::fclose(file_);
}

bool CsvReader::fill() {
  if (pos_ < len_) return true;
  if (eof_ || !file_) return false;
  len_ = std::fread(buf_.data(), 1, buf_.size(), file_);
  pos_ = 0;
  if (len_ == 0) {
    if (std::ferror(file_)) throw_file(path_, "read error at line " + std::to_string(cur_line_));
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

namespace {
std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}
std::string shown(std::string_view s) {
  if (s.size() > 40) return "'" + std::string(s.substr(0, 40)) + "...'";
  return "'" + std::string(s) + "'";
}
}  // namespace

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

// ---------------------------------------------------------------------------------------------------
// formatting helpers

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

namespace {
float to_float(const CsvReader& csv, std::size_t col) {
  const double v = csv.number(col);
  if (std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max()))
    csv.fail(col, "value " + format_double(v) + " is out of float range");
  return static_cast<float>(v);
}
}  // namespace

// ---------------------------------------------------------------------------------------------------
// typed readers

ImuCsvReader::ImuCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  const char* an[3] = {"ax", "ay", "az"};
  const char* gn[3] = {"gx", "gy", "gz"};
  const char* mn[3] = {"mx", "my", "mz"};
  for (int i = 0; i < 3; ++i) {
    a_[i] = csv_.require_column(an[i]);
    g_[i] = csv_.require_column(gn[i]);
    mag_[i] = csv_.find_column(mn[i]);
  }
  const int nmag = int(mag_[0].has_value()) + int(mag_[1].has_value()) + int(mag_[2].has_value());
  if (nmag != 0 && nmag != 3) {
    SceneIssue is{path, 1, 1, -1, "columns mx, my, mz must be given together (found " + std::to_string(nmag) + " of 3)"};
    throw SceneError({is});
  }
}

bool ImuCsvReader::next(ImuSample& out) {
  if (!csv_.next_row()) return false;
  ImuSample s;
  s.device = device_;
  s.t_s = csv_.number(t_);
  if (s.t_s < last_t_)
    csv_.fail(t_, "time " + format_double(s.t_s) + " is before " + format_double(last_t_) + " on line " +
                      std::to_string(last_line_) + " (rows must be in non-decreasing t)");
  for (int i = 0; i < 3; ++i) {
    s.accel_mps2[i] = to_float(csv_, a_[i]);
    s.gyro_radps[i] = to_float(csv_, g_[i]);
  }
  if (mag_[0]) {
    const int nblank = int(csv_.blank(*mag_[0])) + int(csv_.blank(*mag_[1])) + int(csv_.blank(*mag_[2]));
    if (nblank == 3) {
      s.has_mag = false;
    } else {
      for (int i = 0; i < 3; ++i) s.mag_ut[i] = to_float(csv_, *mag_[i]);
      s.has_mag = true;
    }
  }
  last_t_ = s.t_s;
  last_line_ = csv_.row_line();
  out = s;
  return true;
}

BleCsvReader::BleCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  address_ = csv_.require_column("address");
  rssi_ = csv_.require_column("rssi");
  tx_power_ = csv_.find_column("tx_power");
  channel_ = csv_.find_column("channel");
}

bool BleCsvReader::next(BleAdvertisement& out) {
  if (!csv_.next_row()) return false;
  BleAdvertisement a;
  a.device = device_;
  a.t_s = csv_.number(t_);
  const std::string_view addr = trim(csv_.field(address_));
  if (!parse_ble_address(addr, a.address))
    csv_.fail(address_, "expected an address AA:BB:CC:DD:EE:FF (hex), got " + shown(addr));
  a.rssi_dbm = to_float(csv_, rssi_);
  if (tx_power_ && !csv_.blank(*tx_power_)) {
    a.tx_power_dbm = to_float(csv_, *tx_power_);
    a.has_tx_power = true;
  }
  if (channel_ && !csv_.blank(*channel_)) {
    const long long ch = csv_.integer(*channel_, 0, 39);
    if (ch != 0 && ch < 37) csv_.fail(*channel_, "channel " + std::to_string(ch) + ", expected 37, 38, 39 or 0 (unknown)");
    a.channel = static_cast<std::uint8_t>(ch);
  }
  out = a;
  return true;
}

SyncCsvReader::SyncCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  source_ = csv_.require_column("source");
}

bool SyncCsvReader::next(RadioSync& out) {
  if (!csv_.next_row()) return false;
  RadioSync s;
  s.device = device_;
  s.t_s = csv_.number(t_);
  const std::string_view src = trim(csv_.field(source_));
  if (src.empty()) csv_.fail(source_, "expected a sender id, got an empty field");
  if (src.size() > NameTag::max_size())
    csv_.fail(source_, "sender id " + shown(src) + " is longer than " + std::to_string(NameTag::max_size()) +
                           " characters");
  s.source = src;
  out = s;
  return true;
}

TruthCsvReader::TruthCsvReader(const std::string& path) : csv_(path) {
  t_ = csv_.require_column("t");
  id_ = csv_.require_column("id");
  const char* pn[3] = {"x", "y", "z"};
  const char* qn[4] = {"qw", "qx", "qy", "qz"};
  for (int i = 0; i < 3; ++i) p_[i] = csv_.require_column(pn[i]);
  for (int i = 0; i < 4; ++i) q_[i] = csv_.require_column(qn[i]);
}

bool TruthCsvReader::next(TruthRow& out) {
  if (!csv_.next_row()) return false;
  out.t_s = csv_.number(t_);
  if (out.t_s < last_t_)
    csv_.fail(t_, "time " + format_double(out.t_s) + " is before " + format_double(last_t_) + " on line " +
                      std::to_string(last_line_) + " (rows must be sorted by t)");
  const std::string_view id = trim(csv_.field(id_));
  if (id.empty()) csv_.fail(id_, "expected an id, got an empty field");
  out.id.assign(id.data(), id.size());
  for (int i = 0; i < 3; ++i) out.position_m[i] = csv_.number(p_[i]);
  double n2 = 0.0;
  for (int i = 0; i < 4; ++i) {
    out.q_wxyz[i] = csv_.number(q_[i]);
    n2 += out.q_wxyz[i] * out.q_wxyz[i];
  }
  const double n = std::sqrt(n2);
  if (std::fabs(n - 1.0) > 1e-3)
    csv_.fail(q_[0], "quaternion (qw,qx,qy,qz) has norm " + format_double(n) + ", expected 1 (within 1e-3)");
  for (double& q : out.q_wxyz) q /= n;
  last_t_ = out.t_s;
  last_line_ = csv_.row_line();
  return true;
}

// ---------------------------------------------------------------------------------------------------
// CSV writers

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

ImuCsvWriter::ImuCsvWriter(const std::string& path, bool with_mag)
    : CsvWriter(path, with_mag ? std::vector<std::string>{"t", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"}
                               : std::vector<std::string>{"t", "ax", "ay", "az", "gx", "gy", "gz"}),
      with_mag_(with_mag) {}

void ImuCsvWriter::write(const ImuSample& s) {
  std::string line = format_double(s.t_s);
  for (float v : s.accel_mps2) line += "," + format_float(v);
  for (float v : s.gyro_radps) line += "," + format_float(v);
  if (with_mag_) {
    for (float v : s.mag_ut) line += "," + (s.has_mag ? format_float(v) : std::string());
  }
  line += '\n';
  put(line);
}

BleCsvWriter::BleCsvWriter(const std::string& path)
    : CsvWriter(path, {"t", "address", "rssi", "tx_power", "channel"}) {}

void BleCsvWriter::write(const BleAdvertisement& a) {
  std::string line = format_double(a.t_s) + "," + format_ble_address(a.address) + "," + format_float(a.rssi_dbm) +
                     "," + (a.has_tx_power ? format_float(a.tx_power_dbm) : std::string()) + "," +
                     std::to_string(unsigned(a.channel)) + "\n";
  put(line);
}

SyncCsvWriter::SyncCsvWriter(const std::string& path) : CsvWriter(path, {"t", "source"}) {}

void SyncCsvWriter::write(const RadioSync& s) { row({format_double(s.t_s), s.source.str()}); }

TruthCsvWriter::TruthCsvWriter(const std::string& path)
    : CsvWriter(path, {"t", "id", "x", "y", "z", "qw", "qx", "qy", "qz"}) {}

void TruthCsvWriter::write(const TruthRow& r) {
  std::vector<std::string> f;
  f.reserve(9);
  f.push_back(format_double(r.t_s));
  f.push_back(r.id);
  for (double v : r.position_m) f.push_back(format_double(v));
  for (double v : r.q_wxyz) f.push_back(format_double(v));
  row(f);
}

// ---------------------------------------------------------------------------------------------------
// truth trajectories

std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b_in, double u) noexcept {
  std::array<double, 4> b = b_in;
  double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  if (d < 0.0) {
    for (double& x : b) x = -x;
    d = -d;
  }
  std::array<double, 4> r{};
  if (d > 0.9995) {
    for (int i = 0; i < 4; ++i) r[i] = a[i] + u * (b[i] - a[i]);
  } else {
    const double th = std::acos(std::min(1.0, d));
    const double s = std::sin(th);
    const double wa = std::sin((1.0 - u) * th) / s, wb = std::sin(u * th) / s;
    for (int i = 0; i < 4; ++i) r[i] = wa * a[i] + wb * b[i];
  }
  const double n = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
  for (double& x : r) x /= n;
  return r;
}

TruthTrajectories TruthTrajectories::load(const std::string& path) {
  TruthTrajectories tt;
  TruthCsvReader rd(path);
  TruthRow row;
  while (rd.next(row)) tt.add(row);
  return tt;
}

void TruthTrajectories::add(const TruthRow& row) {
  Track& tr = tracks_[row.id];
  if (!tr.t.empty() && row.t_s < tr.t.back())
    throw std::invalid_argument("truth row for '" + row.id + "' at t=" + format_double(row.t_s) +
                                " is before the previous one (" + format_double(tr.t.back()) + ")");
  tr.t.push_back(row.t_s);
  tr.pose.push_back(Pose{row.position_m, row.q_wxyz});
  if (tracks_.size() == 1 && tr.t.size() == 1) {
    t_begin_ = t_end_ = row.t_s;
  } else {
    t_begin_ = std::min(t_begin_, row.t_s);
    t_end_ = std::max(t_end_, row.t_s);
  }
}

bool TruthTrajectories::has(const std::string& id) const { return tracks_.count(id) != 0; }

std::vector<std::string> TruthTrajectories::ids() const {
  std::vector<std::string> v;
  v.reserve(tracks_.size());
  for (const auto& [k, _] : tracks_) v.push_back(k);
  return v;
}

std::pair<double, double> TruthTrajectories::time_range(const std::string& id) const {
  const auto it = tracks_.find(id);
  if (it == tracks_.end()) throw std::out_of_range("truth: unknown id '" + id + "'");
  return {it->second.t.front(), it->second.t.back()};
}

Pose TruthTrajectories::pose_at(const std::string& id, double t) const {
  const auto it = tracks_.find(id);
  if (it == tracks_.end()) throw std::out_of_range("truth: unknown id '" + id + "'");
  const Track& tr = it->second;
  if (!(t > tr.t.front())) return tr.pose.front();  // also NaN
  if (t >= tr.t.back()) return tr.pose.back();
  const auto hi = static_cast<std::size_t>(std::upper_bound(tr.t.begin(), tr.t.end(), t) - tr.t.begin());
  const std::size_t lo = hi - 1;
  const double dt = tr.t[hi] - tr.t[lo];
  const double u = dt > 0.0 ? (t - tr.t[lo]) / dt : 0.0;
  Pose p;
  for (int i = 0; i < 3; ++i)
    p.position_m[i] = tr.pose[lo].position_m[i] + u * (tr.pose[hi].position_m[i] - tr.pose[lo].position_m[i]);
  p.q_wxyz = slerp(tr.pose[lo].q_wxyz, tr.pose[hi].q_wxyz, u);
  return p;
}

}  // namespace locus::scene
