// The plugin ABI: one versioned extern "C" entry point per shared object, returning descriptors.
//
// A plugin .so exports
//
//     extern "C" const locus_plugin_descriptor* locus_plugin_enum(uint32_t index);
//
// which returns its index-th descriptor, or nullptr past the last one (the shape of PipeWire's
// spa_handle_factory_enum). The host reads `abi_version` first (it is the first field and never
// moves) and refuses a plugin built against another ABI with a message naming the file and both
// versions. The factories create C++ objects, so a plugin must be built with a compatible C++
// toolchain; LOCUS_PLUGIN_ABI_VERSION changes whenever any header a plugin sees changes layout.
//
// Built-in plugins use the same descriptors, listed in LOCUS_BUILTIN_PLUGINS (plugins/CMakeLists.txt).
//
// Writing a plugin: implement locus::Detector or locus::Localizer, declare its ParamSchema, and
// LOCUS_PLUGIN_EXPORT(your descriptor(s)). examples/out-of-tree-plugin shows a complete one.
#pragma once

#include <cstdint>
#include <memory>

#include "locus/detector.hpp"
#include "locus/localizer.hpp"
#include "locus/params.hpp"

/// Bump on any change of layout or virtual table in the public headers.
// 2: HostContext::geometry (DeviceGeometry); 3: HostContext::emitter, DeviceGeometry::scene_emits_json;
// 4: signals typed (SignalSpec, locus/signal.hpp): DeviceGeometry::emits / scene_emits spans replace
//    the JSON texts, Emitter::schedule takes a SignalSpec; Estimate gains direction_std_rad,
//    distance_std_m and flags;
// 5: AudioDetection::envelope_frame and carrier_period (consistent carrier cycles across arrivals).
// 6: SceneSignal::has_anchor / anchor_m (a localizer knows the scene's anchored beacons, SpyLoc);
//    Estimate::los (in the padding after flags).
#define LOCUS_PLUGIN_ABI_VERSION 6u
#define LOCUS_PLUGIN_ENUM_SYMBOL "locus_plugin_enum"

extern "C" {

enum locus_plugin_kind : std::uint32_t {
  LOCUS_PLUGIN_DETECTOR = 1,
  LOCUS_PLUGIN_LOCALIZER = 2,
};

struct locus_plugin_descriptor {
  std::uint32_t abi_version;       ///< LOCUS_PLUGIN_ABI_VERSION the plugin was built with (first field, always)
  std::uint32_t kind;              ///< locus_plugin_kind
  const char* name;                ///< registry name used in configs, [a-z0-9_]+
  const char* version;             ///< the plugin's own version string
  const char* description;         ///< one line
  std::uint32_t inputs;            ///< detectors: DetectorInput bit mask
  /// The parameter schema (static storage owned by the plugin).
  const locus::ParamSchema* (*schema)();
  /// Exactly one of these is set, according to `kind`. Return a new instance owned by the caller.
  locus::Detector* (*create_detector)();
  locus::Localizer* (*create_localizer)();
};

typedef const locus_plugin_descriptor* (*locus_plugin_enum_fn)(std::uint32_t index);
}

/// Defines the entry point of a plugin .so from a list of descriptors:
///   LOCUS_PLUGIN_EXPORT(my_detector_descriptor, my_localizer_descriptor)
#define LOCUS_PLUGIN_EXPORT(...)                                                              \
  extern "C" __attribute__((visibility("default"))) const locus_plugin_descriptor*            \
  locus_plugin_enum(std::uint32_t index) {                                                    \
    static const locus_plugin_descriptor* const table[] = {__VA_ARGS__};                      \
    return index < sizeof(table) / sizeof(table[0]) ? table[index] : nullptr;                 \
  }
