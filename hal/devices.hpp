// What `locus devices` lists: one entry per capture/playback PCM, JACK port, IIO device or BLE adapter
// a backend can see. Each backend has its own list function (hal/<backend>/*_devices.hpp); the tool
// prints them all. Listing never fails hard: a backend that cannot look (no JACK server running, no
// system bus) returns one entry of kind "unavailable" whose description says why.
#pragma once

#include <string>
#include <vector>

namespace locus::hal {

struct DeviceInfo {
  std::string backend;      ///< "alsa", "jack", "iio", "bluez"
  std::string kind;         ///< e.g. "pcm", "card", "port", "imu", "adapter", "unavailable"
  std::string id;           ///< what a config names it by (PCM name, port name, iio:deviceN, hci0)
  std::string description;  ///< one line (card name, port flags, IIO name and channels, adapter address)
};

}  // namespace locus::hal
