// The `bluez` scanner against a real D-Bus daemon and python3-dbusmock's bluez5 template:
//   - a private dbus-daemon (its own config and socket in a temp dir) is the "system bus"
//     (DBUS_SYSTEM_BUS_ADDRESS); dbusmock plays bluetoothd on it;
//   - the scanner, made through the registry like locusd makes it, sets the LE discovery filter and
//     starts discovery (checked on the mock's adapter), then every RSSI the test sets on the mock's
//     Device1 objects comes out as one BleAdvertisement: values, addresses, TxPower and order;
//   - the mock is killed and started again (bluetoothd restart): the same scanner, never restarted,
//     notices, finds the adapter again when it is re-added, and keeps reporting;
//   - allow list + RSSI threshold; malformed values ignored and counted; a full queue drops and counts; bluetoothd and the adapter
//     appearing after the scanner started; losing the bus itself; stop() is prompt.
// Every process is started here and killed by PID (also when a check fails, and by PR_SET_PDEATHSIG
// if this binary dies); everything is in a private temp dir; every wait has a timeout.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <sdbus-c++/sdbus-c++.h>

#include "bluez/bluez_devices.hpp"
#include "bluez/bluez_parse.hpp"
#include "bluez/bluez_scanner.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus::hal::bluez {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr const char* kMac1 = "AA:BB:CC:DD:EE:01";
constexpr const char* kMac2 = "AA:BB:CC:DD:EE:02";
constexpr auto kTimeout = 20s;

double now_mono_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

bool wait_for(const std::function<bool()>& cond, std::chrono::milliseconds timeout = kTimeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (cond()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return cond();
}

/// A child process killed (SIGTERM, then SIGKILL) and reaped when this goes out of scope.
class Child {
 public:
  Child(std::vector<std::string> argv, const fs::path& log) {
    // Everything the child needs is prepared before fork(): the scanner thread may hold the malloc
    // lock at that moment, so the child only makes async-signal-safe calls.
    std::vector<char*> args;
    for (auto& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    const std::string log_path = log.string();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      ::execv(args[0], args.data());
      ::_exit(127);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() { kill(); }

  pid_t pid() const { return pid_; }
  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    return true;
  }
  void kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    const auto end = std::chrono::steady_clock::now() + 5s;
    int status = 0;
    while (std::chrono::steady_clock::now() < end) {
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(10ms);
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, &status, 0);
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
};

/// Private bus + dbusmock bluez5, and a client connection to drive the mock.
class BluezMockTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/locus-bluez-XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    const fs::path sock = dir_ / "bus.sock";
    std::ofstream(dir_ / "bus.conf")
        << "<!DOCTYPE busconfig PUBLIC \"-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN\"\n"
           " \"http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd\">\n"
           "<busconfig>\n  <type>system</type>\n  <listen>unix:path="
        << sock.string()
        << "</listen>\n  <auth>EXTERNAL</auth>\n"
           "  <policy context=\"default\">\n    <allow user=\"*\"/>\n    <allow own=\"*\"/>\n"
           "    <allow send_type=\"method_call\"/>\n    <allow send_type=\"signal\"/>\n"
           "    <allow send_type=\"method_return\"/>\n    <allow send_type=\"error\"/>\n"
           "    <allow receive_type=\"method_call\"/>\n    <allow receive_type=\"signal\"/>\n"
           "    <allow receive_type=\"method_return\"/>\n    <allow receive_type=\"error\"/>\n"
           "  </policy>\n</busconfig>\n";
    bus_ = std::make_unique<Child>(
        std::vector<std::string>{"/usr/bin/dbus-daemon", "--config-file=" + (dir_ / "bus.conf").string(), "--nofork",
                                 "--nopidfile"},
        dir_ / "dbus-daemon.log");
    address_ = "unix:path=" + sock.string();
    setenv("DBUS_SYSTEM_BUS_ADDRESS", address_.c_str(), 1);
    ASSERT_TRUE(wait_for([&] {
      try {
        client_ = sdbus::createSystemBusConnection();
        return true;
      } catch (const sdbus::Error&) {
        return false;
      }
    })) << "the private dbus-daemon did not come up; see " << (dir_ / "dbus-daemon.log");
    dbus_ = sdbus::createProxy(*client_, "org.freedesktop.DBus", "/org/freedesktop/DBus");
  }

  void TearDown() override {
    mock_.reset();
    mock_proxy_.reset();
    dbus_.reset();
    client_.reset();
    bus_.reset();
    unsetenv("DBUS_SYSTEM_BUS_ADDRESS");
    if (!HasFailure()) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
    } else {
      std::cerr << "kept " << dir_ << " (dbus-daemon.log, mock.log) for inspection\n";
    }
  }

  bool bluez_on_bus() {
    bool has = false;
    dbus_->callMethod("NameHasOwner").onInterface("org.freedesktop.DBus").withArguments(std::string("org.bluez"))
        .storeResultsTo(has);
    return has;
  }

  /// Starts `python3 -m dbusmock --system --template bluez5` and waits until it owns org.bluez.
  void start_mock() {
    mock_ = std::make_unique<Child>(
        std::vector<std::string>{"/usr/bin/python3", "-m", "dbusmock", "--system", "--template", "bluez5"},
        dir_ / "mock.log");
    ASSERT_TRUE(wait_for([&] { return bluez_on_bus(); })) << "dbusmock did not take org.bluez; see " << (dir_ / "mock.log");
    mock_proxy_ = sdbus::createProxy(*client_, "org.bluez", "/");
  }

  void kill_mock() {
    mock_->kill();
    mock_.reset();
    ASSERT_TRUE(wait_for([&] { return !bluez_on_bus(); }));
  }

  void add_adapter(const std::string& name) {
    std::string path;
    mock_proxy_->callMethod("AddAdapter").onInterface("org.bluez.Mock").withArguments(name, std::string("locus-test"))
        .storeResultsTo(path);
    ASSERT_EQ(path, "/org/bluez/" + name);
  }
  void add_device(const std::string& adapter, const std::string& mac) {
    std::string path;
    mock_proxy_->callMethod("AddDevice").onInterface("org.bluez.Mock")
        .withArguments(adapter, mac, std::string("tag"))
        .storeResultsTo(path);
  }
  static std::string device_path(const std::string& adapter, std::string mac) {
    for (char& c : mac)
      if (c == ':') c = '_';
    return "/org/bluez/" + adapter + "/dev_" + mac;
  }
  /// Sets a Device1 property on the mock (Properties.Set: the mock emits PropertiesChanged).
  void set_device_prop(const std::string& mac, const std::string& key, std::int16_t value,
                       const std::string& adapter = "hci0") {
    set_device_variant(mac, key, sdbus::Variant(value), adapter);
  }
  void set_device_variant(const std::string& mac, const std::string& key, const sdbus::Variant& value,
                          const std::string& adapter = "hci0") {
    auto dev = sdbus::createProxy(*client_, "org.bluez", device_path(adapter, mac));
    dev->callMethod("Set").onInterface("org.freedesktop.DBus.Properties")
        .withArguments(std::string("org.bluez.Device1"), key, value);
  }
  PropertyMap adapter_props(const std::string& adapter = "hci0") {
    auto a = sdbus::createProxy(*client_, "org.bluez", "/org/bluez/" + adapter);
    PropertyMap props;
    a->callMethod("GetAll").onInterface("org.freedesktop.DBus.Properties")
        .withArguments(std::string("org.bluez.Adapter1"))
        .storeResultsTo(props);
    return props;
  }

  std::unique_ptr<SensorSource> make_scanner(Params params, HostContext& ctx) {
    Registry registry;
    register_builtins(registry);
    auto src = registry.create_sensor_source("bluez");
    src->open(params, ctx);
    return src;
  }

  static BluezScanner& as_bluez(SensorSource& s) { return dynamic_cast<BluezScanner&>(s); }

  /// Pops adverts until `n` arrived or the timeout.
  static std::vector<BleAdvertisement> collect(SensorQueue& q, std::size_t n, std::chrono::milliseconds timeout = kTimeout) {
    std::vector<BleAdvertisement> out;
    wait_for(
        [&] {
          Event e;
          while (q.try_pop(e)) {
            if (const auto* a = std::get_if<BleAdvertisement>(&e)) out.push_back(*a);
          }
          return out.size() >= n;
        },
        timeout);
    return out;
  }

  fs::path dir_;
  std::string address_;
  std::unique_ptr<Child> bus_;
  std::unique_ptr<Child> mock_;
  std::unique_ptr<sdbus::IConnection> client_;
  std::unique_ptr<sdbus::IProxy> dbus_;
  std::unique_ptr<sdbus::IProxy> mock_proxy_;
};

struct Expect {
  const char* mac;
  int rssi;
  bool has_tx;
  int tx;
};

void check_adverts(const std::vector<BleAdvertisement>& got, const std::vector<Expect>& want, double t0, double t1,
                   const char* phase) {
  ASSERT_EQ(got.size(), want.size()) << phase;
  double prev = -1.0;
  for (std::size_t i = 0; i < want.size(); ++i) {
    SCOPED_TRACE(std::string(phase) + " advert " + std::to_string(i));
    EXPECT_EQ(format_mac(got[i].address), want[i].mac);
    EXPECT_EQ(got[i].rssi_dbm, static_cast<float>(want[i].rssi));
    EXPECT_EQ(got[i].has_tx_power, want[i].has_tx);
    if (want[i].has_tx) {
      EXPECT_EQ(got[i].tx_power_dbm, static_cast<float>(want[i].tx));
    }
    EXPECT_EQ(std::string(got[i].device.str()), "A");
    EXPECT_GE(got[i].t_s, t0);
    EXPECT_LE(got[i].t_s, t1);
    EXPECT_GE(got[i].t_s, prev);
    prev = got[i].t_s;
  }
}

TEST_F(BluezMockTest, FollowsRssiAndSurvivesBluetoothdRestart) {
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac2));

  // `locus devices` sees the adapter.
  const auto list = list_bluez_adapters();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].kind, "adapter");
  EXPECT_EQ(list[0].id, "hci0");
  EXPECT_NE(list[0].description.find("00:01:02:03:04:05"), std::string::npos) << list[0].description;

  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  auto src = make_scanner(Params::defaults(bluez_schema()), ctx);
  BluezScanner& scanner = as_bluez(*src);
  SensorQueue queue(256);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning; })) << "discovery never started";

  // The mock saw SetDiscoveryFilter({Transport: le, DuplicateData: true}) and StartDiscovery.
  {
    PropertyMap props = adapter_props();
    ASSERT_TRUE(props.count("Discovering"));
    EXPECT_TRUE(props.at("Discovering").get<bool>());
    ASSERT_TRUE(props.count("DiscoveryFilter"));
    const auto filter = props.at("DiscoveryFilter").get<std::map<std::string, sdbus::Variant>>();
    ASSERT_TRUE(filter.count("Transport"));
    EXPECT_EQ(filter.at("Transport").get<std::string>(), "le");
    ASSERT_TRUE(filter.count("DuplicateData"));
    EXPECT_TRUE(filter.at("DuplicateData").get<bool>());
    EXPECT_EQ(filter.count("RSSI"), 0u);
  }

  // Phase 1: devices known before the scan (no advert for their cached RSSI -79; TxPower 0 cached).
  const double t0 = now_mono_s();
  const std::vector<int> seq1 = {-40, -55, -55, -70, -62};
  std::vector<Expect> want;
  for (std::size_t i = 0; i < seq1.size(); ++i) {
    set_device_prop(kMac1, "RSSI", static_cast<std::int16_t>(seq1[i]));
    want.push_back({kMac1, seq1[i], true, i < 2 ? 0 : -4});
    if (i == 1) set_device_prop(kMac1, "TxPower", -4);  // TxPower alone is no advert
    if (i == 2) {
      set_device_prop(kMac2, "RSSI", -90);
      want.push_back({kMac2, -90, true, 0});
    }
  }
  auto got = collect(queue, want.size());
  check_adverts(got, want, t0, now_mono_s(), "before restart");

  // Figure: from just before Properties.Set to the advert's local receive time (mock + bus + us).
  {
    std::vector<double> lat_ms;
    for (int i = 0; i < 50; ++i) {
      const double before = now_mono_s();
      set_device_prop(kMac2, "RSSI", static_cast<std::int16_t>(-50 - i % 20));
      const auto one = collect(queue, 1);
      ASSERT_EQ(one.size(), 1u);
      EXPECT_EQ(one[0].rssi_dbm, static_cast<float>(-50 - i % 20));
      lat_ms.push_back(1e3 * (one[0].t_s - before));
    }
    std::sort(lat_ms.begin(), lat_ms.end());
    std::cout << "[ figures  ] Set -> advert t_s: median " << lat_ms[lat_ms.size() / 2] << " ms, max "
              << lat_ms.back() << " ms (50 round trips through dbusmock)\n";
  }
  EXPECT_TRUE(collect(queue, 1, 300ms).empty()) << "an advert nobody sent";

  // Phase 2: bluetoothd goes away; the source keeps running.
  ASSERT_NO_FATAL_FAILURE(kill_mock());
  ASSERT_TRUE(wait_for([&] { return scanner.stats().bluez_losses == 1 && !scanner.stats().scanning; }));
  EXPECT_FALSE(src->finished()) << src->error();
  EXPECT_TRUE(host.log.contains("left the system bus", LogLevel::Warn));

  // Phase 3: it comes back (a new process, a new unique name), without its adapter at first.
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_TRUE(wait_for([&] { return host.log.contains("org.bluez is back"); }));
  std::this_thread::sleep_for(200ms);
  EXPECT_FALSE(scanner.stats().scanning);
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning && scanner.stats().discovery_starts == 2; }))
      << "discovery did not restart after bluetoothd came back";
  EXPECT_TRUE(adapter_props().at("Discovering").get<bool>());
  EXPECT_TRUE(host.log.contains("scanning again after bluetoothd came back", LogLevel::Info));

  // A device discovered while scanning (InterfacesAdded with RSSI -79, TxPower 0) is an advert too.
  const double t2 = now_mono_s();
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));
  std::vector<Expect> want2 = {{kMac1, -79, true, 0}};
  const std::vector<int> seq2 = {-33, -48, -48, -81};
  for (int r : seq2) {
    set_device_prop(kMac1, "RSSI", static_cast<std::int16_t>(r));
    want2.push_back({kMac1, r, true, 0});
  }
  got = collect(queue, want2.size());
  check_adverts(got, want2, t2, now_mono_s(), "after restart");

  EXPECT_FALSE(src->finished());
  EXPECT_EQ(src->error(), "");
  EXPECT_EQ(queue.dropped(), 0u);
  const auto st = scanner.stats();
  EXPECT_EQ(st.adverts, want.size() + want2.size() + 50);
  EXPECT_EQ(st.malformed, 0u);

  const auto s0 = std::chrono::steady_clock::now();
  src->stop();
  const double stop_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - s0).count();
  std::cout << "[ figures  ] stop() took " << stop_ms << " ms\n";
  EXPECT_LT(stop_ms, 2000.0);
  EXPECT_FALSE(src->finished());
  // Our discovery session ended (StopDiscovery sent before disconnecting).
  EXPECT_TRUE(wait_for([&] { return !adapter_props().at("Discovering").get<bool>(); }, 5s));
}

TEST_F(BluezMockTest, AllowListAndRssiThreshold) {
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac2));

  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  Params p = Params::defaults(bluez_schema());
  p.set("addresses", std::string("aa:bb:cc:dd:ee:01"));
  p.set("rssi_threshold_dbm", std::int64_t{-60});
  p.set("duplicate_data", false);
  auto src = make_scanner(p, ctx);
  BluezScanner& scanner = as_bluez(*src);
  SensorQueue queue(64);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning; }));
  {
    const auto filter = adapter_props().at("DiscoveryFilter").get<std::map<std::string, sdbus::Variant>>();
    ASSERT_TRUE(filter.count("RSSI"));
    EXPECT_EQ(filter.at("RSSI").get<std::int16_t>(), -60);
    EXPECT_FALSE(filter.at("DuplicateData").get<bool>());
  }
  const double t0 = now_mono_s();
  set_device_prop(kMac2, "RSSI", -30);  // not allowed
  set_device_prop(kMac1, "RSSI", -61);  // below the threshold
  set_device_prop(kMac1, "RSSI", -60);
  set_device_prop(kMac2, "RSSI", -20);
  set_device_prop(kMac1, "RSSI", -45);
  auto got = collect(queue, 2);
  check_adverts(got, {{kMac1, -60, true, 0}, {kMac1, -45, true, 0}}, t0, now_mono_s(), "filtered");
  EXPECT_TRUE(collect(queue, 1, 300ms).empty());
  EXPECT_EQ(scanner.stats().filtered, 3u);
  src->stop();
}

TEST_F(BluezMockTest, AFullQueueDropsAndCounts) {
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));
  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  auto src = make_scanner(Params::defaults(bluez_schema()), ctx);
  BluezScanner& scanner = as_bluez(*src);
  SensorQueue queue(16);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning; }));
  constexpr int kSent = 100;
  for (int i = 0; i < kSent; ++i) set_device_prop(kMac1, "RSSI", static_cast<std::int16_t>(-30 - i % 60));
  ASSERT_TRUE(wait_for([&] {
    const auto st = scanner.stats();
    return st.adverts + st.dropped_full == static_cast<std::uint64_t>(kSent);
  })) << scanner.stats().adverts << " + " << scanner.stats().dropped_full;
  const auto st = scanner.stats();
  EXPECT_EQ(st.adverts, queue.capacity());
  EXPECT_EQ(st.dropped_full, queue.dropped());
  // The ones kept are the first ones, in order.
  auto got = collect(queue, queue.capacity());
  ASSERT_EQ(got.size(), queue.capacity());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].rssi_dbm, static_cast<float>(-30 - static_cast<int>(i) % 60));
  // Room again: the next advert gets through.
  set_device_prop(kMac1, "RSSI", -11);
  got = collect(queue, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].rssi_dbm, -11.0f);
  src->stop();
}

TEST_F(BluezMockTest, MalformedValuesAreIgnoredAndCounted) {
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));
  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  auto src = make_scanner(Params::defaults(bluez_schema()), ctx);
  BluezScanner& scanner = as_bluez(*src);
  SensorQueue queue(64);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning; }));
  set_device_variant(kMac1, "RSSI", sdbus::Variant(std::string("-40")));     // not an integer
  set_device_variant(kMac1, "RSSI", sdbus::Variant(std::int32_t{-41}));      // int32: tolerated
  set_device_prop(kMac1, "RSSI", 127);                                       // "not available"
  set_device_variant(kMac1, "TxPower", sdbus::Variant(3.5));                 // not an integer
  set_device_variant(kMac1, "Address", sdbus::Variant(std::string("junk")));  // garbled: path address kept
  set_device_prop(kMac1, "RSSI", -42);
  auto got = collect(queue, 2);
  check_adverts(got, {{kMac1, -41, true, 0}, {kMac1, -42, true, 0}}, 0.0, now_mono_s(), "malformed");
  EXPECT_TRUE(collect(queue, 1, 300ms).empty());
  EXPECT_EQ(scanner.stats().malformed, 4u);
  EXPECT_TRUE(host.log.contains("RSSI has D-Bus type 's'", LogLevel::Warn));
  EXPECT_FALSE(src->finished());
  src->stop();
}

TEST_F(BluezMockTest, WaitsForBluetoothdAndForAMissingAdapter) {
  // Scanner first, bluetoothd later, and the adapter it wants (hci1) later still.
  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  Params p = Params::defaults(bluez_schema());
  p.set("adapter", std::string("hci1"));
  p.set("restart_backoff_s", 0.2);
  auto src = make_scanner(p, ctx);
  BluezScanner& scanner = as_bluez(*src);
  SensorQueue queue(64);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return host.log.contains("org.bluez is not on the system bus", LogLevel::Warn); }));
  EXPECT_TRUE(host.log.contains(address_));

  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  ASSERT_TRUE(wait_for([&] { return host.log.contains("adapter 'hci1' (/org/bluez/hci1) not found", LogLevel::Warn); }));
  std::this_thread::sleep_for(500ms);  // a few retries
  EXPECT_FALSE(scanner.stats().scanning);
  EXPECT_TRUE(host.log.contains("adapters: hci0"));
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci1"));
  ASSERT_TRUE(wait_for([&] { return scanner.stats().scanning; }));
  ASSERT_NO_FATAL_FAILURE(add_device("hci1", kMac2));  // discovered while scanning: RSSI -79
  ASSERT_NO_FATAL_FAILURE(add_device("hci0", kMac1));  // another adapter: not ours
  set_device_prop(kMac1, "RSSI", -50, "hci0");
  set_device_prop(kMac2, "RSSI", -51, "hci1");
  auto got = collect(queue, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(format_mac(got[0].address), kMac2);
  EXPECT_EQ(got[0].rssi_dbm, -79.0f);
  EXPECT_EQ(format_mac(got[1].address), kMac2);
  EXPECT_EQ(got[1].rssi_dbm, -51.0f);
  EXPECT_TRUE(collect(queue, 1, 300ms).empty());
  src->stop();
  EXPECT_FALSE(src->finished());
}

TEST_F(BluezMockTest, LosingTheBusEndsTheStreamWithAClearError) {
  ASSERT_NO_FATAL_FAILURE(start_mock());
  ASSERT_NO_FATAL_FAILURE(add_adapter("hci0"));
  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  auto src = make_scanner(Params::defaults(bluez_schema()), ctx);
  SensorQueue queue(64);
  src->start(queue);
  ASSERT_TRUE(wait_for([&] { return as_bluez(*src).stats().scanning; }));
  mock_.reset();
  bus_->kill();  // the system bus itself goes away
  ASSERT_TRUE(wait_for([&] { return src->finished(); })) << "no error after the bus died";
  EXPECT_NE(src->error().find("lost the D-Bus system bus " + address_), std::string::npos) << src->error();
  src->stop();
}

}  // namespace
}  // namespace locus::hal::bluez
