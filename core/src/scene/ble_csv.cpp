// ble.csv (ble_csv.hpp); BLE address text is locus/signal.hpp's.
#include "locus/scene/ble_csv.hpp"

#include <cstdio>
#include <string>

#include "stream_detail.hpp"

namespace locus::scene {

using detail::shown;
using detail::to_float;
using detail::trim;

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
