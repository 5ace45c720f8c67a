// Parsing of addresses and D-Bus property values for the BlueZ backend (see bluez_parse.hpp).
#include "bluez/bluez_parse.hpp"

#include <limits>
#include <stdexcept>

#include <sdbus-c++/Error.h>

namespace locus::hal::bluez {

namespace {

int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

/// Parses 6 hex octets separated by `sep` (17 characters).
std::optional<MacAddress> parse_octets(std::string_view text, char sep) noexcept {
  if (text.size() != 17) return std::nullopt;
  MacAddress out{};
  for (std::size_t i = 0; i < 6; ++i) {
    const std::size_t at = i * 3;
    const int hi = hex_digit(text[at]);
    const int lo = hex_digit(text[at + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    if (i < 5 && text[at + 2] != sep) return std::nullopt;
    out[i] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  return out;
}

std::string_view trim(std::string_view s) noexcept {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::optional<MacAddress> parse_mac(std::string_view text) noexcept { return parse_octets(text, ':'); }

std::string format_mac(const MacAddress& address) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out(17, ':');
  for (std::size_t i = 0; i < 6; ++i) {
    out[i * 3] = kHex[address[i] >> 4];
    out[i * 3 + 1] = kHex[address[i] & 0x0f];
  }
  return out;
}

bool valid_adapter_name(std::string_view adapter) noexcept {
  if (adapter.empty() || adapter.size() > 64) return false;
  for (char c : adapter)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

std::string adapter_object_path(std::string_view adapter) { return "/org/bluez/" + std::string(adapter); }

std::optional<MacAddress> address_from_device_path(std::string_view path, std::string_view adapter_path) {
  std::string_view rest;
  if (!adapter_path.empty()) {
    if (path.size() <= adapter_path.size() + 1 || path.substr(0, adapter_path.size()) != adapter_path ||
        path[adapter_path.size()] != '/')
      return std::nullopt;
    rest = path.substr(adapter_path.size() + 1);
  } else {
    constexpr std::string_view kRoot = "/org/bluez/";
    if (path.substr(0, kRoot.size()) != kRoot) return std::nullopt;
    const std::string_view after = path.substr(kRoot.size());
    const auto slash = after.find('/');
    if (slash == std::string_view::npos || slash == 0) return std::nullopt;
    rest = after.substr(slash + 1);
  }
  constexpr std::string_view kDev = "dev_";
  if (rest.substr(0, kDev.size()) != kDev) return std::nullopt;
  // Exactly "dev_XX_XX_XX_XX_XX_XX": nothing after it (a service object "dev_.../service0001" is not a device).
  return parse_octets(rest.substr(kDev.size()), '_');
}

std::vector<MacAddress> parse_address_list(std::string_view text) {
  std::vector<MacAddress> out;
  if (trim(text).empty()) return out;
  std::size_t index = 0;
  while (true) {
    const auto comma = text.find(',');
    const std::string_view entry = trim(text.substr(0, comma));
    ++index;
    const auto mac = parse_mac(entry);
    if (!mac)
      throw std::invalid_argument("entry " + std::to_string(index) + " '" + std::string(entry) +
                                  "' is not a Bluetooth address (expected AA:BB:CC:DD:EE:FF)");
    out.push_back(*mac);
    if (comma == std::string_view::npos) break;
    text.remove_prefix(comma + 1);
  }
  return out;
}

std::string IntProperty::problem(std::string_view key) const {
  switch (status) {
    case Status::Absent:
    case Status::Ok: return {};
    case Status::WrongType:
      return std::string(key) + " has D-Bus type '" + type + "' (expected an integer; BlueZ sends int16 'n')";
    case Status::OutOfRange:
      return std::string(key) + " = " + std::to_string(value) + " is out of the plausible range";
  }
  return {};
}

IntProperty read_int_property(const PropertyMap& props, const std::string& key, std::int64_t min,
                              std::int64_t max) {
  IntProperty out;
  const auto it = props.find(key);
  if (it == props.end()) return out;
  const sdbus::Variant& v = it->second;
  try {
    if (v.isEmpty()) {
      out.status = IntProperty::Status::WrongType;
      out.type = "(empty)";
      return out;
    }
    out.type = v.peekValueType();
    std::int64_t value = 0;
    if (out.type == "n") value = v.get<std::int16_t>();
    else if (out.type == "y") value = v.get<std::uint8_t>();
    else if (out.type == "q") value = v.get<std::uint16_t>();
    else if (out.type == "i") value = v.get<std::int32_t>();
    else if (out.type == "u") value = v.get<std::uint32_t>();
    else if (out.type == "x") value = v.get<std::int64_t>();
    else if (out.type == "t") {
      const std::uint64_t u = v.get<std::uint64_t>();
      value = u > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())
                  ? std::numeric_limits<std::int64_t>::max()
                  : static_cast<std::int64_t>(u);
    } else {
      out.status = IntProperty::Status::WrongType;
      return out;
    }
    out.value = value;
    out.status = (value < min || value > max) ? IntProperty::Status::OutOfRange : IntProperty::Status::Ok;
  } catch (const sdbus::Error&) {
    out.status = IntProperty::Status::WrongType;
    if (out.type.empty()) out.type = "(unreadable)";
  }
  return out;
}

DeviceProperties parse_device_properties(const PropertyMap& props) {
  DeviceProperties out;
  const auto it = props.find("Address");
  if (it != props.end()) {
    try {
      if (!it->second.isEmpty() && it->second.peekValueType() == "s") out.address = parse_mac(it->second.get<std::string>());
    } catch (const sdbus::Error&) {
    }
    out.address_malformed = !out.address.has_value();
  }
  out.rssi = read_int_property(props, "RSSI", kMinDbm, kMaxDbm);
  out.tx_power = read_int_property(props, "TxPower", kMinDbm, kMaxDbm);
  return out;
}

}  // namespace locus::hal::bluez
