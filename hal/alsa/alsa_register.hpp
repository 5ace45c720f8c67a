// Registration of the ALSA backend: the `alsa` audio source (capture) and the `alsa` playback sink.
#pragma once

#include "locus/registry.hpp"

namespace locus::hal::alsa {

/// Adds SourceDescriptor "alsa" and SinkDescriptor "alsa" to `registry`.
void register_alsa_backends(Registry& registry);

}  // namespace locus::hal::alsa
