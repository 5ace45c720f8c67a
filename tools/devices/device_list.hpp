// `locus devices`: what a node could record from or play to on this machine, from every HAL backend
// (ALSA PCMs and cards, JACK ports, IIO devices, BLE adapters), so a user can write a config's source
// params without guessing names. Each backend lists its own (hal/<backend>/*_devices.hpp); a backend
// that cannot look reports one "unavailable" entry saying why, so the listing itself never fails. A
// backend this build lacks (LOCUS_WITH_ALSA/JACK/BLUEZ off or its library not found) reports one
// "not-built-in" entry: "jack  not-built-in  -  JACK support was not built in (LOCUS_WITH_JACK=OFF)".
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "devices.hpp"  // hal/devices.hpp (locus::hal::DeviceInfo)

namespace locus::app {

struct DevicesOptions {
  bool json = false;
  std::string jack_server;   ///< "" = the default server ($JACK_DEFAULT_SERVER, else "default")
  std::string iio_root = "/";  ///< root prefix of the IIO sysfs tree and /dev (tests use a fake tree)
};

/// The kind of the one entry a backend this build lacks gets.
inline constexpr const char* kNotBuiltKind = "not-built-in";

/// {backend, "not-built-in", "", "<Title> support was not built in (<why>)"} for an optional backend
/// (alsa, jack, bluez) whatever this build has; throws std::invalid_argument for another name.
hal::DeviceInfo not_built_entry(std::string_view backend);

/// Every backend's entries, in backend order (alsa, jack, iio, bluez). A backend that throws is turned
/// into one entry {backend, "unavailable", "", "<what it said>"}; one this build lacks into its
/// not_built_entry().
std::vector<hal::DeviceInfo> list_all_devices(const DevicesOptions& options);

/// An aligned text table with a header row (BACKEND KIND ID DESCRIPTION), one line per entry.
std::string format_devices_table(const std::vector<hal::DeviceInfo>& devices);
/// A JSON array of {"backend","kind","id","description"} objects (one line).
std::string format_devices_json(const std::vector<hal::DeviceInfo>& devices);

/// Prints the list to stdout. Exit status 0 (unavailable backends are part of the answer).
int run_devices(const DevicesOptions& options);

}  // namespace locus::app
