// IIO device discovery (see iio_devices.hpp).
#include "iio/iio_devices.hpp"

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <set>
#include <system_error>

#include "iio/iio_parse.hpp"

namespace locus::hal::iio {

namespace fs = std::filesystem;

std::string iio_devices_dir(const std::string& root) {
  fs::path base = root.empty() ? fs::path("/") : fs::path(root);
  return (base / "sys/bus/iio/devices").string();
}

std::vector<IioDeviceEntry> enumerate_iio_devices(const std::string& root) {
  const std::string dir = iio_devices_dir(root);
  const fs::path dev_dir = (root.empty() ? fs::path("/") : fs::path(root)) / "dev";
  std::vector<IioDeviceEntry> out;
  std::error_code ec;
  if (!fs::exists(dir, ec)) return out;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string file = it->path().filename().string();
    static constexpr std::string_view kPrefix = "iio:device";
    if (file.size() <= kPrefix.size() || file.compare(0, kPrefix.size(), kPrefix) != 0) continue;
    int n = -1;
    const char* first = file.data() + kPrefix.size();
    const char* last = file.data() + file.size();
    const auto r = std::from_chars(first, last, n);
    if (r.ec != std::errc() || r.ptr != last || n < 0) continue;
    IioDeviceEntry e;
    e.id = file;
    e.dir = it->path().string();
    e.dev_node = (dev_dir / file).string();
    e.number = n;
    read_sysfs_optional(e.dir + "/name", e.name);
    out.push_back(std::move(e));
  }
  if (ec) throw IioError("cannot list " + dir + ": " + ec.message());
  std::sort(out.begin(), out.end(), [](const IioDeviceEntry& a, const IioDeviceEntry& b) { return a.number < b.number; });
  return out;
}

std::vector<std::string> iio_channel_names(const IioDeviceEntry& device) {
  std::set<std::string> names;
  std::error_code ec;
  auto scan = [&](const std::string& dir, std::string_view suffix) {
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
      const std::string f = it->path().filename().string();
      if (f.size() > 3 + suffix.size() && f.compare(0, 3, "in_") == 0 &&
          f.compare(f.size() - suffix.size(), suffix.size(), suffix) == 0) {
        names.insert(f.substr(3, f.size() - 3 - suffix.size()));
      }
    }
    ec.clear();
  };
  scan(device.dir, "_raw");
  scan(device.dir + "/scan_elements", "_en");
  return {names.begin(), names.end()};
}

IioDeviceEntry find_iio_device(const std::string& root, const std::string& spec) {
  const std::vector<IioDeviceEntry> all = enumerate_iio_devices(root);
  for (const IioDeviceEntry& e : all) {
    if (e.id == spec) return e;
  }
  for (const IioDeviceEntry& e : all) {
    if (!e.name.empty() && e.name == spec) return e;
  }
  std::string have;
  for (const IioDeviceEntry& e : all) have += (have.empty() ? "" : ", ") + e.id + (e.name.empty() ? "" : " (" + e.name + ")");
  throw IioError("no IIO device '" + spec + "' in " + iio_devices_dir(root) + " (expected iio:deviceN or a name; found: " +
                 (have.empty() ? std::string("none") : have) + ")");
}

std::vector<hal::DeviceInfo> list_iio_devices(const std::string& root) {
  std::vector<hal::DeviceInfo> out;
  try {
    const std::vector<IioDeviceEntry> all = enumerate_iio_devices(root);
    if (all.empty()) {
      out.push_back({"iio", "iio_unavailable", "", "no IIO devices in " + iio_devices_dir(root)});
      return out;
    }
    for (const IioDeviceEntry& e : all) {
      const std::vector<std::string> channels = iio_channel_names(e);
      const bool accel = std::find(channels.begin(), channels.end(), "accel_x") != channels.end();
      std::error_code ec;
      const bool buffered = fs::is_directory(e.dir + "/scan_elements", ec) && fs::is_directory(e.dir + "/buffer", ec);
      std::string desc = (e.name.empty() ? std::string("(no name)") : e.name) + ": channels ";
      for (std::size_t i = 0; i < channels.size(); ++i) desc += (i ? " " : "") + channels[i];
      if (channels.empty()) desc += "none";
      desc += buffered ? "; buffered (" + e.dev_node + ")" : "; polled only (no scan_elements/buffer)";
      out.push_back({"iio", accel ? "imu" : "sensor", e.id, desc});
    }
  } catch (const std::exception& ex) {
    out.clear();
    out.push_back({"iio", "iio_unavailable", "", ex.what()});
  }
  return out;
}

}  // namespace locus::hal::iio
