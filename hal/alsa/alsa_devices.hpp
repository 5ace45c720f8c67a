// What `locus devices` shows for ALSA: the sound cards with their PCM devices (hw:N,D), and the PCMs
// the ALSA configuration defines (snd_device_name_hint: default, null, jack, plughw:..., with their
// description and direction). On a machine without cards only the configuration PCMs are listed.
// Never throws: when libasound cannot give hints, one entry of kind "unavailable" says why.
#pragma once

#include <vector>

#include "devices.hpp"

namespace locus::hal::alsa {

/// [main] Cards (kind "card", id "hw:N"), card PCM devices (kind "pcm", id "hw:N,D") and configured
/// PCMs (kind "pcm", id the PCM name; description "<DESC> [capture|playback|capture+playback]").
std::vector<DeviceInfo> list_alsa_devices();

}  // namespace locus::hal::alsa
