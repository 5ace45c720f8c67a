// The scene recording format, version 1 (`locus-scene/1`): the data model of scene.yaml.
//
// The format is a public interface (../shared/docs/scene-format.md, mirrored in docs/scene-format.md):
// readers are strict about what the format requires and tolerant of what it allows (absent optional
// fields, unknown extra keys and columns are ignored). Every error names the file, line and column
// (or byte offset for binary files) and what was expected.
//
// Streams (audio.wav, imu.csv, ble.csv, sync.csv, truth.csv) are read by the streaming readers in
// scene/streams.hpp; this header only describes scene.yaml.
#pragma once

#include <array>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "locus/dsp/signals.hpp"

namespace locus::scene {

inline constexpr const char* kFormatVersion = "locus-scene/1";

using Vec3 = std::array<double, 3>;

/// A device: records sound and/or senses (IMU, BLE, radio sync); may emit.
struct DeviceSpec {
  std::string id;                            ///< [A-Za-z0-9_-]+, unique among devices and emitters
  std::vector<Vec3> mics_m;                  ///< body frame, one per audio channel, channel order
  std::optional<Vec3> speaker_m;             ///< body frame; absent = cannot emit
  std::vector<dsp::SignalSpec> emits;
  std::string audio;                         ///< path relative to the scene dir; "" = absent
  std::string imu;
  std::string ble;
  std::string sync;
  std::optional<Vec3> anchor_position_m;     ///< position known to the system (infrastructure)
  int line = 0;                              ///< where it is declared in scene.yaml (0 = unknown)
  std::vector<std::pair<int, int>> emits_at; ///< line, column of each `emits` entry (empty = unknown)
};

/// Something that transmits but records nothing (beacon, BLE tag).
struct EmitterSpec {
  std::string id;
  std::vector<dsp::SignalSpec> emits;
  std::optional<Vec3> anchor_position_m;
  int line = 0;
  std::vector<std::pair<int, int>> emits_at; ///< line, column of each `emits` entry (empty = unknown)
};

/// local_time = true_time · (1 + skew_ppm·1e-6) + offset_s
struct ClockTruth {
  double offset_s = 0.0;
  double skew_ppm = 0.0;
  double local_from_true(double true_s) const noexcept { return true_s * (1.0 + skew_ppm * 1e-6) + offset_s; }
  double true_from_local(double local_s) const noexcept { return (local_s - offset_s) / (1.0 + skew_ppm * 1e-6); }
};

/// Ground truth: evaluation only, never read by a plugin.
struct Truth {
  std::map<std::string, ClockTruth> clocks;              ///< by device id
  std::string trajectories;                              ///< truth.csv path relative to the scene dir; "" = none
  std::optional<Vec3> magnetic_field_world_ut;
};

struct Scene {
  std::string dir;                 ///< directory the scene was loaded from / is written to
  std::string format = kFormatVersion;
  std::string name;
  double sample_rate_hz = 44100.0;
  double speed_of_sound_mps = 343.2;        ///< given, or derived from temperature_c
  std::optional<double> temperature_c;      ///< when the scene gave a temperature instead
  std::string environment_yaml;             ///< the free-form `environment` mapping, as YAML text ("" = absent)
  std::vector<DeviceSpec> devices;
  std::vector<EmitterSpec> emitters;
  std::optional<Truth> truth;

  const DeviceSpec* find_device(const std::string& id) const;
  const EmitterSpec* find_emitter(const std::string& id) const;
  /// `relative` resolved against dir ("" stays "").
  std::string path(const std::string& relative) const;
};

/// One problem found in a scene file.
struct SceneIssue {
  std::string file;      ///< path of the file
  int line = 0;          ///< 1-based (text files); 0 when not applicable
  int column = 0;        ///< 1-based (text files); 0 when not applicable
  long long byte_offset = -1;  ///< binary files (WAV); -1 when not applicable
  std::string message;   ///< what was wrong and what was expected
  /// "file:line:column: message" or "file: byte N: message"
  std::string format() const;
};

/// A scene (or one of its files) is malformed. what() lists every issue, one per line.
class SceneError : public std::runtime_error {
 public:
  explicit SceneError(std::vector<SceneIssue> issues);
  const std::vector<SceneIssue>& issues() const noexcept { return issues_; }

 private:
  std::vector<SceneIssue> issues_;
};

/// Reads and validates `<dir>/scene.yaml` (all issues collected, then thrown as one SceneError).
/// Checks that referenced stream files exist; it does not read them.
Scene load_scene(const std::string& dir);

/// Writes `<scene.dir>/scene.yaml` (creating the directory). Throws std::runtime_error on I/O failure.
void write_scene_yaml(const Scene& scene);

/// Opens the header of every referenced audio.wav (cheap: no samples are read) and checks its channel
/// count against the device's mics and its rate against sample_rate. Every mismatch (and every header
/// error) is collected, then thrown as one SceneError. A truncated data chunk is not an error (the
/// readers deliver the frames present): it is returned as a warning line, "file: byte N: ...".
std::vector<std::string> validate_scene_streams(const Scene& scene);

/// Every signal of the scene's devices and emitters with its emitter's id, in scene.yaml order (devices
/// first): what a host hands its plugins as DeviceGeometry::scene_emits.
std::vector<SceneSignal> scene_signals(const Scene& scene);

/// load_scene() keeps `emits` entries of unknown type (a project may add types); a consumer that
/// needs the signals of `ids` (device or emitter ids; empty = every device and emitter) calls this
/// to get a clear error: "scene.yaml:12:9: device 'A': emits[1]: unknown signal type 'chirp2'
/// (known: lfm, gold, multitone, ble)". Throws SceneError listing every such entry.
void require_known_signal_types(const Scene& scene, const std::vector<std::string>& ids = {});

}  // namespace locus::scene
