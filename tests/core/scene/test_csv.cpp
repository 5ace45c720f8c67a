// CSV streams: the strict reader (header by name, quoting, CRLF, BOM, blank lines), the typed readers
// and writers (round trips at full precision), and the truth trajectories (interpolation, slerp).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "locus/scene/streams.hpp"
#include "scene_test_util.hpp"

using namespace locus;
using namespace locus::scene;
using namespace locus::scene::test;

TEST(SceneCsv, Rfc4180QuotingCrlfBomAndTrailingBlankLines) {
  TempDir tmp;
  const std::string p = tmp / "q.csv";
  write_file(p, "\xEF\xBB\xBF" "a, b ,c\r\n1,\"x,\"\"y\"\"\r\nz\",3\r\n\"\",,\r\n\r\n\n");
  CsvReader csv(p);
  EXPECT_EQ(csv.header(), (std::vector<std::string>{"a", "b", "c"}));
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(csv.field(0), "1");
  EXPECT_EQ(csv.field(1), "x,\"y\"\r\nz");
  EXPECT_EQ(csv.field(2), "3");
  EXPECT_EQ(csv.line(2), 3);  // the quoted field spanned a line break
  EXPECT_EQ(csv.column(2), 4);
  EXPECT_EQ(csv.row_line(), 2);
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(csv.row_line(), 4);
  EXPECT_TRUE(csv.blank(0));
  EXPECT_TRUE(csv.blank(2));
  EXPECT_FALSE(csv.next_row());
  EXPECT_FALSE(csv.next_row());
}

namespace {
std::size_t open_fds() {
  std::size_t n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/fd")) ++n;
  return n;
}
}  // namespace

// Found by profiling the imu_csv fuzz target: an unterminated quote in the header row threw out of the
// constructor past an unowned FILE*, so every such file left a descriptor (and its 4 KiB buffer) open.
TEST(SceneCsv, AMalformedHeaderClosesTheFile) {
  TempDir tmp;
  const std::string p = tmp / "h.csv";
  write_file(p, "t,ax,\"gy0,1\n0,0\n");
  const std::size_t before = open_fds();
  for (int i = 0; i < 50; ++i) EXPECT_THROW(CsvReader{p}, SceneError);
  write_file(p, "t,t\n0,0\n");
  for (int i = 0; i < 50; ++i) EXPECT_THROW(CsvReader{p}, SceneError);
  EXPECT_EQ(open_fds(), before);
}

TEST(SceneCsv, NumbersAreStrict) {
  TempDir tmp;
  const std::string p = tmp / "n.csv";
  write_file(p, "v\n 1.5 \n+2\n-3e-2\n1e400\nnan\n0x10\n");
  CsvReader csv(p);
  const auto c = csv.require_column("v");
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(csv.number(c), 1.5);
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(csv.number(c), 2.0);
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(csv.number(c), -0.03);
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(scene_error([&] { csv.number(c); }), p + ":5:1: column 'v': number '1e400' is out of range");
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(scene_error([&] { csv.number(c); }), p + ":6:1: column 'v': expected a finite number, got 'nan'");
  ASSERT_TRUE(csv.next_row());
  EXPECT_EQ(scene_error([&] { csv.number(c); }), p + ":7:1: column 'v': expected a number, got '0x10'");
}

TEST(SceneCsv, ImuRoundTripWithAndWithoutMag) {
  TempDir tmp;
  std::mt19937 rng(3);
  std::normal_distribution<float> nd(0.0f, 5.0f);
  std::vector<ImuSample> in;
  double t = 1234.000123456789;
  for (int i = 0; i < 500; ++i) {
    ImuSample s;
    s.device = "A";
    s.t_s = t;
    t += 0.01 + 1e-9 * i;
    for (int k = 0; k < 3; ++k) {
      s.accel_mps2[k] = nd(rng);
      s.gyro_radps[k] = nd(rng) * 1e-3f;
      s.mag_ut[k] = nd(rng) * 10.0f;
    }
    s.has_mag = (i % 7) != 0;
    if (!s.has_mag) s.mag_ut = {0, 0, 0};
    in.push_back(s);
  }
  for (bool with_mag : {true, false}) {
    const std::string p = tmp / (with_mag ? "m.csv" : "n.csv");
    {
      ImuCsvWriter w(p, with_mag);
      for (const auto& s : in) w.write(s);
      w.close();
    }
    ImuCsvReader r(p, "A");
    EXPECT_EQ(r.has_mag_columns(), with_mag);
    ImuSample s;
    std::size_t n = 0;
    while (r.next(s)) {
      const ImuSample& e = in[n++];
      ASSERT_EQ(s.device.str(), e.device.str());
      ASSERT_EQ(s.t_s, e.t_s);
      ASSERT_EQ(s.accel_mps2, e.accel_mps2);
      ASSERT_EQ(s.gyro_radps, e.gyro_radps);
      ASSERT_EQ(s.has_mag, with_mag && e.has_mag);
      if (s.has_mag) {
        ASSERT_EQ(s.mag_ut, e.mag_ut);
      }
    }
    EXPECT_EQ(n, in.size());
  }
}

TEST(SceneCsv, ImuColumnOrderFreeExtraColumnsIgnored) {
  TempDir tmp;
  const std::string p = tmp / "imu.csv";
  write_file(p, "gz,gy,gx,az,ay,ax,comment,t\n0.3,0.2,0.1,9.81,0,-0.5,\"hello, world\",0.02\n");
  ImuCsvReader r(p, "P");
  ImuSample s;
  ASSERT_TRUE(r.next(s));
  EXPECT_EQ(s.t_s, 0.02);
  EXPECT_EQ(s.accel_mps2, (std::array<float, 3>{-0.5f, 0.0f, 9.81f}));
  EXPECT_EQ(s.gyro_radps, (std::array<float, 3>{0.1f, 0.2f, 0.3f}));
  EXPECT_FALSE(s.has_mag);
  EXPECT_EQ(s.device.str(), "P");
  EXPECT_FALSE(r.next(s));
}

TEST(SceneCsv, BleRoundTripAndOptionalColumns) {
  TempDir tmp;
  const std::string p = tmp / "ble.csv";
  std::vector<BleAdvertisement> in;
  for (int i = 0; i < 50; ++i) {
    BleAdvertisement a;
    a.device = "B";
    a.t_s = 0.1 * i + 1e-7;
    a.address = {0xC4, 0x2C, 0x03, 0x3A, 0x2C, static_cast<std::uint8_t>(i)};
    a.rssi_dbm = -40.5f - static_cast<float>(i);
    a.has_tx_power = i % 2 == 0;
    a.tx_power_dbm = a.has_tx_power ? -59.0f : 0.0f;
    a.channel = static_cast<std::uint8_t>(i % 4 == 3 ? 0 : 37 + i % 4);
    in.push_back(a);
  }
  {
    BleCsvWriter w(p);
    for (const auto& a : in) w.write(a);
  }
  BleCsvReader r(p, "B");
  BleAdvertisement a;
  std::size_t n = 0;
  while (r.next(a)) {
    const auto& e = in[n++];
    ASSERT_EQ(a.t_s, e.t_s);
    ASSERT_EQ(a.address, e.address);
    ASSERT_EQ(a.rssi_dbm, e.rssi_dbm);
    ASSERT_EQ(a.has_tx_power, e.has_tx_power);
    ASSERT_EQ(a.tx_power_dbm, e.tx_power_dbm);
    ASSERT_EQ(a.channel, e.channel);
  }
  EXPECT_EQ(n, in.size());
  // minimal columns, lower-case hex, integer rssi
  write_file(tmp / "min.csv", "rssi,address,t\n-70,c4:2c:03:3a:2c:a1,5\n");
  BleCsvReader m(tmp / "min.csv", "B");
  ASSERT_TRUE(m.next(a));
  EXPECT_EQ(format_ble_address(a.address), "C4:2C:03:3A:2C:A1");
  EXPECT_EQ(a.rssi_dbm, -70.0f);
  EXPECT_FALSE(a.has_tx_power);
  EXPECT_EQ(a.channel, 0);
}

TEST(SceneCsv, SyncRoundTripWithQuotedSource) {
  TempDir tmp;
  const std::string p = tmp / "sync.csv";
  {
    SyncCsvWriter w(p);
    RadioSync s;
    s.t_s = 0.1;
    s.source = "B1";
    w.write(s);
    s.t_s = 1e-9;
    s.source = "odd,name";
    w.write(s);
  }
  EXPECT_EQ(read_file(p), "t,source\n0.1,B1\n1e-09,\"odd,name\"\n");
  SyncCsvReader r(p, "A");
  RadioSync s;
  ASSERT_TRUE(r.next(s));
  EXPECT_EQ(s.source.str(), "B1");
  EXPECT_EQ(s.device.str(), "A");
  ASSERT_TRUE(r.next(s));
  EXPECT_EQ(s.t_s, 1e-9);
  EXPECT_EQ(s.source.str(), "odd,name");
  EXPECT_FALSE(r.next(s));
}

TEST(SceneTruth, RoundTripInterpolationSlerpAndHold) {
  TempDir tmp;
  const std::string p = tmp / "truth.csv";
  const double c = std::cos(M_PI / 4), s = std::sin(M_PI / 4);  // 90° about z
  {
    TruthCsvWriter w(p);
    w.write({0.0, "A", {0, 0, 1}, {1, 0, 0, 0}});
    w.write({0.5, "tag7", {3, 3, 0}, {1, 0, 0, 0}});
    w.write({1.0, "A", {2, 4, 1}, {c, 0, 0, s}});
    w.write({2.0, "A", {2, 4, 3}, {c, 0, 0, s}});
  }
  TruthCsvReader rd(p);
  TruthRow row;
  ASSERT_TRUE(rd.next(row));
  EXPECT_EQ(row.id, "A");
  ASSERT_TRUE(rd.next(row));
  EXPECT_EQ(row.id, "tag7");
  EXPECT_EQ(row.position_m, (Vec3{3, 3, 0}));

  const auto tt = TruthTrajectories::load(p);
  EXPECT_EQ(tt.ids(), (std::vector<std::string>{"A", "tag7"}));
  EXPECT_TRUE(tt.has("A"));
  EXPECT_FALSE(tt.has("B"));
  EXPECT_EQ(tt.t_begin_s(), 0.0);
  EXPECT_EQ(tt.t_end_s(), 2.0);
  EXPECT_EQ(tt.time_range("A"), (std::pair<double, double>{0.0, 2.0}));
  const Pose mid = tt.pose_at("A", 0.5);
  EXPECT_DOUBLE_EQ(mid.position_m[0], 1.0);
  EXPECT_DOUBLE_EQ(mid.position_m[1], 2.0);
  EXPECT_DOUBLE_EQ(mid.position_m[2], 1.0);
  // slerp halfway of 0→90° about z is 45° about z
  EXPECT_NEAR(mid.q_wxyz[0], std::cos(M_PI / 8), 1e-12);
  EXPECT_NEAR(mid.q_wxyz[3], std::sin(M_PI / 8), 1e-12);
  const Pose quarter = tt.pose_at("A", 0.25);
  EXPECT_NEAR(quarter.q_wxyz[3], std::sin(M_PI / 16), 1e-12);
  EXPECT_DOUBLE_EQ(tt.pose_at("A", 1.5).position_m[2], 2.0);
  // hold at both ends; a single-row object is static
  EXPECT_EQ(tt.pose_at("A", -5.0).position_m, (Vec3{0, 0, 1}));
  EXPECT_EQ(tt.pose_at("A", 99.0).position_m, (Vec3{2, 4, 3}));
  EXPECT_EQ(tt.pose_at("tag7", 0.0).position_m, (Vec3{3, 3, 0}));
  EXPECT_EQ(tt.pose_at("tag7", 10.0).position_m, (Vec3{3, 3, 0}));
  EXPECT_THROW(tt.pose_at("nobody", 0.0), std::out_of_range);
}

TEST(SceneTruth, SlerpTakesShortestArc) {
  // q and -q are the same rotation: interpolating towards -q must not spin the long way round
  const std::array<double, 4> a{1, 0, 0, 0};
  const double c = std::cos(M_PI / 8), s = std::sin(M_PI / 8);  // 45° about x
  const auto r = slerp(a, {-c, -s, 0, 0}, 0.5);
  EXPECT_NEAR(std::fabs(r[0]), std::cos(M_PI / 16), 1e-12);
  EXPECT_NEAR(std::fabs(r[1]), std::sin(M_PI / 16), 1e-12);
  const auto e = slerp(a, a, 0.3);
  EXPECT_EQ(e, a);
}

TEST(SceneTruth, AbsentOptionalTruthFileFieldsAndUnnormalisedQuaternion) {
  TempDir tmp;
  const std::string p = tmp / "truth.csv";
  write_file(p, "id,t,qz,qy,qx,qw,z,y,x,extra\nA,0,0,0,0,1.0005,1,2,3,x\n");
  TruthCsvReader rd(p);
  TruthRow row;
  ASSERT_TRUE(rd.next(row));
  EXPECT_EQ(row.position_m, (Vec3{3, 2, 1}));
  EXPECT_DOUBLE_EQ(row.q_wxyz[0], 1.0);  // normalised
}
