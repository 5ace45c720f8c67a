#include "devices/device_list.hpp"

#include <algorithm>
#include <exception>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "iio/iio_devices.hpp"
#include "locus/build_options.hpp"
#if LOCUS_HAVE_ALSA
#include "alsa/alsa_devices.hpp"
#endif
#if LOCUS_HAVE_BLUEZ
#include "bluez/bluez_devices.hpp"
#endif
#if LOCUS_HAVE_JACK
#include "jack/jack_devices.hpp"
#endif

namespace locus::app {

namespace {

/// Runs one backend's lister; an exception becomes its "unavailable" entry (listing never fails).
void collect(std::vector<hal::DeviceInfo>& out, const char* backend,
             const std::function<std::vector<hal::DeviceInfo>()>& list) {
  try {
    std::vector<hal::DeviceInfo> got = list();
    out.insert(out.end(), std::make_move_iterator(got.begin()), std::make_move_iterator(got.end()));
  } catch (const std::exception& e) {
    out.push_back(hal::DeviceInfo{backend, "unavailable", "", e.what()});
  }
}

}  // namespace

hal::DeviceInfo not_built_entry(std::string_view backend) {
  const build::OptionalBackend* b = build::find_optional_backend(backend);
  if (b == nullptr) throw std::invalid_argument("'" + std::string(backend) + "' is not an optional backend");
  return hal::DeviceInfo{std::string(backend), kNotBuiltKind, "", build::not_built_reason(*b)};
}

std::vector<hal::DeviceInfo> list_all_devices(const DevicesOptions& o) {
  std::vector<hal::DeviceInfo> out;
#if LOCUS_HAVE_ALSA
  collect(out, "alsa", [] { return hal::alsa::list_alsa_devices(); });
#else
  out.push_back(not_built_entry("alsa"));
#endif
#if LOCUS_HAVE_JACK
  collect(out, "jack", [&] { return hal::list_jack_ports(o.jack_server); });
#else
  out.push_back(not_built_entry("jack"));
#endif
  collect(out, "iio", [&] { return hal::iio::list_iio_devices(o.iio_root); });
#if LOCUS_HAVE_BLUEZ
  collect(out, "bluez", [] { return hal::list_bluez_adapters(); });
#else
  out.push_back(not_built_entry("bluez"));
#endif
  return out;
}

std::string format_devices_table(const std::vector<hal::DeviceInfo>& devices) {
  const char* headers[] = {"BACKEND", "KIND", "ID", "DESCRIPTION"};
  std::size_t w[3] = {7, 4, 2};
  for (const auto& d : devices) {
    w[0] = std::max(w[0], d.backend.size());
    w[1] = std::max(w[1], d.kind.size());
    w[2] = std::max(w[2], d.id.size());
  }
  std::ostringstream os;
  const auto line = [&](const std::string& a, const std::string& b, const std::string& c, const std::string& desc) {
    os << a << std::string(w[0] - a.size() + 2, ' ') << b << std::string(w[1] - b.size() + 2, ' ') << c
       << std::string(w[2] - c.size() + 2, ' ') << desc << "\n";
  };
  line(headers[0], headers[1], headers[2], headers[3]);
  for (const auto& d : devices) {
    // One line per entry: a description with line breaks would break the table.
    std::string desc = d.description;
    std::replace(desc.begin(), desc.end(), '\n', ' ');
    line(d.backend, d.kind, d.id.empty() ? "-" : d.id, desc);
  }
  return os.str();
}

std::string format_devices_json(const std::vector<hal::DeviceInfo>& devices) {
  nlohmann::ordered_json arr = nlohmann::ordered_json::array();
  for (const auto& d : devices) {
    arr.push_back({{"backend", d.backend}, {"kind", d.kind}, {"id", d.id}, {"description", d.description}});
  }
  // Replace invalid UTF-8 (a card name from a driver) instead of throwing.
  return arr.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace);
}

int run_devices(const DevicesOptions& options) {
  const std::vector<hal::DeviceInfo> devices = list_all_devices(options);
  if (options.json) {
    std::cout << format_devices_json(devices) << "\n";
  } else {
    std::cout << format_devices_table(devices);
  }
  std::cout.flush();
  return 0;
}

}  // namespace locus::app
