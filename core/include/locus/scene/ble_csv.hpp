// ble.csv of a scene device (docs/scene-format.md): BleAdvertisement rows, read and written, and
// the "AA:BB:CC:DD:EE:FF" address text they use.
#pragma once

#include "locus/signal.hpp"
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "locus/events.hpp"
#include "locus/scene/csv.hpp"

namespace locus::scene {

/// BLE addresses "AA:BB:CC:DD:EE:FF": one parser and formatter, with the signal description
/// (locus/signal.hpp), where a ble signal's address is checked.
using locus::format_ble_address;
using locus::parse_ble_address;

/// ble.csv: t, address, rssi required; tx_power (empty cell = absent), channel (0 or 37..39; empty =
/// unknown) optional. Row order is not required by the format and not checked.
class BleCsvReader {
 public:
  BleCsvReader(const std::string& path, DeviceId device);
  bool next(BleAdvertisement& out);

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, address_, rssi_;
  std::optional<std::size_t> tx_power_, channel_;
};

/// Writes ble.csv (t, address, rssi, tx_power, channel; tx_power empty when !has_tx_power).
class BleCsvWriter : public CsvWriter {
 public:
  explicit BleCsvWriter(const std::string& path);
  void write(const BleAdvertisement& a);
};

}  // namespace locus::scene
