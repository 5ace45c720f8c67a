// audio.wav of a scene (docs/scene-format.md): the RIFF/WAVE header, checked by hand so errors can
// name the byte offset and the value expected, and the samples streamed block by block through
// libsndfile. Part of the scene stream I/O (streams.hpp); single-threaded, file I/O (not real-time).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "locus/scene/scene.hpp"

namespace locus::scene {

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

}  // namespace locus::scene
