// Registers the built-in HAL audio sources.
#pragma once
#include "locus/registry.hpp"
namespace locus::hal {
/// Adds every built-in source, sensor source and playback sink (synth, alsa, scene_*, jack, iio, bluez).
/// An optional backend this build lacks (LOCUS_WITH_ALSA/JACK/BLUEZ) is added with
/// Registry::add_not_built instead, with the reason from locus/build_options.hpp.
void register_builtin_sources(Registry& registry);
}
