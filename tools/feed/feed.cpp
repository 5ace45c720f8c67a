// `locus feed`: see feed.hpp for what it plays where, and docs/room.md ("LocBLE") for its use.
#include "feed/feed.hpp"

#include <signal.h>
#include <time.h>

#include <sdbus-c++/sdbus-c++.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "iio/fake_iio_tree.hpp"
#include "locus/scene/ble_csv.hpp"
#include "locus/scene/imu_csv.hpp"
#include "locus/scene/scene.hpp"

namespace locus::feed {
namespace {

namespace fs = std::filesystem;

double monotonic_s() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// SIGINT/SIGTERM are blocked and waited for: every sleep of the feed is a sigtimedwait, so a signal
/// ends it at once and nothing runs in a handler.
class StopSignals {
 public:
  StopSignals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    ::sigprocmask(SIG_BLOCK, &set_, &old_);
    ::signal(SIGPIPE, SIG_IGN);  // a node that goes away: EPIPE on the FIFO, counted
  }
  ~StopSignals() { ::sigprocmask(SIG_SETMASK, &old_, nullptr); }
  /// Sleeps until CLOCK_MONOTONIC `until_s`; false when a stop signal came (remembered).
  bool sleep_until(double until_s) {
    while (!stopped_) {
      const double left = until_s - monotonic_s();
      if (left <= 0) return true;
      const double s = std::min(left, 1.0);
      timespec t{static_cast<time_t>(s), static_cast<long>((s - std::floor(s)) * 1e9)};
      if (::sigtimedwait(&set_, nullptr, &t) > 0) stopped_ = true;
    }
    return false;
  }
  bool poll() { return sleep_until(0.0); }
  void wait_forever() {
    while (sleep_until(monotonic_s() + 1.0)) {
    }
  }
  bool stopped() const { return stopped_; }

 private:
  sigset_t set_{}, old_{};
  bool stopped_ = false;
};

/// The LSM6DSL's full-scale ranges: units per LSB of accel (m/s^2) and gyro (rad/s).
struct FullScale {
  double per_lsb;
  const char* range;
};
constexpr FullScale kAccelRanges[] = {{0.000598550, "2 g"}, {0.001197101, "4 g"}, {0.002394202, "8 g"}, {0.004788403, "16 g"}};
constexpr FullScale kGyroRanges[] = {{0.0000763582, "125 dps"}, {0.000152716, "250 dps"}, {0.000305433, "500 dps"},
                                     {0.000610865, "1000 dps"}, {0.00122173, "2000 dps"}};

template <std::size_t N>
std::optional<FullScale> smallest_range(const FullScale (&ranges)[N], double max_abs) {
  for (const FullScale& r : ranges)
    if (max_abs <= 32767.0 * r.per_lsb) return r;
  return std::nullopt;
}

std::string fmt(double v, int decimals) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double max_of(const std::vector<double>& v) { return v.empty() ? std::nan("") : *std::max_element(v.begin(), v.end()); }

/// dbusmock's BlueZ: the adapter and one device object per tag, and the RSSI changes.
class MockBluez {
 public:
  MockBluez(const std::string& adapter, double timeout_s, StopSignals& stop) : adapter_(adapter) {
    conn_ = sdbus::createSystemBusConnection();
    auto dbus = sdbus::createProxy(*conn_, "org.freedesktop.DBus", "/org/freedesktop/DBus");
    const double deadline = monotonic_s() + timeout_s;
    for (;;) {
      bool has = false;
      dbus->callMethod("NameHasOwner").onInterface("org.freedesktop.DBus").withArguments(std::string("org.bluez")).storeResultsTo(has);
      if (has) break;
      if (monotonic_s() > deadline) throw std::runtime_error("no owner of org.bluez on the system bus (is dbusmock's bluez5 running?)");
      if (!stop.sleep_until(monotonic_s() + 0.05)) throw std::runtime_error("interrupted");
    }
    root_ = sdbus::createProxy(*conn_, "org.bluez", "/");
    root_->callMethod("AddAdapter").onInterface("org.bluez.Mock").withArguments(adapter, std::string("locus-feed")).storeResultsTo(adapter_path_);
    adapter_proxy_ = sdbus::createProxy(*conn_, "org.bluez", adapter_path_);
  }

  bool known(const std::string& address) const { return tags_.count(address) != 0; }

  /// A tag's first advertisement: as bluetoothd announces a newly discovered device, its Device1 object
  /// appears with the advertisement's RSSI (and TxPower) in one InterfacesAdded (dbusmock: AddObject,
  /// then the signal from the object manager at "/", as its own AddDevice does).
  void discover(const std::string& address, std::int16_t rssi, std::optional<std::int16_t> tx_power) {
    std::string dev = "dev_" + address;
    std::replace(dev.begin(), dev.end(), ':', '_');
    const std::string path = adapter_path_ + "/" + dev;
    std::map<std::string, sdbus::Variant> props{
        {"Address", sdbus::Variant(address)},
        {"AddressType", sdbus::Variant(std::string("public"))},
        {"Alias", sdbus::Variant(address)},
        {"Adapter", sdbus::Variant(sdbus::ObjectPath(adapter_path_))},
        {"Paired", sdbus::Variant(false)},
        {"Connected", sdbus::Variant(false)},
        {"Trusted", sdbus::Variant(false)},
        {"Blocked", sdbus::Variant(false)},
        {"LegacyPairing", sdbus::Variant(false)},
        {"ServicesResolved", sdbus::Variant(false)},
        {"UUIDs", sdbus::Variant(std::vector<std::string>{})},
        {"RSSI", sdbus::Variant(rssi)},
    };
    if (tx_power) props.emplace("TxPower", sdbus::Variant(*tx_power));
    root_->callMethod("AddObject").onInterface("org.freedesktop.DBus.Mock")
        .withArguments(path, std::string("org.bluez.Device1"), props,
                       std::vector<sdbus::Struct<std::string, std::string, std::string, std::string>>{});
    const std::map<std::string, std::map<std::string, sdbus::Variant>> interfaces{{"org.bluez.Device1", props}};
    root_->callMethod("EmitSignal").onInterface("org.freedesktop.DBus.Mock")
        .withArguments(std::string("org.freedesktop.DBus.ObjectManager"), std::string("InterfacesAdded"), std::string("oa{sa{sv}}"),
                       std::vector<sdbus::Variant>{sdbus::Variant(sdbus::ObjectPath(path)), sdbus::Variant(interfaces)});
    Tag t;
    t.proxy = sdbus::createProxy(*conn_, "org.bluez", path);
    t.tx_power = tx_power;
    tags_.emplace(address, std::move(t));
  }
  void set_tx_power(const std::string& address, std::int16_t dbm) {
    Tag& t = tags_.at(address);
    set(t, "TxPower", dbm);
    t.tx_power = dbm;
  }
  std::optional<std::int16_t> tx_power(const std::string& address) const { return tags_.at(address).tx_power; }
  void set_rssi(const std::string& address, std::int16_t dbm) { set(tags_.at(address), "RSSI", dbm); }

  bool discovering() {
    return adapter_proxy_->getProperty("Discovering").onInterface("org.bluez.Adapter1").get<bool>();
  }

 private:
  struct Tag {
    std::unique_ptr<sdbus::IProxy> proxy;
    std::optional<std::int16_t> tx_power;
  };
  static void set(Tag& t, const char* property, std::int16_t v) {
    t.proxy->callMethod("Set").onInterface("org.freedesktop.DBus.Properties")
        .withArguments(std::string("org.bluez.Device1"), std::string(property), sdbus::Variant(v));
  }
  std::string adapter_, adapter_path_;
  std::unique_ptr<sdbus::IConnection> conn_;
  std::unique_ptr<sdbus::IProxy> root_, adapter_proxy_;
  std::map<std::string, Tag> tags_;
};

struct Row {
  double t_s;
  bool imu;
  std::size_t index;
};

}  // namespace

int run_feed(const FeedOptions& opts) {
  StopSignals stop;
  // ---- the recording
  scene::Scene sc;
  try {
    sc = scene::load_scene(opts.scene_dir);
  } catch (const std::exception& e) {
    std::cerr << "locus feed: " << e.what() << "\n";
    return 2;
  }
  const auto dev = std::find_if(sc.devices.begin(), sc.devices.end(), [&](const scene::DeviceSpec& d) { return d.id == opts.device; });
  if (dev == sc.devices.end()) {
    std::string ids;
    for (const auto& d : sc.devices) ids += (ids.empty() ? "" : ", ") + d.id;
    std::cerr << "locus feed: " << opts.scene_dir << "/scene.yaml has no device '" << opts.device << "' (devices: " << ids << ")\n";
    return 2;
  }
  const bool with_imu = !opts.iio_root.empty();
  if (with_imu && dev->imu.empty()) {
    std::cerr << "locus feed: device " << dev->id << " of " << opts.scene_dir << " has no imu stream (scene.yaml devices[].imu)\n";
    return 2;
  }
  if (opts.ble && dev->ble.empty()) {
    std::cerr << "locus feed: device " << dev->id << " of " << opts.scene_dir << " has no ble stream (scene.yaml devices[].ble)\n";
    return 2;
  }
  if (!with_imu && !opts.ble) {
    std::cerr << "locus feed: nothing to play (--iio-root not given and --no-ble)\n";
    return 2;
  }
  std::vector<ImuSample> imu;
  std::vector<BleAdvertisement> ble;
  try {
    const DeviceId id(dev->id);
    if (with_imu) {
      scene::ImuCsvReader r(sc.path(dev->imu), id);
      for (ImuSample s; r.next(s);) imu.push_back(s);
    }
    if (opts.ble) {
      scene::BleCsvReader r(sc.path(dev->ble), id);
      for (BleAdvertisement a; r.next(a);) ble.push_back(a);
      std::stable_sort(ble.begin(), ble.end(), [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
    }
  } catch (const std::exception& e) {
    std::cerr << "locus feed: " << e.what() << "\n";
    return 2;
  }
  if ((with_imu && imu.empty()) || (opts.ble && ble.empty())) {
    std::cerr << "locus feed: " << (with_imu && imu.empty() ? sc.path(dev->imu) : sc.path(dev->ble)) << " has no rows\n";
    return 2;
  }

  // ---- the IIO device: the smallest full scale that holds the recording
  std::unique_ptr<iio_fake::FakeIioTree> tree;
  double accel_per_lsb = 1.0, gyro_per_lsb = 1.0;
  if (with_imu) {
    double amax = 0.0, gmax = 0.0;
    for (const ImuSample& s : imu)
      for (int k = 0; k < 3; ++k) amax = std::max(amax, std::abs(double(s.accel_mps2[k]))), gmax = std::max(gmax, std::abs(double(s.gyro_radps[k])));
    const auto ar = smallest_range(kAccelRanges, amax);
    const auto gr = smallest_range(kGyroRanges, gmax);
    if (!ar || !gr) {
      std::cerr << "locus feed: " << sc.path(dev->imu) << ": " << (!ar ? "accel up to " + fmt(amax, 2) + " m/s^2" : "gyro up to " + fmt(gmax, 2) + " rad/s")
                << " exceeds the IIO part's largest range (16 g, 2000 dps)\n";
      return 2;
    }
    if (fs::exists(opts.iio_root)) {
      std::cerr << "locus feed: --iio-root " << opts.iio_root << " exists already (the feed creates the tree and removes it)\n";
      return 2;
    }
    accel_per_lsb = ar->per_lsb;
    gyro_per_lsb = gr->per_lsb;
    const double rate_hz = imu.size() > 1 && imu.back().t_s > imu.front().t_s
                               ? double(imu.size() - 1) / (imu.back().t_s - imu.front().t_s) : 100.0;
    iio_fake::FakeIioTree::ImuOptions io;
    io.accel_scale = fmt(accel_per_lsb, 9);
    io.gyro_scale = fmt(gyro_per_lsb, 9);
    io.sampling_frequency = fmt(rate_hz * opts.speed, 6);
    io.timestamp_clock = "realtime";  // the kernel's default; the node's `iio` source switches it to monotonic
    tree = std::make_unique<iio_fake::FakeIioTree>(opts.iio_root);
    tree->add_imu(0, io);
    std::cout << "feed: IIO device lsm6dsl at " << opts.iio_root << ": " << imu.size() << " scans at " << fmt(rate_hz, 1)
              << " Hz, full scale " << ar->range << " (recording up to " << fmt(amax, 1) << " m/s^2), " << gr->range
              << " (up to " << fmt(gmax, 2) << " rad/s)\n";
  }

  // ---- BlueZ: the adapter and the tags, before the node scans
  std::unique_ptr<MockBluez> bluez;
  std::size_t rounded = 0;
  if (opts.ble) {
    try {
      bluez = std::make_unique<MockBluez>(opts.adapter, opts.start_timeout_s, stop);
      for (const BleAdvertisement& a : ble)
        if (std::abs(a.rssi_dbm - std::round(a.rssi_dbm)) > 1e-6) ++rounded;
    } catch (const std::exception& e) {
      std::cerr << "locus feed: BlueZ (" << (std::getenv("DBUS_SYSTEM_BUS_ADDRESS") ? std::getenv("DBUS_SYSTEM_BUS_ADDRESS") : "the system bus")
                << "): " << e.what() << "\n";
      return stop.stopped() ? 130 : 1;
    }
  }
  std::cout << "feed: ready: " << (with_imu ? "IMU " + opts.iio_root : std::string("no IMU")) << "; "
            << (opts.ble ? std::to_string(ble.size()) + " advertisements on " + opts.adapter : std::string("no BLE"))
            << (rounded ? " (" + std::to_string(rounded) + " RSSI values rounded to whole dBm)" : std::string()) << std::endl;

  // ---- wait for the node: its IMU buffer open, its discovery running
  iio_fake::FifoWriter fifo(with_imu ? tree->path("dev/iio:device0") : std::string());
  {
    const double deadline = monotonic_s() + opts.start_timeout_s;
    bool fifo_ok = !with_imu, disc_ok = !opts.ble;
    while (!(fifo_ok && disc_ok)) {
      if (!stop.poll()) return 130;
      if (monotonic_s() > deadline) {
        std::cerr << "locus feed: the node did not " << (!fifo_ok ? "open the IIO buffer " + tree->path("dev/iio:device0") : std::string("start discovery on ") + opts.adapter)
                  << " within " << fmt(opts.start_timeout_s, 0) << " s\n";
        return 1;
      }
      if (!fifo_ok) fifo_ok = fifo.connect(std::chrono::milliseconds(50));
      if (!disc_ok) {
        try {
          disc_ok = bluez->discovering();
        } catch (const sdbus::Error& e) {
          std::cerr << "locus feed: BlueZ: " << e.what() << "\n";
          return 1;
        }
        if (!disc_ok) stop.sleep_until(monotonic_s() + 0.05);
      }
    }
  }

  // ---- play
  std::vector<Row> rows;
  for (std::size_t i = 0; i < imu.size(); ++i) rows.push_back({imu[i].t_s, true, i});
  for (std::size_t i = 0; i < ble.size(); ++i) rows.push_back({ble[i].t_s, false, i});
  std::stable_sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.t_s < b.t_s; });
  const double base = monotonic_s() + opts.lead_in_s - rows.front().t_s / opts.speed;
  auto at = [&](double t_s) { return base + t_s / opts.speed; };
  std::cout << "feed: scene time 0 at CLOCK_MONOTONIC " << fmt(base, 9) << " s (speed " << opts.speed << ")" << std::endl;

  std::uint64_t imu_written = 0, imu_failed = 0, ble_fed = 0, ble_failed = 0;
  std::vector<double> imu_late_ms, ble_late_ms;
  double first_advert = std::nan(""), last_advert = std::nan("");
  bool fifo_open = with_imu;
  for (const Row& r : rows) {
    if (!stop.sleep_until(at(r.t_s))) break;
    if (r.imu) {
      if (!fifo_open) {
        ++imu_failed;
        continue;
      }
      const ImuSample& s = imu[r.index];
      const std::int16_t raw[6]{iio_fake::to_lsb(s.accel_mps2[0], accel_per_lsb), iio_fake::to_lsb(s.accel_mps2[1], accel_per_lsb),
                                iio_fake::to_lsb(s.accel_mps2[2], accel_per_lsb), iio_fake::to_lsb(s.gyro_radps[0], gyro_per_lsb),
                                iio_fake::to_lsb(s.gyro_radps[1], gyro_per_lsb), iio_fake::to_lsb(s.gyro_radps[2], gyro_per_lsb)};
      if (fifo.write(iio_fake::pack_accel_gyro_scan(raw, std::llround(at(r.t_s) * 1e9)))) {
        ++imu_written;
        imu_late_ms.push_back(1e3 * (monotonic_s() - at(r.t_s)));
      } else {
        ++imu_failed;
        fifo_open = false;  // the node closed its buffer
        std::cerr << "locus feed: the node closed the IIO buffer at scene time " << fmt(r.t_s, 3) << " s\n";
      }
    } else {
      const BleAdvertisement& a = ble[r.index];
      const std::string address = scene::format_ble_address(a.address);
      try {
        const auto rssi = std::int16_t(std::lround(a.rssi_dbm));
        const auto tx = a.has_tx_power ? std::optional<std::int16_t>(std::int16_t(std::lround(a.tx_power_dbm))) : std::nullopt;
        if (!bluez->known(address)) {
          bluez->discover(address, rssi, tx);
        } else {
          if (tx && bluez->tx_power(address) != *tx) bluez->set_tx_power(address, *tx);
          bluez->set_rssi(address, rssi);
        }
        const double now = monotonic_s();
        ++ble_fed;
        ble_late_ms.push_back(1e3 * (now - at(r.t_s)));
        if (std::isnan(first_advert)) first_advert = now;
        last_advert = now;
      } catch (const sdbus::Error& e) {
        if (++ble_failed <= 5) std::cerr << "locus feed: RSSI of " << address << " at scene time " << fmt(r.t_s, 3) << " s: " << e.what() << "\n";
      }
    }
  }
  const bool interrupted = stop.stopped();
  std::cout << "feed: " << (interrupted ? "interrupted" : "done") << " imu_written=" << imu_written << " imu_failed=" << imu_failed
            << " imu_rows=" << imu.size() << " adverts_fed=" << ble_fed << " adverts_failed=" << ble_failed << " advert_rows=" << ble.size()
            << " imu_late_median_ms=" << fmt(median(imu_late_ms), 2) << " imu_late_max_ms=" << fmt(max_of(imu_late_ms), 2)
            << " ble_late_median_ms=" << fmt(median(ble_late_ms), 2) << " ble_late_max_ms=" << fmt(max_of(ble_late_ms), 2)
            << " first_advert_monotonic_s=" << fmt(first_advert, 9) << " last_advert_monotonic_s=" << fmt(last_advert, 9)
            << " scene_end_monotonic_s=" << fmt(at(rows.back().t_s), 9) << std::endl;
  if (interrupted) return 130;
  if (!opts.exit_when_done) stop.wait_forever();  // the node's IMU stays open until the run stops it
  return imu_failed || ble_failed ? 1 : 0;
}

}  // namespace locus::feed
