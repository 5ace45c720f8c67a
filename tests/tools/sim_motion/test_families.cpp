// The montage, spyloc and locble families render scenes that load_scene accepts, with the streams
// and truth extras they promise; same seed → same files.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"
#include "locus/sim/families.hpp"

using namespace locus;
using namespace locus::sim;
namespace fs = std::filesystem;

namespace {

fs::path out_dir(const std::string& name) {
  const fs::path d = fs::path(LOCUS_BINARY_DIR) / "test_out" / "sim_motion" / name;
  fs::remove_all(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

Simulation make(const std::string& family, std::uint64_t seed, std::map<std::string, std::string> kv,
                std::optional<double> duration = std::nullopt) {
  FamilyOptions o;
  o.seed = seed;
  o.duration_s = duration;
  for (const auto& [k, v] : kv) o.set(k, v);
  const Family* f = find_family(family);
  EXPECT_NE(f, nullptr) << family;
  return f->make(o);
}

std::size_t count_rows(const fs::path& csv) {
  scene::CsvReader r(csv.string());
  std::size_t n = 0;
  while (r.next_row()) ++n;
  return n;
}

}  // namespace

TEST(Families, LocbleSceneLoadsWithBleImuAndStepTruth) {
  const fs::path dir = out_dir("locble");
  SceneSimulator(make("locble", 3, {{"tags", "4"}, {"clustered", "2"}, {"env", "mixed"}})).write(dir.string());
  const scene::Scene sc = scene::load_scene(dir.string());
  ASSERT_EQ(sc.devices.size(), 1u);
  ASSERT_EQ(sc.emitters.size(), 4u);
  const auto& obs = sc.devices[0];
  EXPECT_TRUE(obs.audio.empty());
  ASSERT_FALSE(obs.ble.empty());
  ASSERT_FALSE(obs.imu.empty());
  // BLE rows parse and come from the four tags.
  scene::BleCsvReader ble(sc.path(obs.ble), DeviceId("O"));
  BleAdvertisement a;
  std::set<std::string> seen;
  std::size_t n = 0;
  while (ble.next(a)) {
    ++n;
    seen.insert(scene::format_ble_address(a.address));
    EXPECT_LT(a.rssi_dbm, -30.0f);
  }
  EXPECT_EQ(seen.size(), 4u);
  EXPECT_GT(n, 100u);
  // IMU: standing still at the start, the accelerometer reads ~g.
  scene::ImuCsvReader imu(sc.path(obs.imu), DeviceId("O"));
  ImuSample s;
  ASSERT_TRUE(imu.next(s));
  EXPECT_NEAR(std::hypot(s.accel_mps2[0], s.accel_mps2[1], s.accel_mps2[2]), 9.81, 0.3);
  EXPECT_TRUE(s.has_mag);
  // Step truth: 4-9 steps for a 3.5-5.5 m L.
  const std::size_t steps = count_rows(dir / "truth_steps.csv");
  EXPECT_GE(steps, 4u);
  EXPECT_LE(steps, 10u);
}

TEST(Families, LocbleIsDeterministicForASeed) {
  const fs::path a = out_dir("locble_a"), b = out_dir("locble_b"), c = out_dir("locble_c");
  SceneSimulator(make("locble", 11, {})).write(a.string());
  SceneSimulator(make("locble", 11, {})).write(b.string());
  SceneSimulator(make("locble", 12, {})).write(c.string());
  for (const char* f : {"O/ble.csv", "O/imu.csv", "truth.csv", "truth_steps.csv"}) {
    EXPECT_EQ(slurp(a / f), slurp(b / f)) << f;
    EXPECT_NE(slurp(a / f), slurp(c / f)) << f;
  }
}

TEST(Families, SpylocSceneHasAnchorsSyncBeepsAndLosTruth) {
  const fs::path dir = out_dir("spyloc");
  SceneSimulator(make("spyloc", 5, {{"beacons", "4"}}, 8.0)).write(dir.string());
  const scene::Scene sc = scene::load_scene(dir.string());
  ASSERT_EQ(sc.emitters.size(), 4u);
  for (const auto& e : sc.emitters) {
    ASSERT_TRUE(e.anchor_position_m.has_value()) << e.id;
    ASSERT_EQ(e.emits.size(), 1u);
    EXPECT_EQ(e.emits[0].type, "multitone");
    EXPECT_GE(e.emits[0].tones_hz.size(), 3u);
    ASSERT_TRUE(e.emits[0].sync_delay_s.has_value());
  }
  const auto* p = sc.find_device("P");
  ASSERT_NE(p, nullptr);
  ASSERT_FALSE(p->sync.empty());
  ASSERT_FALSE(p->audio.empty());
  scene::SyncCsvReader sync(sc.path(p->sync), DeviceId("P"));
  RadioSync r;
  std::size_t n = 0;
  while (sync.next(r)) ++n;
  EXPECT_GE(n, 16u);  // ~7 s of 1 beep/s per beacon
  EXPECT_GE(count_rows(dir / "truth_los.csv"), n);
  EXPECT_GE(count_rows(dir / "truth_steps.csv"), 5u);
}

TEST(Families, MontageSceneHasGoldEmittersWithImu) {
  const fs::path dir = out_dir("montage");
  SceneSimulator(make("montage", 2, {{"walkers", "2"}, {"path", "straight"}}, 4.0)).write(dir.string());
  const scene::Scene sc = scene::load_scene(dir.string());
  ASSERT_EQ(sc.devices.size(), 2u);
  std::set<int> codes;
  for (const auto& d : sc.devices) {
    ASSERT_EQ(d.emits.size(), 1u);
    EXPECT_EQ(d.emits[0].type, "gold");
    EXPECT_EQ(d.emits[0].carrier_hz, 19000.0);
    codes.insert(d.emits[0].index);
    EXPECT_FALSE(d.imu.empty());
    EXPECT_FALSE(d.audio.empty());
  }
  EXPECT_EQ(codes.size(), 2u);
  EXPECT_TRUE(fs::exists(dir / "truth_steps.csv"));
}

TEST(Families, RejectUnknownAndOutOfRangeOptions) {
  EXPECT_THROW(make("locble", 1, {{"tags", "9"}}), std::invalid_argument);
  EXPECT_THROW(make("locble", 1, {{"tags", "2"}, {"clustered", "2"}}), std::invalid_argument);
  EXPECT_THROW(make("spyloc", 1, {{"beacon", "3"}}), std::invalid_argument);
  EXPECT_THROW(make("montage", 1, {{"path", "circle"}}), std::invalid_argument);
  EXPECT_THROW(make("montage", 1, {{"formation", "free"}}), std::invalid_argument);  // needs room=hall
  EXPECT_THROW(make("montage", 1, {{"degree", "8"}}), std::invalid_argument);
}
