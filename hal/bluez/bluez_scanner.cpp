// The `bluez` BLE scanner (see bluez_scanner.hpp for what and why).
//
// Threading: open() makes the bus connection on the main thread; from start() to the end of stop()
// the connection, the proxies and every callback belong to the scanner thread only (sd-bus
// connections are not thread-safe). The loop polls the bus fd and an eventfd that stop() writes, and
// runs sdbus-c++'s processPendingRequest(): signal handlers and async reply handlers run inside it.
// No call blocks on bluetoothd: every method call is asynchronous with call_timeout_s, and its reply
// handler checks the setup generation so a reply from a bluetoothd that has gone since is ignored.
#include "bluez/bluez_scanner.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <unordered_map>

#include <sdbus-c++/sdbus-c++.h>

namespace locus::hal::bluez {

namespace {

constexpr const char* kBluezService = "org.bluez";
constexpr const char* kAdapterIface = "org.bluez.Adapter1";
constexpr const char* kDeviceIface = "org.bluez.Device1";
constexpr const char* kObjectManagerIface = "org.freedesktop.DBus.ObjectManager";
constexpr const char* kPropertiesIface = "org.freedesktop.DBus.Properties";
constexpr std::uint64_t kMaxMalformedLogs = 10;  // then only counted (reported at stop)

using SteadyClock = std::chrono::steady_clock;
using ManagedObjects = std::map<sdbus::ObjectPath, std::map<std::string, PropertyMap>>;

std::string dbus_error_text(const sdbus::Error& e) {
  if (e.getMessage().empty()) return e.getName();
  return e.getName() + ": " + e.getMessage();
}

std::string fmt_s(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", s);
  return buf;
}

/// CLOCK_MONOTONIC in seconds (std::chrono::steady_clock is CLOCK_MONOTONIC on Linux).
double monotonic_s() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

// ------------------------------------------------------------------ params

const ParamSchema& bluez_schema() {
  static const ParamSchema schema{
      string_param("adapter", std::string("hci0"),
                   "BlueZ adapter to scan with (its D-Bus object is /org/bluez/<adapter>)."),
      bool_param("duplicate_data", true,
                 "Report every received advertisement (BlueZ discovery filter DuplicateData); false: "
                 "BlueZ reports a device only when its data changes."),
      int_param("rssi_threshold_dbm", std::int64_t{BluezConfig::kNoRssiThreshold}, -127, 20, "dBm",
                "Drop advertisements weaker than this (also BlueZ's discovery filter RSSI); -127 = no threshold."),
      string_param("addresses", std::string(""),
                   "Comma-separated allow list of device addresses (AA:BB:CC:DD:EE:FF); empty = every device."),
      float_param("restart_backoff_s", 1.0, 0.05, 60.0, "s",
                  "Wait before retrying the adapter lookup / discovery setup after a failure."),
      float_param("call_timeout_s", 5.0, 0.1, 60.0, "s", "Timeout of each D-Bus call to bluetoothd."),
  };
  return schema;
}

BluezConfig bluez_config_from_params(const Params& params) {
  BluezConfig c;
  c.adapter = params.get_string("adapter");
  if (!valid_adapter_name(c.adapter))
    throw std::runtime_error("bluez: adapter '" + c.adapter +
                             "' is not an adapter name (expected letters, digits or '_', e.g. hci0)");
  c.duplicate_data = params.get_bool("duplicate_data");
  c.rssi_threshold_dbm = static_cast<int>(params.get_int("rssi_threshold_dbm"));
  try {
    c.addresses = parse_address_list(params.get_string("addresses"));
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("bluez: addresses: ") + e.what());
  }
  c.restart_backoff_s = params.get_float("restart_backoff_s");
  c.call_timeout_s = params.get_float("call_timeout_s");
  return c;
}

std::string system_bus_address() {
  const char* env = std::getenv("DBUS_SYSTEM_BUS_ADDRESS");
  if (env != nullptr && *env != '\0') return env;
  return "unix:path=/run/dbus/system_bus_socket";
}

// ------------------------------------------------------------------ the scanner state (scanner thread)

struct BluezScanner::Impl {
  BluezScanner& self;
  BluezConfig config;
  std::string adapter_path;
  std::string bus_address;
  Logger* log = nullptr;
  DeviceId device;

  std::unique_ptr<sdbus::IConnection> conn;
  // Thread-confined from start() on:
  SensorQueue* queue = nullptr;
  std::unique_ptr<sdbus::IProxy> bus_proxy;      // org.freedesktop.DBus
  std::unique_ptr<sdbus::IProxy> manager_proxy;  // org.bluez /
  std::unique_ptr<sdbus::IProxy> adapter_proxy;  // org.bluez /org/bluez/<adapter>
  std::vector<sdbus::Slot> matches;

  enum class Phase : std::uint8_t { NoBluez, Querying, NoAdapter, Configuring, Scanning, Backoff };
  Phase phase = Phase::NoBluez;
  std::string bluez_owner;          // unique name of org.bluez's owner, "" = not on the bus
  bool bluez_seen = false;          // org.bluez had an owner at some point while we ran
  bool restarting = false;          // bluetoothd came back after leaving: log when scanning again
  bool adapter_missing_logged = false;
  std::string adapter_missing_have;  // the adapters bluetoothd had when that was logged
  std::uint64_t generation = 0;     // bumped by every setup attempt / loss; stale replies are ignored
  std::optional<SteadyClock::time_point> retry_at;

  struct DeviceState {
    MacAddress address{};
    bool has_tx_power = false;
    float tx_power_dbm = 0.0f;
  };
  std::unordered_map<std::string, DeviceState> devices;  // by object path
  std::uint64_t malformed_logged = 0;

  explicit Impl(BluezScanner& s) : self(s) {}

  std::uint64_t timeout_us() const { return static_cast<std::uint64_t>(config.call_timeout_s * 1e6); }

  // ---------------------------------------------------------------- helpers

  void malformed(const std::string& what) {
    self.malformed_.fetch_add(1, std::memory_order_relaxed);
    if (malformed_logged < kMaxMalformedLogs) {
      ++malformed_logged;
      log->warn("ignored malformed data from bluetoothd: " + what +
                (malformed_logged == kMaxMalformedLogs ? " (further ones are only counted)" : ""));
    }
  }

  bool allowed(const MacAddress& a) const {
    return config.addresses.empty() ||
           std::find(config.addresses.begin(), config.addresses.end(), a) != config.addresses.end();
  }

  void set_scanning(bool on) { self.scanning_.store(on, std::memory_order_relaxed); }

  void schedule_retry() {
    phase = Phase::Backoff;
    retry_at = SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(
                                        std::chrono::duration<double>(config.restart_backoff_s));
  }

  /// Forget the current bluetoothd session: pending replies become stale.
  void reset_session() {
    ++generation;
    set_scanning(false);
    retry_at.reset();
    devices.clear();
  }

  // ---------------------------------------------------------------- adverts

  /// Updates the per-device cache from a Device1 property dict; pushes an advert when it has an RSSI.
  void device_properties(const std::string& path, const PropertyMap& props, bool emit, double t_s) {
    const auto path_address = address_from_device_path(path, adapter_path);
    if (!path_address) return;  // not a device of our adapter (another adapter, a GATT object)
    const DeviceProperties p = parse_device_properties(props);
    auto [it, inserted] = devices.try_emplace(path);
    DeviceState& st = it->second;
    if (inserted) st.address = *path_address;
    if (p.address) st.address = *p.address;
    else if (p.address_malformed) malformed(path + ": Address is not a string AA:BB:CC:DD:EE:FF");
    if (p.tx_power.ok()) {
      st.has_tx_power = true;
      st.tx_power_dbm = static_cast<float>(p.tx_power.value);
    } else if (p.tx_power.status != IntProperty::Status::Absent) {
      malformed(path + ": " + p.tx_power.problem("TxPower"));
    }
    if (p.rssi.status == IntProperty::Status::Absent) return;
    if (!p.rssi.ok()) {
      malformed(path + ": " + p.rssi.problem("RSSI"));
      return;
    }
    if (!emit) return;
    if (!allowed(st.address) ||
        (config.rssi_threshold_dbm != BluezConfig::kNoRssiThreshold && p.rssi.value < config.rssi_threshold_dbm)) {
      self.filtered_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    BleAdvertisement a;
    a.device = device;
    a.t_s = t_s;
    a.address = st.address;
    a.rssi_dbm = static_cast<float>(p.rssi.value);
    a.has_tx_power = st.has_tx_power;
    a.tx_power_dbm = st.has_tx_power ? st.tx_power_dbm : 0.0f;
    if (queue->try_push(Event{a})) {
      self.adverts_.fetch_add(1, std::memory_order_relaxed);
    } else {
      queue->count_drop();
      self.dropped_full_.fetch_add(1, std::memory_order_relaxed);
    }
  }

  // ---------------------------------------------------------------- setup chain

  /// GetManagedObjects -> SetDiscoveryFilter -> StartDiscovery, each asynchronous.
  void begin_setup() {
    reset_session();
    if (bluez_owner.empty()) {
      phase = Phase::NoBluez;
      return;
    }
    phase = Phase::Querying;
    const std::uint64_t g = generation;
    auto call = manager_proxy->createMethodCall(kObjectManagerIface, "GetManagedObjects");
    (void)manager_proxy->callMethod(
        call, [this, g](sdbus::MethodReply& reply, const sdbus::Error* err) { on_managed_objects(g, reply, err); },
        timeout_us());
  }

  void on_managed_objects(std::uint64_t g, sdbus::MethodReply& reply, const sdbus::Error* err) {
    if (g != generation) return;
    if (err != nullptr) {
      log->warn("GetManagedObjects on org.bluez failed (" + dbus_error_text(*err) + "); retrying in " +
                fmt_s(config.restart_backoff_s) + " s");
      schedule_retry();
      return;
    }
    ManagedObjects objects;
    try {
      reply >> objects;
    } catch (const sdbus::Error& e) {
      malformed("GetManagedObjects reply: " + dbus_error_text(e));
      schedule_retry();
      return;
    }
    const auto adapter = objects.find(sdbus::ObjectPath(adapter_path));
    if (adapter == objects.end() || adapter->second.count(kAdapterIface) == 0) {
      std::string have;
      for (const auto& [path, ifaces] : objects)
        if (ifaces.count(kAdapterIface) != 0) {
          const std::string& p = path;
          have += (have.empty() ? "" : ", ") + p.substr(p.rfind('/') + 1);
        }
      have = have.empty() ? std::string("no adapter") : "adapters: " + have;
      if (!adapter_missing_logged || have != adapter_missing_have) {  // once, and again when the set changes
        log->warn("adapter '" + config.adapter + "' (" + adapter_path + ") not found on the system bus " +
                  bus_address + " (bluetoothd has " + have + "); waiting for it, retrying every " +
                  fmt_s(config.restart_backoff_s) + " s");
        adapter_missing_logged = true;
        adapter_missing_have = have;
      }
      schedule_retry();
      phase = Phase::NoAdapter;
      return;
    }
    adapter_missing_logged = false;
    const PropertyMap& aprops = adapter->second.at(kAdapterIface);
    if (auto pw = aprops.find("Powered"); pw != aprops.end()) {
      try {
        if (!pw->second.isEmpty() && pw->second.peekValueType() == "b" && !pw->second.get<bool>())
          log->warn("adapter " + config.adapter + " is powered off; discovery will fail until it is powered");
      } catch (const sdbus::Error&) {
      }
    }
    // Cache what bluetoothd already knows (address, TxPower); cached RSSI values are old news, not adverts.
    for (const auto& [path, ifaces] : objects) {
      const auto dev = ifaces.find(kDeviceIface);
      if (dev != ifaces.end()) device_properties(path, dev->second, /*emit=*/false, 0.0);
    }
    phase = Phase::Configuring;
    std::map<std::string, sdbus::Variant> filter;
    filter["Transport"] = sdbus::Variant(std::string("le"));
    filter["DuplicateData"] = sdbus::Variant(config.duplicate_data);
    if (config.rssi_threshold_dbm != BluezConfig::kNoRssiThreshold)
      filter["RSSI"] = sdbus::Variant(static_cast<std::int16_t>(config.rssi_threshold_dbm));
    auto call = adapter_proxy->createMethodCall(kAdapterIface, "SetDiscoveryFilter");
    call << filter;
    (void)adapter_proxy->callMethod(
        call, [this, g](sdbus::MethodReply&, const sdbus::Error* e) { on_filter_set(g, e); }, timeout_us());
  }

  void on_filter_set(std::uint64_t g, const sdbus::Error* err) {
    if (g != generation) return;
    if (err != nullptr) {
      log->warn("SetDiscoveryFilter on " + adapter_path + " failed (" + dbus_error_text(*err) +
                "); retrying in " + fmt_s(config.restart_backoff_s) + " s");
      schedule_retry();
      return;
    }
    auto call = adapter_proxy->createMethodCall(kAdapterIface, "StartDiscovery");
    (void)adapter_proxy->callMethod(
        call, [this, g](sdbus::MethodReply&, const sdbus::Error* e) { on_discovery_started(g, e); }, timeout_us());
  }

  void on_discovery_started(std::uint64_t g, const sdbus::Error* err) {
    if (g != generation) return;
    // InProgress: this client's discovery session is already running (BlueZ keeps one per client).
    if (err != nullptr && err->getName() != "org.bluez.Error.InProgress") {
      log->warn("StartDiscovery on " + adapter_path + " failed (" + dbus_error_text(*err) + "); retrying in " +
                fmt_s(config.restart_backoff_s) + " s");
      schedule_retry();
      return;
    }
    phase = Phase::Scanning;
    retry_at.reset();
    set_scanning(true);
    self.discovery_starts_.fetch_add(1, std::memory_order_relaxed);
    std::string filter = "Transport=le DuplicateData=" + std::string(config.duplicate_data ? "true" : "false");
    if (config.rssi_threshold_dbm != BluezConfig::kNoRssiThreshold)
      filter += " RSSI=" + std::to_string(config.rssi_threshold_dbm);
    log->info(std::string() + (restarting ? "scanning again after bluetoothd came back" : "scanning") +
              " on " + config.adapter + " (" + filter + ", " +
              (config.addresses.empty() ? std::string("all devices") :
                                          std::to_string(config.addresses.size()) + " allowed addresses") + ")");
    restarting = false;
  }

  // ---------------------------------------------------------------- bus / bluetoothd presence

  void bluez_appeared(const std::string& owner) {
    bluez_owner = owner;
    if (bluez_seen) {
      log->info("org.bluez is back on the system bus (" + owner + "); setting up discovery on " +
                config.adapter + " again");
      restarting = true;
    }
    bluez_seen = true;
    adapter_missing_logged = false;
    begin_setup();
  }

  void bluez_vanished() {
    log->warn("bluetoothd (org.bluez, " + bluez_owner + ") left the system bus; scanning on " +
              config.adapter + " stopped, waiting for it to come back");
    self.bluez_losses_.fetch_add(1, std::memory_order_relaxed);
    bluez_owner.clear();
    reset_session();
    phase = Phase::NoBluez;
  }

  void on_name_owner_changed(sdbus::Message& msg) {
    std::string name, old_owner, new_owner;
    try {
      msg >> name >> old_owner >> new_owner;
    } catch (const sdbus::Error& e) {
      malformed("NameOwnerChanged: " + dbus_error_text(e));
      return;
    }
    if (name != kBluezService) return;
    if (!old_owner.empty() && old_owner == bluez_owner) bluez_vanished();
    if (!new_owner.empty() && new_owner != bluez_owner) bluez_appeared(new_owner);
  }

  bool from_bluez(const sdbus::Message& msg) const {
    return !bluez_owner.empty() && msg.getSender() == bluez_owner;
  }

  void on_interfaces_added(sdbus::Message& msg) {
    const double t_s = monotonic_s();
    if (!from_bluez(msg)) return;
    sdbus::ObjectPath path;
    std::map<std::string, PropertyMap> ifaces;
    try {
      msg >> path >> ifaces;
    } catch (const sdbus::Error& e) {
      malformed("InterfacesAdded: " + dbus_error_text(e));
      return;
    }
    if (path == adapter_path && ifaces.count(kAdapterIface) != 0) {
      if (phase == Phase::NoAdapter || phase == Phase::Backoff) {
        log->info("adapter " + config.adapter + " appeared; setting up discovery");
        begin_setup();
      }
      return;
    }
    const auto dev = ifaces.find(kDeviceIface);
    if (dev != ifaces.end()) device_properties(path, dev->second, phase == Phase::Scanning, t_s);
  }

  void on_interfaces_removed(sdbus::Message& msg) {
    if (!from_bluez(msg)) return;
    sdbus::ObjectPath path;
    std::vector<std::string> ifaces;
    try {
      msg >> path >> ifaces;
    } catch (const sdbus::Error& e) {
      malformed("InterfacesRemoved: " + dbus_error_text(e));
      return;
    }
    const bool adapter_gone =
        path == adapter_path && std::find(ifaces.begin(), ifaces.end(), kAdapterIface) != ifaces.end();
    if (adapter_gone) {
      log->warn("adapter " + config.adapter + " was removed; waiting for it to come back");
      reset_session();
      adapter_missing_logged = true;
      schedule_retry();
      phase = Phase::NoAdapter;
      return;
    }
    if (std::find(ifaces.begin(), ifaces.end(), kDeviceIface) != ifaces.end()) devices.erase(path);
  }

  void on_properties_changed(sdbus::Message& msg) {
    const double t_s = monotonic_s();
    if (!from_bluez(msg)) return;
    std::string iface;
    PropertyMap changed;
    try {
      msg >> iface >> changed;
    } catch (const sdbus::Error& e) {
      malformed("PropertiesChanged: " + dbus_error_text(e));
      return;
    }
    const std::string path = msg.getPath();
    if (iface == kDeviceIface) {
      device_properties(path, changed, phase == Phase::Scanning, t_s);
      return;
    }
    if (iface != kAdapterIface || path != adapter_path) return;
    const auto read_bool = [&](const char* key) -> std::optional<bool> {
      const auto it = changed.find(key);
      if (it == changed.end()) return std::nullopt;
      try {
        if (!it->second.isEmpty() && it->second.peekValueType() == "b") return it->second.get<bool>();
      } catch (const sdbus::Error&) {
      }
      malformed(path + ": " + key + " is not a boolean");
      return std::nullopt;
    };
    const auto powered = read_bool("Powered");
    const auto discovering = read_bool("Discovering");
    if (powered == true && phase != Phase::Scanning && phase != Phase::Configuring && phase != Phase::Querying) {
      log->info("adapter " + config.adapter + " was powered on; setting up discovery");
      begin_setup();
    } else if (discovering == false && phase == Phase::Scanning) {
      log->warn("discovery on " + config.adapter + " stopped (Discovering = false); restarting it in " +
                fmt_s(config.restart_backoff_s) + " s");
      reset_session();
      schedule_retry();
    }
  }

  // ---------------------------------------------------------------- lifecycle (scanner thread)

  void subscribe() {
    bus_proxy = sdbus::createProxy(*conn, "org.freedesktop.DBus", "/org/freedesktop/DBus");
    manager_proxy = sdbus::createProxy(*conn, kBluezService, "/");
    adapter_proxy = sdbus::createProxy(*conn, kBluezService, adapter_path);
    // Sender is checked in the handlers against the tracked unique name of org.bluez (a match on the
    // well-known name would silently depend on the bus resolving it).
    matches.push_back(conn->addMatch(
        "type='signal',sender='org.freedesktop.DBus',path='/org/freedesktop/DBus',interface='org.freedesktop.DBus',"
        "member='NameOwnerChanged',arg0='org.bluez'",
        [this](sdbus::Message& m) { on_name_owner_changed(m); }));
    matches.push_back(conn->addMatch(
        "type='signal',interface='org.freedesktop.DBus.ObjectManager',member='InterfacesAdded'",
        [this](sdbus::Message& m) { on_interfaces_added(m); }));
    matches.push_back(conn->addMatch(
        "type='signal',interface='org.freedesktop.DBus.ObjectManager',member='InterfacesRemoved'",
        [this](sdbus::Message& m) { on_interfaces_removed(m); }));
    matches.push_back(conn->addMatch(std::string("type='signal',interface='") + kPropertiesIface +
                                         "',member='PropertiesChanged',path_namespace='" + adapter_path + "'",
                                     [this](sdbus::Message& m) { on_properties_changed(m); }));
    // Who owns org.bluez now (the match above catches every later change).
    auto call = bus_proxy->createMethodCall("org.freedesktop.DBus", "GetNameOwner");
    call << std::string(kBluezService);
    (void)bus_proxy->callMethod(
        call,
        [this](sdbus::MethodReply& reply, const sdbus::Error* err) {
          if (err != nullptr) {
            if (bluez_owner.empty())
              log->warn("org.bluez is not on the system bus " + bus_address + " (" + dbus_error_text(*err) +
                        "; is bluetoothd running?); waiting for it");
            return;
          }
          std::string owner;
          try {
            reply >> owner;
          } catch (const sdbus::Error& e) {
            malformed("GetNameOwner reply: " + dbus_error_text(e));
            return;
          }
          if (!owner.empty() && owner != bluez_owner && bluez_owner.empty()) bluez_appeared(owner);
        },
        timeout_us());
  }

  /// Best effort: ask bluetoothd to stop our discovery session (it also ends it when we disconnect).
  void stop_discovery() {
    if (bluez_owner.empty() || !adapter_proxy) return;
    try {
      auto call = adapter_proxy->createMethodCall(kAdapterIface, "StopDiscovery");
      call.dontExpectReply();
      (void)adapter_proxy->callMethod(call);
    } catch (const sdbus::Error&) {
    }
  }

  void teardown() {
    matches.clear();
    adapter_proxy.reset();
    manager_proxy.reset();
    bus_proxy.reset();
    conn.reset();  // flushes what is queued (StopDiscovery) and closes
    set_scanning(false);
    phase = Phase::NoBluez;
    bluez_owner.clear();
    bluez_seen = false;
    restarting = false;
    devices.clear();
  }
};

// ------------------------------------------------------------------ BluezScanner

BluezScanner::BluezScanner() : impl_(std::make_unique<Impl>(*this)) {}

BluezScanner::~BluezScanner() {
  stop();
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void BluezScanner::open(const Params& params, HostContext& ctx) { open(bluez_config_from_params(params), ctx); }

void BluezScanner::open(const BluezConfig& config, HostContext& ctx) {
  if (thread_.joinable()) throw std::runtime_error("bluez: open() while running");
  if (!valid_adapter_name(config.adapter))
    throw std::runtime_error("bluez: adapter '" + config.adapter + "' is not an adapter name (e.g. hci0)");
  if (!(config.restart_backoff_s > 0.0) || !(config.call_timeout_s > 0.0))
    throw std::runtime_error("bluez: restart_backoff_s and call_timeout_s must be > 0");
  const std::string bus = system_bus_address();
  std::unique_ptr<sdbus::IConnection> conn;
  try {
    conn = sdbus::createSystemBusConnection();
  } catch (const sdbus::Error& e) {
    throw std::runtime_error("bluez: cannot connect to the D-Bus system bus " + bus + " (" + dbus_error_text(e) +
                             ")");
  }
  impl_->config = config;
  impl_->adapter_path = adapter_object_path(config.adapter);
  impl_->log = &ctx.log;
  impl_->device = DeviceId(ctx.device);
  impl_->bus_address = bus;
  impl_->conn = std::move(conn);
  if (wake_fd_ < 0) {
    wake_fd_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    if (wake_fd_ < 0) throw std::runtime_error(std::string("bluez: eventfd: ") + std::strerror(errno));
  }
  {
    std::lock_guard lock(error_mutex_);
    error_.clear();
  }
  finished_.store(false, std::memory_order_release);
}

std::string BluezScanner::error() const {
  std::lock_guard lock(error_mutex_);
  return error_;
}

BluezScanner::Stats BluezScanner::stats() const noexcept {
  Stats s;
  s.adverts = adverts_.load(std::memory_order_relaxed);
  s.dropped_full = dropped_full_.load(std::memory_order_relaxed);
  s.filtered = filtered_.load(std::memory_order_relaxed);
  s.malformed = malformed_.load(std::memory_order_relaxed);
  s.discovery_starts = discovery_starts_.load(std::memory_order_relaxed);
  s.bluez_losses = bluez_losses_.load(std::memory_order_relaxed);
  s.scanning = scanning_.load(std::memory_order_relaxed);
  return s;
}

void BluezScanner::fail(std::string message) {
  {
    std::lock_guard lock(error_mutex_);
    if (error_.empty()) error_ = std::move(message);
  }
  finished_.store(true, std::memory_order_release);
}

void BluezScanner::start(SensorQueue& queue) {
  if (impl_->log == nullptr) throw std::runtime_error("bluez: start() before open()");
  if (thread_.joinable()) throw std::runtime_error("bluez: start() while already running");
  if (!impl_->conn) {  // stopped before: connect again
    try {
      impl_->conn = sdbus::createSystemBusConnection();
    } catch (const sdbus::Error& e) {
      throw std::runtime_error("bluez: cannot connect to the D-Bus system bus " + impl_->bus_address + " (" +
                               dbus_error_text(e) + ")");
    }
  }
  impl_->queue = &queue;
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  std::uint64_t drain = 0;
  while (::read(wake_fd_, &drain, sizeof drain) > 0) {
  }
  thread_ = std::thread([this, &queue] { run(queue); });
}

void BluezScanner::stop() {
  stop_.store(true, std::memory_order_release);
  if (wake_fd_ >= 0) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(wake_fd_, &one, sizeof one);
  }
  if (thread_.joinable()) thread_.join();
}

void BluezScanner::run(SensorQueue&) {
  Impl& s = *impl_;
  try {
    s.subscribe();
    while (!stop_.load(std::memory_order_acquire)) {
      while (s.conn->processPendingRequest()) {
        if (stop_.load(std::memory_order_acquire)) break;
      }
      if (stop_.load(std::memory_order_acquire)) break;
      // Retry timer (adapter missing, a failed call, discovery stopped).
      if (s.retry_at && SteadyClock::now() >= *s.retry_at) {
        s.retry_at.reset();
        if (!s.bluez_owner.empty()) s.begin_setup();
        continue;
      }
      const auto pd = s.conn->getEventLoopPollData();
      int timeout_ms = pd.getPollTimeout();
      if (s.retry_at) {
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(*s.retry_at - SteadyClock::now());
        const int left_ms = static_cast<int>(std::max<std::int64_t>(0, left.count() + 1));
        timeout_ms = timeout_ms < 0 ? left_ms : std::min(timeout_ms, left_ms);
      }
      pollfd fds[2] = {{pd.fd, pd.events, 0}, {wake_fd_, POLLIN, 0}};
      const int r = ::poll(fds, 2, timeout_ms);
      if (r < 0 && errno != EINTR) throw std::runtime_error(std::string("poll: ") + std::strerror(errno));
      if (r > 0 && (fds[1].revents & POLLIN) != 0) {
        std::uint64_t drain = 0;
        while (::read(wake_fd_, &drain, sizeof drain) > 0) {
        }
      }
    }
    s.stop_discovery();
    const Stats st = stats();
    s.log->info("stopped scanning on " + s.config.adapter + ": " + std::to_string(st.adverts) + " adverts, " +
                std::to_string(st.dropped_full) + " dropped (queue full), " + std::to_string(st.filtered) +
                " filtered, " + std::to_string(st.malformed) + " malformed, " + std::to_string(st.bluez_losses) +
                " bluetoothd restarts");
  } catch (const sdbus::Error& e) {
    fail("bluez: lost the D-Bus system bus " + s.bus_address + " while scanning on " + s.config.adapter + " (" +
         dbus_error_text(e) + ")");
    s.log->error(error());
  } catch (const std::exception& e) {
    fail("bluez: scanner on " + s.config.adapter + " failed: " + e.what());
    s.log->error(error());
  }
  s.teardown();
}

// ------------------------------------------------------------------ registration

void register_bluez_source(Registry& registry) {
  registry.add_sensor_source(SensorSourceDescriptor{
      "bluez",
      "BLE scanning through BlueZ's D-Bus API: one BleAdvertisement per RSSI report (LE discovery with "
      "DuplicateData), survives bluetoothd restarts",
      SensorKind::Ble,
      bluez_schema(),
      [] { return std::unique_ptr<SensorSource>(std::make_unique<BluezScanner>()); },
  });
}

}  // namespace locus::hal::bluez
