// Listing BlueZ adapters (see bluez_devices.hpp).
#include "bluez/bluez_devices.hpp"

#include <algorithm>
#include <map>
#include <string>

#include <sdbus-c++/sdbus-c++.h>

#include "bluez/bluez_parse.hpp"
#include "bluez/bluez_scanner.hpp"

namespace locus::hal {

namespace {

DeviceInfo unavailable(std::string why) { return DeviceInfo{"bluez", "unavailable", "", std::move(why)}; }

std::string string_prop(const bluez::PropertyMap& props, const std::string& key) {
  const auto it = props.find(key);
  if (it == props.end()) return {};
  try {
    if (!it->second.isEmpty() && it->second.peekValueType() == "s") return it->second.get<std::string>();
  } catch (const sdbus::Error&) {
  }
  return {};
}

std::optional<bool> bool_prop(const bluez::PropertyMap& props, const std::string& key) {
  const auto it = props.find(key);
  if (it == props.end()) return std::nullopt;
  try {
    if (!it->second.isEmpty() && it->second.peekValueType() == "b") return it->second.get<bool>();
  } catch (const sdbus::Error&) {
  }
  return std::nullopt;
}

std::string error_text(const sdbus::Error& e) {
  return e.getMessage().empty() ? e.getName() : e.getName() + ": " + e.getMessage();
}

}  // namespace

std::vector<DeviceInfo> list_bluez_adapters(double timeout_s) {
  const std::string bus = bluez::system_bus_address();
  std::unique_ptr<sdbus::IConnection> conn;
  try {
    conn = sdbus::createSystemBusConnection();
  } catch (const sdbus::Error& e) {
    return {unavailable("cannot connect to the D-Bus system bus " + bus + " (" + error_text(e) + ")")};
  }
  std::map<sdbus::ObjectPath, std::map<std::string, bluez::PropertyMap>> objects;
  try {
    auto proxy = sdbus::createProxy(*conn, "org.bluez", "/");
    auto call = proxy->createMethodCall("org.freedesktop.DBus.ObjectManager", "GetManagedObjects");
    auto reply = proxy->callMethod(call, static_cast<std::uint64_t>(std::max(0.01, timeout_s) * 1e6));
    reply >> objects;
  } catch (const sdbus::Error& e) {
    if (e.getName() == "org.freedesktop.DBus.Error.ServiceUnknown" ||
        e.getName() == "org.freedesktop.DBus.Error.NameHasNoOwner")
      return {unavailable("org.bluez is not on the system bus " + bus + " (is bluetoothd running?)")};
    return {unavailable("GetManagedObjects on org.bluez failed (" + error_text(e) + ")")};
  }
  std::vector<DeviceInfo> out;
  for (const auto& [path, ifaces] : objects) {
    const auto a = ifaces.find("org.bluez.Adapter1");
    if (a == ifaces.end()) continue;
    const std::string& p = path;
    DeviceInfo info{"bluez", "adapter", p.substr(p.rfind('/') + 1), {}};
    const std::string address = string_prop(a->second, "Address");
    const std::string name = string_prop(a->second, "Name");
    const auto powered = bool_prop(a->second, "Powered");
    const auto discovering = bool_prop(a->second, "Discovering");
    info.description = "address " + (address.empty() ? std::string("unknown") : address);
    if (!name.empty()) info.description += ", name '" + name + "'";
    if (powered) info.description += *powered ? ", powered" : ", powered off";
    if (discovering) info.description += *discovering ? ", discovering" : ", not discovering";
    out.push_back(std::move(info));
  }
  std::sort(out.begin(), out.end(), [](const DeviceInfo& x, const DeviceInfo& y) { return x.id < y.id; });
  if (out.empty()) out.push_back(unavailable("bluetoothd on the system bus " + bus + " has no adapter"));
  return out;
}

}  // namespace locus::hal
