// IIO device discovery under a root prefix: <root>/sys/bus/iio/devices/iio:deviceN (what `locus
// devices` lists, and how the `iio` source resolves its `device` param). The root prefix exists so
// that tests (and `locus devices --root`) can point at a fake tree built in a temp dir; on a board it
// is "/".
#pragma once

#include <string>
#include <vector>

#include "devices.hpp"

namespace locus::hal::iio {

/// One IIO device directory.
struct IioDeviceEntry {
  std::string id;       ///< "iio:device0"
  std::string dir;      ///< <root>/sys/bus/iio/devices/iio:device0
  std::string dev_node; ///< <root>/dev/iio:device0
  std::string name;     ///< content of its `name` file ("" when absent)
  int number = 0;       ///< N of iio:deviceN
};

/// <root>/sys/bus/iio/devices (root "" or "/" = the real tree).
std::string iio_devices_dir(const std::string& root);

/// Every iio:deviceN under `root`, sorted by N (triggers and other entries skipped). An absent
/// directory yields an empty list; an unreadable one throws IioError.
std::vector<IioDeviceEntry> enumerate_iio_devices(const std::string& root);

/// Short channel names a device offers through sysfs *_raw files and scan_elements, e.g.
/// {"accel_x", "accel_y", ..., "timestamp"}, sorted.
std::vector<std::string> iio_channel_names(const IioDeviceEntry& device);

/// Resolves `spec`: "iio:deviceN", or the content of a device's `name` file (first match by N).
/// Throws IioError naming the root and listing what exists when nothing matches.
IioDeviceEntry find_iio_device(const std::string& root, const std::string& spec);

/// One DeviceInfo per IIO device: backend "iio", kind "imu" when it has accelerometer channels else
/// "sensor", id "iio:deviceN", description "<name>: channels ...; buffered|polled only". Never throws:
/// an unreadable tree gives one entry of kind "iio_unavailable" saying why.
std::vector<hal::DeviceInfo> list_iio_devices(const std::string& root);

}  // namespace locus::hal::iio
