// The registry: every plugin and audio source the host can instantiate, by name.
//
// Built-in plugins and sources are added explicitly (plugins/builtin.cpp, hal/builtin.cpp);
// external plugins are shared objects loaded with dlopen through LOCUS_PLUGIN_ENUM_SYMBOL
// (see plugin.hpp), refused with a clear message on an ABI mismatch. [main] only.
#pragma once

#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "locus/audio_source.hpp"
#include "locus/event_output.hpp"
#include "locus/playback.hpp"
#include "locus/plugin.hpp"
#include "locus/sensor_source.hpp"

namespace locus {

/// A HAL audio source type (built in; sources are host-side, not part of the plugin ABI).
struct SourceDescriptor {
  std::string name;
  std::string description;
  ParamSchema schema;
  std::function<std::unique_ptr<AudioSource>()> create;
};

/// A HAL sensor source type (IMU, BLE scanner, radio sync receiver; built in, host-side like audio sources).
struct SensorSourceDescriptor {
  std::string name;
  std::string description;
  SensorKind kind = SensorKind::Imu;  ///< what it produces: the config section it may appear in
  ParamSchema schema;
  std::function<std::unique_ptr<SensorSource>()> create;
};

/// A HAL playback backend type (`playback:` section of a device; built in).
struct SinkDescriptor {
  std::string name;
  std::string description;
  ParamSchema schema;
  std::function<std::unique_ptr<AudioSink>()> create;
};

/// A link type (`link:` section of a node: how its localizers reach other nodes; built in).
/// `create` gets the validated params and the node's logger; throws std::runtime_error naming what
/// failed (e.g. the broker refused the credentials).
struct LinkDescriptor {
  std::string name;
  std::string description;
  ParamSchema schema;
  std::function<std::unique_ptr<Link>(const Params&, Logger&)> create;
};

/// An extra event output (`outputs:` list of a node, besides the JSON-lines `output:`; built in).
struct OutputDescriptor {
  std::string name;
  std::string description;
  ParamSchema schema;
  std::function<std::unique_ptr<EventOutput>(const Params&, Logger&)> create;
};

/// A backend this build does not have: an optional dependency switched off (LOCUS_WITH_JACK=OFF) or not
/// found when the build was configured (cmake/LocusBackends.cmake). It is registered instead of its
/// descriptors (hal/builtin.cpp, link/links.cpp), so that a config naming it is told why it is missing
/// ("JACK support was not built in (LOCUS_WITH_JACK=OFF)") rather than "unknown audio source", and
/// `locus devices` / `locus plugins` can list it as not built in.
struct NotBuiltBackend {
  std::string name;    ///< the name configs use: "jack" (audio source and playback sink), "mqtt" (link, output)
  std::string reason;  ///< one sentence saying what is missing and why (no trailing period)
};

/// A plugin library could not be loaded or one of its descriptors is invalid. what() names the file
/// and the reason (dlopen error, missing entry point, ABI mismatch, duplicate name, bad descriptor).
class PluginLoadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class Registry {
 public:
  Registry();
  ~Registry();
  Registry(const Registry&) = delete;
  Registry& operator=(const Registry&) = delete;

  /// Adds a built-in plugin descriptor (static storage). Throws PluginLoadError on a duplicate name
  /// or an invalid descriptor.
  void add_plugin(const locus_plugin_descriptor* descriptor, std::string origin = "built-in");
  /// Checks what add_plugin checks (ABI version, name, kind, factory, schema, no clash with a registered
  /// name) without adding anything; throws the same PluginLoadError.
  void check_plugin(const locus_plugin_descriptor* descriptor, const std::string& origin = "built-in") const;
  /// Adds a built-in audio source. Throws std::invalid_argument on an empty name, a missing factory or
  /// a duplicate name.
  void add_source(SourceDescriptor source);
  /// Adds a built-in sensor source. Throws std::invalid_argument on an empty name, a missing factory or
  /// a duplicate name (sensor source names are unique across kinds).
  void add_sensor_source(SensorSourceDescriptor source);

  /// Adds a playback backend / link type / event output. Throw std::invalid_argument like add_source.
  void add_sink(SinkDescriptor sink);
  void add_link(LinkDescriptor link);
  void add_output(OutputDescriptor output);

  /// Records a backend this build lacks (see NotBuiltBackend). Throws std::invalid_argument on an empty
  /// name or reason, a duplicate, or a name already registered as a source, sensor source, playback
  /// sink, link or output (a backend is either built or not).
  void add_not_built(NotBuiltBackend backend);

  /// dlopens `path` and adds every descriptor it enumerates. Throws PluginLoadError (nothing from a
  /// refused library is added). Returns the names added.
  std::vector<std::string> load_library(const std::string& path);
  /// Loads every `*.so` in `dir` (sorted by name). Collects failures instead of stopping at the first:
  /// returns one message per library that failed.
  std::vector<std::string> load_directory(const std::string& dir);

  /// nullptr when absent.
  const locus_plugin_descriptor* find_plugin(std::string_view name) const;
  const SourceDescriptor* find_source(std::string_view name) const;
  const SensorSourceDescriptor* find_sensor_source(std::string_view name) const;
  const SinkDescriptor* find_sink(std::string_view name) const;
  const LinkDescriptor* find_link(std::string_view name) const;
  const OutputDescriptor* find_output(std::string_view name) const;
  /// The backend of that name this build lacks, or nullptr. Lookups that fail (find_source, ...) are
  /// followed by this one wherever a user is told what went wrong (config validation, create_*).
  const NotBuiltBackend* find_not_built(std::string_view name) const;

  struct PluginEntry {
    const locus_plugin_descriptor* descriptor;
    std::string origin;  ///< "built-in" or the .so path
  };
  const std::vector<PluginEntry>& plugins() const noexcept { return plugins_; }
  const std::vector<SourceDescriptor>& sources() const noexcept { return sources_; }
  const std::vector<SensorSourceDescriptor>& sensor_sources() const noexcept { return sensor_sources_; }
  const std::vector<SinkDescriptor>& sinks() const noexcept { return sinks_; }
  const std::vector<LinkDescriptor>& links() const noexcept { return links_; }
  const std::vector<OutputDescriptor>& outputs() const noexcept { return outputs_; }
  const std::vector<NotBuiltBackend>& not_built() const noexcept { return not_built_; }

  std::unique_ptr<Detector> create_detector(std::string_view name) const;    ///< throws if absent/not a detector
  std::unique_ptr<Localizer> create_localizer(std::string_view name) const;  ///< throws if absent/not a localizer
  /// Throw std::runtime_error if absent (with the reason when the backend was not built in).
  std::unique_ptr<AudioSource> create_source(std::string_view name) const;
  std::unique_ptr<SensorSource> create_sensor_source(std::string_view name) const;

 private:
  std::vector<PluginEntry> plugins_;
  std::vector<SourceDescriptor> sources_;
  std::vector<SensorSourceDescriptor> sensor_sources_;
  std::vector<SinkDescriptor> sinks_;
  std::vector<LinkDescriptor> links_;
  std::vector<OutputDescriptor> outputs_;
  std::vector<NotBuiltBackend> not_built_;
  std::vector<void*> libraries_;  // dlopen handles, closed in the destructor after instances are gone
};

/// A registry holding every built-in plugin and source (defined in the locus_builtins library).
void register_builtins(Registry& registry);

}  // namespace locus
