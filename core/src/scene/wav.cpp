// audio.wav (wav.hpp). The RIFF/WAVE/fmt /data headers are parsed here (so errors can name byte
// offsets and the value expected); samples are then read and written with libsndfile. Integer
// conversion is done here on the write side because libsndfile's float→int scaling (0x7FFF) is not
// the inverse of its int→float scaling (1/0x8000); with v/2^(bits−1) both ways, quantised values
// round-trip exactly.
#include "locus/scene/wav.hpp"

#include <sndfile.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <system_error>

#include "locus/scene/csv.hpp"
#include "stream_detail.hpp"

namespace locus::scene {

namespace {

using detail::throw_at_byte;
using detail::throw_file;

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

}  // namespace locus::scene
