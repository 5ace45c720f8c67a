// ble.csv and BLE address text (ble_csv.hpp).
#include "locus/scene/ble_csv.hpp"

#include <cstdio>
#include <string>

#include "stream_detail.hpp"

namespace locus::scene {

using detail::shown;
using detail::to_float;
using detail::trim;

bool parse_ble_address(std::string_view s, std::array<std::uint8_t, 6>& out) noexcept {
  if (s.size() != 17) return false;
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (int i = 0; i < 6; ++i) {
    const int hi = hex(s[i * 3]), lo = hex(s[i * 3 + 1]);
    if (hi < 0 || lo < 0) return false;
    if (i < 5 && s[i * 3 + 2] != ':') return false;
    out[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  return true;
}

std::string format_ble_address(const std::array<std::uint8_t, 6>& a) {
  char b[18];
  std::snprintf(b, sizeof b, "%02X:%02X:%02X:%02X:%02X:%02X", a[0], a[1], a[2], a[3], a[4], a[5]);
  return b;
}

BleCsvReader::BleCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  address_ = csv_.require_column("address");
  rssi_ = csv_.require_column("rssi");
  tx_power_ = csv_.find_column("tx_power");
  channel_ = csv_.find_column("channel");
}

bool BleCsvReader::next(BleAdvertisement& out) {
  if (!csv_.next_row()) return false;
  BleAdvertisement a;
  a.device = device_;
  a.t_s = csv_.number(t_);
  const std::string_view addr = trim(csv_.field(address_));
  if (!parse_ble_address(addr, a.address))
    csv_.fail(address_, "expected an address AA:BB:CC:DD:EE:FF (hex), got " + shown(addr));
  a.rssi_dbm = to_float(csv_, rssi_);
  if (tx_power_ && !csv_.blank(*tx_power_)) {
    a.tx_power_dbm = to_float(csv_, *tx_power_);
    a.has_tx_power = true;
  }
  if (channel_ && !csv_.blank(*channel_)) {
    const long long ch = csv_.integer(*channel_, 0, 39);
    if (ch != 0 && ch < 37) csv_.fail(*channel_, "channel " + std::to_string(ch) + ", expected 37, 38, 39 or 0 (unknown)");
    a.channel = static_cast<std::uint8_t>(ch);
  }
  out = a;
  return true;
}

BleCsvWriter::BleCsvWriter(const std::string& path)
    : CsvWriter(path, {"t", "address", "rssi", "tx_power", "channel"}) {}

void BleCsvWriter::write(const BleAdvertisement& a) {
  std::string line = format_double(a.t_s) + "," + format_ble_address(a.address) + "," + format_float(a.rssi_dbm) +
                     "," + (a.has_tx_power ? format_float(a.tx_power_dbm) : std::string()) + "," +
                     std::to_string(unsigned(a.channel)) + "\n";
  put(line);
}

}  // namespace locus::scene
