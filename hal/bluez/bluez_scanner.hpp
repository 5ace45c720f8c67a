// BLE scanning through BlueZ's D-Bus API: the `bluez` sensor source (kind ble).
//
// Why D-Bus and not raw HCI: bluetoothd owns the controller on every Linux board we run on; a second
// raw-HCI user fights it (and needs CAP_NET_RAW). BlueZ's discovery API gives one RSSI report per
// received advertisement when a discovery filter with DuplicateData is set, which is what the BLE
// localizers need. sdbus-c++ (v1 API) is the D-Bus library.
//
// What it does (all on one thread it owns, running its own poll loop over the bus fd and an eventfd,
// so stop() is prompt; every D-Bus call is asynchronous, so a hung bluetoothd never blocks it):
//   1. open(): validates params and connects to the system bus (DBUS_SYSTEM_BUS_ADDRESS if set).
//   2. start(): subscribes to NameOwnerChanged for org.bluez, InterfacesAdded/InterfacesRemoved and
//      PropertiesChanged; asks who owns org.bluez.
//   3. When bluetoothd is there: GetManagedObjects -> the adapter /org/bluez/<adapter> (missing: warn,
//      retry every restart_backoff_s and on its InterfacesAdded), SetDiscoveryFilter({Transport: "le",
//      DuplicateData, RSSI when a threshold is set}), StartDiscovery. Any failure: warn and retry
//      after restart_backoff_s.
//   4. Each RSSI report of a device under that adapter (InterfacesAdded with RSSI, PropertiesChanged
//      with RSSI) is one BleAdvertisement: t_s = CLOCK_MONOTONIC seconds when the signal was read
//      (the node's monotonic clock; D-Bus latency, typically < 1 ms, is included), rssi_dbm, and the
//      device's latest TxPower when BlueZ has reported one. Filtered by `addresses` and
//      `rssi_threshold_dbm`. A full queue drops the advert (SensorQueue::count_drop()).
//   5. bluetoothd leaving the bus (NameOwnerChanged to "") is logged; when the name gets an owner
//      again, step 3 runs again. The source keeps running throughout.
//   6. Losing the system bus itself ends the stream: finished() with error() naming the bus address.
//
// Params (see bluez_schema()): adapter, duplicate_data, rssi_threshold_dbm, addresses,
// restart_backoff_s, call_timeout_s.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "bluez/bluez_parse.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"

namespace locus::hal::bluez {

/// The `bluez` parameter schema.
const ParamSchema& bluez_schema();

/// Validated configuration of a scanner.
struct BluezConfig {
  std::string adapter = "hci0";
  bool duplicate_data = true;
  /// Adverts weaker than this are dropped (and BlueZ is asked not to report them); kNoRssiThreshold = off.
  int rssi_threshold_dbm = kNoRssiThreshold;
  std::vector<MacAddress> addresses;  ///< allow list; empty = every device
  double restart_backoff_s = 1.0;
  double call_timeout_s = 5.0;

  static constexpr int kNoRssiThreshold = -127;
};

/// Params -> BluezConfig. Throws std::runtime_error naming the key and what was expected
/// (an adapter name that cannot be an object path, a malformed entry of `addresses`).
BluezConfig bluez_config_from_params(const Params& params);

/// The system bus address a client would use: $DBUS_SYSTEM_BUS_ADDRESS or the default socket.
std::string system_bus_address();

class BluezScanner final : public SensorSource {
 public:
  BluezScanner();
  ~BluezScanner() override;

  /// [main] Validates params and connects to the system bus; throws std::runtime_error naming the bus
  /// address when it cannot.
  void open(const Params& params, HostContext& ctx) override;
  /// [main] The same with an already validated config (tests, tools).
  void open(const BluezConfig& config, HostContext& ctx);
  SensorKind kind() const override { return SensorKind::Ble; }
  bool live() const override { return true; }
  /// t_s is CLOCK_MONOTONIC at the read (see above).
  bool monotonic_time() const override { return true; }
  void start(SensorQueue& queue) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override;

  /// Counters [any].
  struct Stats {
    std::uint64_t adverts = 0;            ///< BleAdvertisements pushed
    std::uint64_t dropped_full = 0;       ///< lost to a full queue (also counted in the queue)
    std::uint64_t filtered = 0;           ///< RSSI reports dropped by `addresses` / `rssi_threshold_dbm`
    std::uint64_t malformed = 0;          ///< property values or signals that could not be read
    std::uint64_t discovery_starts = 0;   ///< successful StartDiscovery calls
    std::uint64_t bluez_losses = 0;       ///< times org.bluez lost its owner while we ran
    bool scanning = false;                ///< discovery currently running on the adapter
  };
  Stats stats() const noexcept;

 private:
  struct Impl;
  void run(SensorQueue& queue);
  void fail(std::string message);

  std::unique_ptr<Impl> impl_;
  std::thread thread_;
  int wake_fd_ = -1;  ///< eventfd: stop() wakes the loop
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::uint64_t> adverts_{0}, dropped_full_{0}, filtered_{0}, malformed_{0};
  std::atomic<std::uint64_t> discovery_starts_{0}, bluez_losses_{0};
  std::atomic<bool> scanning_{false};
  mutable std::mutex error_mutex_;
  std::string error_;
};

/// Registers the `bluez` sensor source (kind ble).
void register_bluez_source(Registry& registry);

}  // namespace locus::hal::bluez
