// `locus record`: live HAL streams written into a scene directory (docs/scene-format.md), so anything
// recorded on a board can be replayed later with `locus replay` (docs/record.md).
//
// Why not the Pipeline: recording needs the raw streams, not detections. The recorder reads the same
// node config locusd runs (load_config), creates each device's audio source and sensor sources directly
// from the registry, each feeding its own AudioRing / SensorQueue, and runs one writer thread per
// device that drains them into the scene files with the scene writers (WavWriter, Imu/Ble/SyncCsvWriter,
// write_scene_yaml). Nothing here is real-time: the sources' callbacks only copy into the rings.
//
// What is guaranteed:
//   - the WAV frame index equals the stream frame counter: frames a live source lost (ring overrun,
//     xrun gap reported through ReadSpan::lost_before, or a loss the ring could not queue) are written
//     as zeros and listed in <device>/gaps.csv (`frame,frames`), a side file scene-format.md has no
//     place for (readers ignore files they do not know);
//   - everything a source handed over before the stop is written (the stop is graceful: sources are
//     stopped first, then the rings and queues are drained, then the files are closed);
//   - scene.yaml is written when the recording starts (so a recorder killed mid-way leaves a readable,
//     truncated scene) and rewritten when it ends; recording.yaml (also a side file) says which sources
//     produced the streams and what was lost.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "locus/config.hpp"
#include "locus/registry.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"

namespace locus::app {

struct RecordOptions {
  std::string config_path;
  std::string out_dir;
  std::optional<double> duration_s;          ///< stop after this much audio (see RecorderSettings)
  bool overwrite = false;
  std::string sample_format = "auto";        ///< auto | float32 | int16 | int24 | int32
  std::optional<std::string> name;           ///< scene name (default: the OUT directory's name)
  std::optional<std::string> log_level;
};

/// Runs `locus record`. Exit status: 0 the recording ended normally (end of every finite stream,
/// --duration, SIGINT/SIGTERM); 2 a bad config, option or OUT directory (nothing recorded); 1 a
/// source or a file failed mid-way (everything recorded before is flushed and OUT is a valid scene).
int run_record(const RecordOptions& options);

/// How the recorder writes a scene.
struct RecorderSettings {
  std::string out_dir;
  std::string name;                                      ///< scene name ("" = the directory's name)
  /// Each audio stream keeps exactly its first round(duration_s · rate) frames (stream time); the
  /// recording is complete once every audio stream has them (a node without audio: after duration_s
  /// of host time).
  std::optional<double> duration_s;
  bool overwrite = false;                                ///< replace an existing scene directory
  std::optional<scene::WavSampleFormat> sample_format;   ///< nullopt = as the source delivers
  std::size_t min_ring_frames = std::size_t{1} << 18;    ///< rings hold at least this (disk stalls)
  std::string config_file;                               ///< for recording.yaml ("" = unknown)
};

/// A run of frames a source lost, written as zeros.
struct RecordedGap {
  std::uint64_t frame = 0;   ///< stream frame number of the first lost frame
  std::uint64_t frames = 0;  ///< how many
};

/// What one device's files hold once the recording stopped.
struct RecordedDevice {
  std::string id;
  // audio ("" source: the device has no audio stream)
  std::string audio_source;
  std::uint32_t channels = 0;
  double sample_rate_hz = 0.0;
  scene::WavSampleFormat sample_format = scene::WavSampleFormat::Float32;
  std::uint64_t frames = 0;             ///< frames in audio.wav (zero-filled gaps included)
  std::uint64_t lost_frames = 0;        ///< zero-filled frames (sum of gaps)
  std::vector<RecordedGap> gaps;
  std::uint64_t ring_overruns = 0;      ///< loss episodes counted by the ring
  std::uint64_t discarded_frames = 0;   ///< frames past --duration, not written
  // sensors, indexed by SensorKind (imu, ble, sync); "" source = no such stream
  std::array<std::string, 3> sensor_source{};
  std::array<std::uint64_t, 3> events{};          ///< rows written
  std::array<std::uint64_t, 3> dropped_events{};  ///< a live source found its queue full
  /// Where the times of each sensor stream are: "source" (as stamped: replay, or no live audio to align
  /// to), "audio" (moved from CLOCK_MONOTONIC onto the audio timeline, t = 0 at audio frame 0),
  /// "monotonic" (the live audio never gave an origin: CLOCK_MONOTONIC seconds).
  std::array<std::string, 3> time_base{};
  std::uint64_t imu_out_of_order = 0;             ///< IMU rows written with t below the previous row's
  std::string error;                              ///< first source or file error ("" = none)
};

/// The recorder behind `locus record`, usable on its own (tests, other tools).
///
/// Threading: every method is [main]; the recorder owns one writer thread per device.
class Recorder {
 public:
  /// Opens every source of every (non-template) device of `config` with its validated params,
  /// prepares the scene directory (refusing an existing non-empty one unless overwrite, and never
  /// removing a directory that is not a scene) and writes the initial scene.yaml. Throws
  /// std::runtime_error naming the device, source or file that failed; nothing runs then.
  Recorder(const Config& config, const Registry& registry, RecorderSettings settings);
  ~Recorder();  ///< stops (errors swallowed; call stop() to see them)
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// Starts the writer threads, then the sources.
  void start();
  /// True when there is nothing more to wait for: every stream ended and was written, or --duration
  /// is complete.
  bool complete() const;
  /// Why complete() is true ("end of streams", "duration"), "" otherwise.
  std::string completion_reason() const;
  /// First error of a source (AudioSource/SensorSource::error()) or of a writer, prefixed with the
  /// device and stream; "" if none.
  std::string error() const;
  /// Stops the sources, drains and writes everything they handed over, closes the files, writes
  /// scene.yaml and recording.yaml. Idempotent. `reason` goes to recording.yaml. Throws
  /// std::runtime_error when a file cannot be finalised.
  void stop(const std::string& reason = "stopped");

  const scene::Scene& scene() const noexcept { return scene_; }
  /// Per device, in config order; final after stop().
  std::vector<RecordedDevice> devices() const;
  /// Host seconds since start().
  double elapsed_s() const;

 private:
  struct Device;
  void run_writer(Device& d);
  void write_recording_yaml(const std::string& reason) const;

  RecorderSettings settings_;
  scene::Scene scene_;
  std::vector<std::unique_ptr<Device>> devices_;
  struct Host;
  std::unique_ptr<Host> host_;
  std::string started_utc_;
  double start_s_ = 0.0;
  bool started_ = false;
  bool stopped_ = false;
};

/// "float32" | "int16" | "int24" | "int32" -> format; false otherwise.
bool parse_sample_format(const std::string& s, scene::WavSampleFormat& out);

/// The sample format a source delivers: an opened ALSA source's negotiated PCM format; a scene_audio
/// source's WAV format; a `format` or `sample_format` string parameter naming a 16/24/32-bit integer or
/// float format (int16, S16_LE, s24, S32_LE, float32, FLOAT_LE ...); float32 otherwise (JACK, synth).
scene::WavSampleFormat native_sample_format(const std::string& source, const Params& params,
                                            const AudioSource* opened = nullptr);

}  // namespace locus::app
