// The node configuration (YAML), validated as a whole before anything runs.
//
// load_config() parses the file, loads the plugin directories it names, then checks every section
// against the schemas of the registry (unknown keys, missing required keys, wrong types, values out
// of range, unknown plugins/sources/event types, duplicate ids) and reports ALL errors at once, each
// with file:line:column, the key path and what was expected. docs/config.md is the reference.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"
#include "locus/registry.hpp"

namespace locus {

struct ConfigError {
  std::string file;
  int line = 0;    ///< 1-based; 0 when unknown
  int column = 0;  ///< 1-based; 0 when unknown
  std::string key; ///< dotted path, e.g. "devices[0].detectors[1].params.threshold_db"
  std::string message;  ///< what was wrong and what was expected
  /// "file:line:column: key: message"
  std::string format() const;
};

/// Thrown by load_config with every error found. what() is all of them, one per line.
class ConfigErrors : public std::runtime_error {
 public:
  explicit ConfigErrors(std::vector<ConfigError> errors);
  const std::vector<ConfigError>& errors() const noexcept { return errors_; }

 private:
  std::vector<ConfigError> errors_;
};

/// One plugin instance (detector or localizer).
struct ComponentConfig {
  std::string plugin;  ///< registry name
  std::string name;    ///< instance name, unique on the node (defaults to the plugin name)
  Params params;       ///< validated, defaults filled
};

struct AudioConfig {
  std::string source;                  ///< registry name of the audio source
  Params params;                       ///< validated against the source's schema
  std::uint32_t ring_frames = 65536;   ///< ring capacity (rounded up to a power of two)
  std::uint32_t block_frames = 256;    ///< frames per detector block
};

/// A sensor stream of a device (`imu:`, `ble:` or `sync:` section).
struct SensorConfig {
  std::string source;                    ///< registry name of a sensor source of the section's kind
  Params params;                         ///< validated against the source's schema
  std::uint32_t queue_capacity = 4096;   ///< events the hand-over queue holds (rounded up to a power of two)
};

/// A device's speaker output (`playback:` section): the HAL sink its Emitter plays through.
struct PlaybackConfig {
  std::string sink;                  ///< registry name of the playback sink ("alsa", "jack")
  Params params;                     ///< validated against the sink's schema
  std::uint32_t max_pending = 64;    ///< emissions queued or playing at once
};

/// Where a live device's microphones, speaker and position are (`geometry:` section): what replay
/// takes from scene.yaml. Body frame (Android convention) for mics and speaker, world for the anchor.
struct GeometryConfig {
  std::vector<std::array<double, 3>> mics_m;     ///< one per audio channel, channel order
  std::optional<std::array<double, 3>> speaker_m;
  std::optional<std::array<double, 3>> anchor_m;
};

/// How the node's localizers reach other nodes (`link:` section); absent = in-process.
struct LinkConfig {
  std::string type;  ///< registry name of the link ("mqtt")
  Params params;
};

/// One extra event output (`outputs:` list entry), e.g. estimates to MQTT.
struct EventOutputConfig {
  std::string type;  ///< registry name of the output ("mqtt")
  std::vector<EventType> events{EventType::Estimate};
  Params params;
};

/// Id of the template device entry (`id: "*"`): used by `locus replay` for every scene device without
/// an entry of its own; a node run (`locusd`, `locus run`) does not instantiate it.
inline constexpr std::string_view kTemplateDeviceId = "*";

struct DeviceConfig {
  std::string id;  ///< [A-Za-z0-9_-]+, unique; or "*" (kTemplateDeviceId)
  std::optional<AudioConfig> audio;
  std::optional<SensorConfig> imu;
  std::optional<SensorConfig> ble;
  std::optional<SensorConfig> sync;
  std::optional<PlaybackConfig> playback;
  std::optional<GeometryConfig> geometry;
  std::vector<ComponentConfig> detectors;

  bool is_template() const noexcept { return id == kTemplateDeviceId; }
  /// The section of `kind` (imu, ble, sync).
  std::optional<SensorConfig>& sensor(SensorKind kind) {
    return kind == SensorKind::Imu ? imu : kind == SensorKind::Ble ? ble : sync;
  }
  const std::optional<SensorConfig>& sensor(SensorKind kind) const {
    return kind == SensorKind::Imu ? imu : kind == SensorKind::Ble ? ble : sync;
  }
};

struct OutputConfig {
  std::string path = "-";  ///< JSON lines destination, "-" = stdout (relative to the working dir)
  std::vector<EventType> events{EventType::Estimate, EventType::AudioDetection};
  bool events_given = false;  ///< `output.events` was in the file (`locus replay` uses it then, else estimates)
};

struct Config {
  std::string file;                      ///< where it was loaded from
  double sample_rate_hz = 44100.0;
  LogLevel log_level = LogLevel::Info;
  std::vector<std::string> plugin_dirs;  ///< resolved relative to the config file's directory
  OutputConfig output;
  std::optional<LinkConfig> link;
  std::vector<EventOutputConfig> outputs;
  std::vector<DeviceConfig> devices;
  std::vector<ComponentConfig> localizers;
};

/// Loads and validates `path`. Plugin directories named in the file are loaded into `registry`
/// first. Throws ConfigErrors (every problem found, including an unreadable file or bad YAML).
Config load_config(const std::string& path, Registry& registry);

/// Same, from text; `name` stands for the file name in error messages and `base_dir` resolves
/// relative plugin directories.
Config load_config_string(std::string_view yaml, const std::string& name, Registry& registry,
                          const std::string& base_dir = ".");

/// Validates one params mapping against a schema outside a file (used by tests and by tools that
/// take parameters on the command line).
Params validate_params(const ParamSchema& schema, const std::vector<std::pair<std::string, std::string>>& kv,
                       std::vector<ConfigError>& errors);

}  // namespace locus
