// locus feed: bad input is refused before anything is played, with a message naming what is wrong.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "feed/feed.hpp"

namespace fs = std::filesystem;
using locus::feed::FeedOptions;
using locus::feed::run_feed;

namespace {

/// A scene in a fresh temp dir: device O with imu.csv and ble.csv (both optional), removed at the end.
class Scene {
 public:
  Scene(const std::string& imu_rows, const std::string& ble_rows, bool with_ble = true) {
    dir_ = fs::temp_directory_path() / ("locus-feed-test-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::create_directories(dir_ / "O");
    std::ofstream(dir_ / "scene.yaml") << "format: locus-scene/1\nname: feed-test\nsample_rate: 44100\nspeed_of_sound: 343\ndevices:\n"
                                       << "- {id: O, imu: O/imu.csv" << (with_ble ? ", ble: O/ble.csv" : "") << "}\n";
    std::ofstream(dir_ / "O" / "imu.csv") << "t,ax,ay,az,gx,gy,gz\n" << imu_rows;
    if (with_ble) std::ofstream(dir_ / "O" / "ble.csv") << "t,address,rssi,tx_power,channel\n" << ble_rows;
  }
  ~Scene() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string dir() const { return dir_.string(); }

 private:
  fs::path dir_;
  static inline int counter_ = 0;
};

const char* kImu = "0.00,0,0,9.81,0,0,0\n0.01,0,0,9.81,0,0,0\n";
const char* kBle = "0.05,AA:BB:CC:DD:EE:01,-70,-60,37\n";

int feed(const FeedOptions& o, std::string& err) {
  testing::internal::CaptureStderr();
  const int status = run_feed(o);
  err = testing::internal::GetCapturedStderr();
  return status;
}

FeedOptions options(const Scene& s, const std::string& device = "O") {
  FeedOptions o;
  o.scene_dir = s.dir();
  o.device = device;
  o.iio_root = s.dir() + "/iio";
  o.start_timeout_s = 1.0;
  return o;
}

}  // namespace

TEST(Feed, AnUnknownDeviceIsNamedWithTheScenesDevices) {
  Scene s(kImu, kBle);
  std::string err;
  EXPECT_EQ(feed(options(s, "X"), err), 2);
  EXPECT_NE(err.find("has no device 'X' (devices: O)"), std::string::npos) << err;
}

TEST(Feed, ADeviceWithoutABleStreamIsRefused) {
  Scene s(kImu, "", false);
  std::string err;
  EXPECT_EQ(feed(options(s), err), 2);
  EXPECT_NE(err.find("has no ble stream (scene.yaml devices[].ble)"), std::string::npos) << err;
}

TEST(Feed, AMalformedBleRowIsNamedByFileAndLine) {
  Scene s(kImu, "0.05,AA:BB:CC:DD:EE:01,-70,-60,37\n0.15,AA:BB:CC:DD:EE:01,loud,-60,37\n");
  std::string err;
  EXPECT_EQ(feed(options(s), err), 2);
  EXPECT_NE(err.find("ble.csv"), std::string::npos) << err;
  EXPECT_NE(err.find(":3"), std::string::npos) << "the line of the bad row: " << err;
  EXPECT_FALSE(fs::exists(s.dir() + "/iio")) << "nothing is created for bad input";
}

TEST(Feed, AnEmptyStreamIsRefused) {
  Scene s(kImu, "");
  std::string err;
  EXPECT_EQ(feed(options(s), err), 2);
  EXPECT_NE(err.find("ble.csv has no rows"), std::string::npos) << err;
}

TEST(Feed, AnImuBeyondTheLargestRangeIsRefused) {
  Scene s("0.00,0,0,9.81,0,0,0\n0.01,0,0,200.0,0,0,0\n", kBle);
  std::string err;
  EXPECT_EQ(feed(options(s), err), 2);
  EXPECT_NE(err.find("accel up to 200.00 m/s^2 exceeds the IIO part's largest range (16 g, 2000 dps)"), std::string::npos) << err;
}

TEST(Feed, AnExistingIioRootIsNotOverwritten) {
  Scene s(kImu, kBle);
  fs::create_directories(s.dir() + "/iio");
  std::string err;
  EXPECT_EQ(feed(options(s), err), 2);
  EXPECT_NE(err.find("exists already"), std::string::npos) << err;
}

TEST(Feed, NoSystemBusIsAFailureNamingIt) {
  Scene s(kImu, kBle);
  const char* old = std::getenv("DBUS_SYSTEM_BUS_ADDRESS");
  const std::string saved = old ? old : "";
  const std::string bus = "unix:path=" + s.dir() + "/no-such-bus";
  ::setenv("DBUS_SYSTEM_BUS_ADDRESS", bus.c_str(), 1);
  FeedOptions o = options(s);
  o.iio_root.clear();  // BLE only
  std::string err;
  const int status = feed(o, err);
  if (old) ::setenv("DBUS_SYSTEM_BUS_ADDRESS", saved.c_str(), 1);
  else ::unsetenv("DBUS_SYSTEM_BUS_ADDRESS");
  EXPECT_EQ(status, 1);
  EXPECT_NE(err.find("BlueZ (" + bus + ")"), std::string::npos) << err;
}
