// Registry: plugin descriptors and audio sources by name (the in-memory part; dlopen lives in
// plugin_loader.cpp, the rules a descriptor must meet in descriptor_rules.cpp).
#include "locus/registry.hpp"

#include "descriptor_rules.hpp"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>

namespace locus {

namespace {

std::string_view kind_name(std::uint32_t kind) noexcept {
  switch (kind) {
    case LOCUS_PLUGIN_DETECTOR: return "detector";
    case LOCUS_PLUGIN_LOCALIZER: return "localizer";
    default: return "plugin of unknown kind";
  }
}

}  // namespace

Registry::Registry() = default;

Registry::~Registry() {
  // Descriptors point into the libraries: forget them first, then unload in reverse load order.
  plugins_.clear();
  for (auto it = libraries_.rbegin(); it != libraries_.rend(); ++it) {
    if (*it != nullptr) ::dlclose(*it);
  }
}

void Registry::check_plugin(const locus_plugin_descriptor* d, const std::string& origin) const {
  const auto fail = [&](const std::string& reason) -> PluginLoadError {
    std::string who = "cannot add plugin";
    // Only abi_version is at a known position in a descriptor of another ABI: never read the name then.
    if (d != nullptr && d->abi_version == LOCUS_PLUGIN_ABI_VERSION && d->name != nullptr) {
      who += " '" + std::string(d->name) + "'";
    }
    return PluginLoadError(who + " (" + origin + "): " + reason);
  };
  // The descriptor's own rules (descriptor_rules.hpp), then the registry's: a name used once.
  if (const auto fault = descriptor_fault(d)) throw fail(fault->reason);
  const std::string_view name(d->name);
  for (const PluginEntry& e : plugins_) {
    if (e.descriptor->name == name) throw fail("the name is already registered (" + e.origin + ")");
  }
}

void Registry::add_plugin(const locus_plugin_descriptor* descriptor, std::string origin) {
  check_plugin(descriptor, origin);
  plugins_.push_back(PluginEntry{descriptor, std::move(origin)});
}

void Registry::add_source(SourceDescriptor source) {
  if (source.name.empty()) throw std::invalid_argument("cannot add an audio source without a name");
  if (!source.create) throw std::invalid_argument("audio source '" + source.name + "' has no factory");
  if (find_source(source.name) != nullptr) {
    throw std::invalid_argument("audio source '" + source.name + "' is already registered");
  }
  sources_.push_back(std::move(source));
}

const locus_plugin_descriptor* Registry::find_plugin(std::string_view name) const {
  for (const PluginEntry& e : plugins_) {
    if (e.descriptor->name == name) return e.descriptor;
  }
  return nullptr;
}

const SourceDescriptor* Registry::find_source(std::string_view name) const {
  for (const SourceDescriptor& s : sources_) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

namespace {

const locus_plugin_descriptor& require(const Registry& r, std::string_view name, std::uint32_t kind) {
  const locus_plugin_descriptor* d = r.find_plugin(name);
  if (d == nullptr) throw std::runtime_error("unknown plugin '" + std::string(name) + "'");
  if (d->kind != kind) {
    throw std::runtime_error("plugin '" + std::string(name) + "' is a " + std::string(kind_name(d->kind)) +
                             ", not a " + std::string(kind_name(kind)));
  }
  return *d;
}

}  // namespace

std::unique_ptr<Detector> Registry::create_detector(std::string_view name) const {
  const locus_plugin_descriptor& d = require(*this, name, LOCUS_PLUGIN_DETECTOR);
  std::unique_ptr<Detector> p(d.create_detector());
  if (!p) throw std::runtime_error("plugin '" + std::string(name) + "' failed to create a detector");
  return p;
}

std::unique_ptr<Localizer> Registry::create_localizer(std::string_view name) const {
  const locus_plugin_descriptor& d = require(*this, name, LOCUS_PLUGIN_LOCALIZER);
  std::unique_ptr<Localizer> p(d.create_localizer());
  if (!p) throw std::runtime_error("plugin '" + std::string(name) + "' failed to create a localizer");
  return p;
}

std::unique_ptr<AudioSource> Registry::create_source(std::string_view name) const {
  const SourceDescriptor* s = find_source(name);
  if (s == nullptr) {
    if (const NotBuiltBackend* nb = find_not_built(name)) {
      throw std::runtime_error("audio source '" + std::string(name) + "': " + nb->reason);
    }
    throw std::runtime_error("unknown audio source '" + std::string(name) + "'");
  }
  std::unique_ptr<AudioSource> p = s->create();
  if (!p) throw std::runtime_error("audio source '" + std::string(name) + "' failed to create an instance");
  return p;
}

void Registry::add_sensor_source(SensorSourceDescriptor source) {
  if (source.name.empty()) throw std::invalid_argument("cannot add a sensor source without a name");
  if (!source.create) throw std::invalid_argument("sensor source '" + source.name + "' has no factory");
  if (find_sensor_source(source.name) != nullptr) {
    throw std::invalid_argument("sensor source '" + source.name + "' is already registered");
  }
  sensor_sources_.push_back(std::move(source));
}

const SensorSourceDescriptor* Registry::find_sensor_source(std::string_view name) const {
  for (const SensorSourceDescriptor& s : sensor_sources_) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

std::unique_ptr<SensorSource> Registry::create_sensor_source(std::string_view name) const {
  const SensorSourceDescriptor* s = find_sensor_source(name);
  if (s == nullptr) {
    if (const NotBuiltBackend* nb = find_not_built(name)) {
      throw std::runtime_error("sensor source '" + std::string(name) + "': " + nb->reason);
    }
    throw std::runtime_error("unknown sensor source '" + std::string(name) + "'");
  }
  std::unique_ptr<SensorSource> p = s->create();
  if (!p) throw std::runtime_error("sensor source '" + std::string(name) + "' failed to create an instance");
  if (p->kind() != s->kind) {
    throw std::runtime_error("sensor source '" + std::string(name) + "' produces " +
                             std::string(sensor_kind_name(p->kind())) + " but is registered as " +
                             std::string(sensor_kind_name(s->kind)));
  }
  return p;
}

namespace {
// Shared shape of the host-side descriptor lists (sinks, links, outputs): unique non-empty names and
// a factory.
template <typename Descriptor>
void add_named(std::vector<Descriptor>& list, Descriptor d, const char* what) {
  if (d.name.empty()) throw std::invalid_argument(std::string("cannot add a ") + what + " without a name");
  if (!d.create) throw std::invalid_argument(std::string(what) + " '" + d.name + "' has no factory");
  for (const Descriptor& e : list) {
    if (e.name == d.name) throw std::invalid_argument(std::string(what) + " '" + d.name + "' is already registered");
  }
  list.push_back(std::move(d));
}
template <typename Descriptor>
const Descriptor* find_named(const std::vector<Descriptor>& list, std::string_view name) {
  for (const Descriptor& e : list) {
    if (e.name == name) return &e;
  }
  return nullptr;
}
}  // namespace

void Registry::add_sink(SinkDescriptor sink) { add_named(sinks_, std::move(sink), "playback sink"); }
void Registry::add_link(LinkDescriptor link) { add_named(links_, std::move(link), "link"); }
void Registry::add_output(OutputDescriptor output) { add_named(outputs_, std::move(output), "output"); }
const SinkDescriptor* Registry::find_sink(std::string_view name) const { return find_named(sinks_, name); }
const LinkDescriptor* Registry::find_link(std::string_view name) const { return find_named(links_, name); }
const OutputDescriptor* Registry::find_output(std::string_view name) const { return find_named(outputs_, name); }

void Registry::add_not_built(NotBuiltBackend backend) {
  if (backend.name.empty()) throw std::invalid_argument("cannot add a not-built backend without a name");
  if (backend.reason.empty()) {
    throw std::invalid_argument("not-built backend '" + backend.name + "' has no reason");
  }
  if (find_not_built(backend.name) != nullptr) {
    throw std::invalid_argument("backend '" + backend.name + "' is already registered as not built in");
  }
  const char* registered_as = find_source(backend.name) != nullptr          ? "an audio source"
                              : find_sensor_source(backend.name) != nullptr ? "a sensor source"
                              : find_sink(backend.name) != nullptr          ? "a playback sink"
                              : find_link(backend.name) != nullptr          ? "a link"
                              : find_output(backend.name) != nullptr        ? "an output"
                                                                            : nullptr;
  if (registered_as != nullptr) {
    throw std::invalid_argument("backend '" + backend.name + "' cannot be both not built in and registered as " +
                                registered_as);
  }
  not_built_.push_back(std::move(backend));
}

const NotBuiltBackend* Registry::find_not_built(std::string_view name) const { return find_named(not_built_, name); }

}  // namespace locus
