// The `iio` source through a fake sysfs tree with a FIFO as /dev/iio:deviceN: buffered scans (exact
// scaled values and timestamps, big-endian/shifted formats, magnetometer on the same or a second device,
// no timestamp channel), polled mode, the sysfs writes it makes, device errors (EOF, short read, vanished
// files), malformed trees, prompt stop() with a stalled writer, device listing and registration.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

#include "iio/fake_iio_tree.hpp"
#include "iio/iio_devices.hpp"
#include "iio/iio_source.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

using namespace locus;
using namespace locus::hal::iio;
using locus::iio_fake::FakeIioTree;
using locus::iio_fake::FifoWriter;
using namespace std::chrono_literals;

namespace {

constexpr double kAccelScale = 0.000598550;
constexpr double kGyroScale = 0.000152716;
constexpr double kMagnScale = 0.000146;

Params params_for(const FakeIioTree& tree) {
  Params p = Params::defaults(iio_schema());
  p.set("root", tree.root());
  return p;
}

void put_le(std::vector<std::uint8_t>& b, std::size_t off, std::uint64_t v, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) b[off + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_be(std::vector<std::uint8_t>& b, std::size_t off, std::uint64_t v, std::size_t bytes) {
  for (std::size_t i = 0; i < bytes; ++i) b[off + bytes - 1 - i] = static_cast<std::uint8_t>(v >> (8 * i));
}

/// A 24-byte scan packed by hand (independently of compute_layout): 6 x le:s16 at bytes 0..11, 4 bytes
/// of padding, the le:s64 timestamp at 16..23.
std::vector<std::uint8_t> scan24(const std::array<std::int16_t, 6>& raw, std::int64_t ts_ns) {
  std::vector<std::uint8_t> b(24, 0xEE);  // padding bytes must be ignored
  for (std::size_t i = 0; i < 6; ++i) put_le(b, 2 * i, static_cast<std::uint16_t>(raw[i]), 2);
  put_le(b, 16, static_cast<std::uint64_t>(ts_ns), 8);
  return b;
}

std::array<std::int16_t, 6> raw_of(int k) {
  return {static_cast<std::int16_t>(100 * k - 2000), static_cast<std::int16_t>(-3 * k), static_cast<std::int16_t>(16384 + k),
          static_cast<std::int16_t>(-32768 + k), static_cast<std::int16_t>(32767 - k), static_cast<std::int16_t>(7 * k)};
}

float si(std::int64_t raw, double scale, double unit = 1.0) {
  return static_cast<float>((static_cast<double>(raw) + 0.0) * scale * unit);
}

template <typename Pred>
bool wait_for(Pred pred, std::chrono::milliseconds timeout = 10000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return pred();
}

std::vector<ImuSample> drain(SensorQueue& q) {
  std::vector<ImuSample> out;
  Event e;
  while (q.try_pop(e)) {
    EXPECT_EQ(type_of(e), EventType::ImuSample);
    if (const auto* s = std::get_if<ImuSample>(&e)) out.push_back(*s);
  }
  return out;
}

std::string open_error(const Params& p) {
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  try {
    src.open(p, ctx);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(IioSource, BufferedScansGiveExactScaledValuesAndTimestamps) {
  FakeIioTree tree;
  tree.add_imu(0);
  const std::string d = FakeIioTree::dev_rel(0);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  EXPECT_EQ(src.device().id, "iio:device0");
  EXPECT_EQ(src.scan_bytes(), 24u);
  // The scan setup the source wrote: what it needs enabled, the rest disabled, the buffer length.
  for (const char* ch : {"in_accel_x", "in_accel_y", "in_accel_z", "in_anglvel_x", "in_anglvel_y", "in_anglvel_z",
                         "in_timestamp"}) {
    EXPECT_EQ(tree.read(d + "scan_elements/" + ch + "_en"), "1\n") << ch;
  }
  EXPECT_EQ(tree.read(d + "scan_elements/in_temp_en"), "0\n");
  EXPECT_EQ(tree.read(d + "buffer/length"), "256\n");
  EXPECT_EQ(tree.read(d + "buffer/enable"), "0\n");

  SensorQueue queue(1024);
  src.start(queue);
  constexpr int kScans = 200;
  const std::int64_t t0_ns = 1'700'000'000'123'456'789LL;
  const std::int64_t dt_ns = 9'615'385;
  std::atomic<bool> release{false};
  std::thread writer([&] {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    // Split scans across writes at odd boundaries: the reader must reassemble partial scans.
    std::vector<std::uint8_t> all;
    for (int k = 0; k < kScans; ++k) {
      const auto s = scan24(raw_of(k), t0_ns + k * dt_ns);
      all.insert(all.end(), s.begin(), s.end());
    }
    for (std::size_t pos = 0; pos < all.size();) {
      const std::size_t n = std::min<std::size_t>(37, all.size() - pos);
      ASSERT_TRUE(w.write(std::vector<std::uint8_t>(all.begin() + pos, all.begin() + pos + n)));
      pos += n;
    }
    // keep the FIFO open until the source is stopped (EOF would be an error)
    wait_for([&] { return release.load(); });
  });
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= kScans; })) << src.error();
  EXPECT_EQ(tree.read(d + "buffer/enable"), "1\n");
  const std::vector<ImuSample> got = drain(queue);
  ASSERT_EQ(got.size(), static_cast<std::size_t>(kScans));
  for (int k = 0; k < kScans; ++k) {
    const ImuSample& s = got[k];
    const auto r = raw_of(k);
    EXPECT_EQ(std::string(s.device.view()), "phone");
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(s.accel_mps2[a], si(r[a], kAccelScale)) << k << " " << a;
      EXPECT_EQ(s.gyro_radps[a], si(r[3 + a], kGyroScale)) << k << " " << a;
    }
    EXPECT_FALSE(s.has_mag);
    EXPECT_EQ(s.t_s, static_cast<double>(t0_ns + k * dt_ns) * 1e-9) << k;
  }
  EXPECT_EQ(queue.dropped(), 0u);
  EXPECT_FALSE(src.finished());
  EXPECT_EQ(src.error(), "");
  src.stop();
  release = true;
  writer.join();
  EXPECT_EQ(tree.read(d + "buffer/enable"), "0\n");
  EXPECT_FALSE(src.finished());  // stopped, not ended
  EXPECT_EQ(src.error(), "");
}

TEST(IioSource, ShortReadAtEofEndsWithError) {
  FakeIioTree tree;
  tree.add_imu(0);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  SensorQueue queue(64);
  src.start(queue);
  {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    ASSERT_TRUE(w.write(scan24(raw_of(1), 1000)));
    ASSERT_TRUE(w.write(scan24(raw_of(2), 2000)));
    std::vector<std::uint8_t> partial = scan24(raw_of(3), 3000);
    partial.resize(10);
    ASSERT_TRUE(w.write(partial));
  }  // writer closes: EOF
  ASSERT_TRUE(wait_for([&] { return src.finished(); }));
  const std::string e = src.error();
  EXPECT_NE(e.find(tree.path("dev/iio:device0")), std::string::npos) << e;
  EXPECT_NE(e.find("end of stream (EOF) after 2 scans"), std::string::npos) << e;
  EXPECT_NE(e.find("24-byte scans"), std::string::npos) << e;
  EXPECT_NE(e.find("short read: 10 bytes"), std::string::npos) << e;
  EXPECT_EQ(drain(queue).size(), 2u);  // everything before the error was delivered
  src.stop();
  EXPECT_EQ(tree.read(FakeIioTree::dev_rel(0) + "buffer/enable"), "0\n");
}

TEST(IioSource, CleanEofIsAnErrorToo) {
  FakeIioTree tree;
  tree.add_imu(0);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  SensorQueue queue(64);
  src.start(queue);
  {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    ASSERT_TRUE(w.write(scan24(raw_of(1), 1000)));
  }
  ASSERT_TRUE(wait_for([&] { return src.finished(); }));
  EXPECT_NE(src.error().find("end of stream (EOF) after 1 scans"), std::string::npos) << src.error();
  EXPECT_EQ(src.error().find("short read"), std::string::npos) << src.error();
  src.stop();
}

TEST(IioSource, StopIsPromptWhenTheWriterStalls) {
  FakeIioTree tree;
  tree.add_imu(0);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  for (const bool connect : {false, true}) {
    IioImuSource src;
    src.open(params_for(tree), ctx);
    SensorQueue queue(64);
    src.start(queue);
    FifoWriter w(tree.path("dev/iio:device0"));
    if (connect) {
      ASSERT_TRUE(w.connect());
      std::vector<std::uint8_t> half = scan24(raw_of(1), 1000);
      half.resize(12);  // half a scan, then nothing: the reader must not wait for the rest
      ASSERT_TRUE(w.write(half));
    }
    std::this_thread::sleep_for(100ms);
    const auto t0 = std::chrono::steady_clock::now();
    src.stop();
    const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_LT(stop_s, 2.0) << "stop() took " << stop_s << " s";  // ~50 ms poll timeout; generous bound
    std::printf("[   info   ] stop() with %s writer took %.1f ms\n", connect ? "a stalled" : "no", stop_s * 1e3);
    EXPECT_FALSE(src.finished());
    EXPECT_EQ(src.samples_produced(), 0u);
    EXPECT_EQ(tree.read(FakeIioTree::dev_rel(0) + "buffer/enable"), "0\n");
  }
}

TEST(IioSource, BigEndianShiftedFormat) {
  FakeIioTree tree;
  FakeIioTree::ImuOptions o;
  o.type = "be:s12/16>>4";
  tree.add_imu(0, o);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  ASSERT_EQ(src.scan_bytes(), 24u);
  SensorQueue queue(64);
  src.start(queue);
  const std::array<std::int16_t, 6> raw{-2048, 2047, -1, 0, 1000, -1000};
  std::thread writer([&] {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    std::vector<std::uint8_t> b(24, 0);
    for (std::size_t i = 0; i < 6; ++i) {
      // 12-bit value in the top bits of a big-endian 16-bit word; the low 4 bits carry junk.
      put_be(b, 2 * i, ((static_cast<std::uint16_t>(raw[i]) & 0x0fffu) << 4) | 0x000au, 2);
    }
    put_le(b, 16, 5'000'000'000ULL, 8);
    ASSERT_TRUE(w.write(b));
    wait_for([&] { return src.samples_produced() >= 1; });
  });
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 1; })) << src.error();
  src.stop();
  writer.join();
  const auto got = drain(queue);
  ASSERT_EQ(got.size(), 1u);
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(got[0].accel_mps2[a], si(raw[a], kAccelScale));
    EXPECT_EQ(got[0].gyro_radps[a], si(raw[3 + a], kGyroScale));
  }
  EXPECT_EQ(got[0].t_s, 5.0);
}

TEST(IioSource, NoTimestampChannelUsesSampleCountOverRate) {
  FakeIioTree tree;
  FakeIioTree::ImuOptions o;
  o.timestamp = false;
  tree.add_imu(0, o);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  Params p = params_for(tree);
  p.set("sampling_frequency_hz", 200.0);
  src.open(p, ctx);
  EXPECT_EQ(tree.read(FakeIioTree::dev_rel(0) + "sampling_frequency"), "200\n");
  EXPECT_EQ(src.sampling_frequency_hz(), 200.0);
  ASSERT_EQ(src.scan_bytes(), 12u);  // 6 x s16, no padding
  SensorQueue queue(64);
  src.start(queue);
  std::thread writer([&] {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    for (int k = 0; k < 5; ++k) {
      std::vector<std::uint8_t> b(12, 0);
      for (std::size_t i = 0; i < 6; ++i) put_le(b, 2 * i, static_cast<std::uint16_t>(raw_of(k)[i]), 2);
      ASSERT_TRUE(w.write(b));
    }
    wait_for([&] { return src.samples_produced() >= 5; });
  });
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 5; })) << src.error();
  src.stop();
  writer.join();
  const auto got = drain(queue);
  ASSERT_EQ(got.size(), 5u);
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(got[k].t_s, k / 200.0);
    EXPECT_EQ(got[k].accel_mps2[2], si(raw_of(k)[2], kAccelScale));
  }
}

TEST(IioSource, MagnetometerOnTheSameDeviceInMicroTesla) {
  FakeIioTree tree;
  FakeIioTree::ImuOptions o;
  o.magn = true;
  tree.add_imu(0, o);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  // 9 x s16 = 18 -> timestamp aligned at 24 -> 32 bytes.
  ASSERT_EQ(src.scan_bytes(), 32u);
  SensorQueue queue(64);
  src.start(queue);
  const std::int16_t raw[9]{1, 2, 3, 4, 5, 6, 1500, -2500, 3500};
  std::thread writer([&] {
    FifoWriter w(tree.path("dev/iio:device0"));
    ASSERT_TRUE(w.connect());
    ASSERT_TRUE(w.write(locus::iio_fake::pack_accel_gyro_magn_scan(raw, 42'000'000'000LL)));  // what `locus room --magnetometer` writes
    wait_for([&] { return src.samples_produced() >= 1; });
  });
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 1; })) << src.error();
  src.stop();
  writer.join();
  const auto got = drain(queue);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_TRUE(got[0].has_mag);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(got[0].mag_ut[a], si(raw[6 + a], kMagnScale, 100.0));
  EXPECT_EQ(got[0].t_s, 42.0);
}

TEST(IioSource, MagnetometerFromASecondDevice) {
  FakeIioTree tree;
  tree.add_imu(0);
  // iio:device1: a buffered magnetometer (magn x/y/z le:s16 + timestamp).
  const std::string m = FakeIioTree::dev_rel(1);
  tree.write(m + "name", "ak8975\n");
  tree.write(m + "in_magn_scale", "0.003\n");
  int index = 0;
  for (const char* ch : {"in_magn_x", "in_magn_y", "in_magn_z", "in_timestamp"}) {
    tree.write(m + "scan_elements/" + ch + "_en", "0\n");
    tree.write(m + "scan_elements/" + ch + "_index", std::to_string(index++) + "\n");
    tree.write(m + "scan_elements/" + ch + "_type", std::string(ch) == "in_timestamp" ? "le:s64/64>>0\n" : "le:s16/16>>0\n");
  }
  tree.write(m + "buffer/enable", "0\n");
  tree.write(m + "buffer/length", "16\n");
  tree.mkfifo("dev/iio:device1");

  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  Params p = params_for(tree);
  p.set("device", std::string("lsm6dsl"));
  p.set("mag_device", std::string("ak8975"));
  src.open(p, ctx);
  EXPECT_EQ(tree.read(m + "scan_elements/in_magn_x_en"), "1\n");
  SensorQueue queue(4096);
  src.start(queue);
  EXPECT_TRUE(wait_for([&] { return tree.read(m + "buffer/enable") == "1\n"; }));
  FifoWriter mw(tree.path("dev/iio:device1"));
  FifoWriter w(tree.path("dev/iio:device0"));
  ASSERT_TRUE(mw.connect());
  ASSERT_TRUE(w.connect());
  std::vector<std::uint8_t> mb(16, 0);
  put_le(mb, 0, static_cast<std::uint16_t>(std::int16_t{-100}), 2);
  put_le(mb, 2, 200, 2);
  put_le(mb, 4, 300, 2);
  ASSERT_TRUE(mw.write(mb));
  // IMU scans until one carries the magnetometer reading (the two devices are read independently).
  bool seen = false;
  ImuSample with_mag{};
  std::size_t before = 0;
  for (int k = 0; k < 2000 && !seen; ++k) {
    ASSERT_TRUE(w.write(scan24(raw_of(k), 1'000'000LL * (k + 1))));
    ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= static_cast<std::uint64_t>(k + 1); })) << src.error();
    for (const ImuSample& s : drain(queue)) {
      if (s.has_mag) {
        seen = true;
        with_mag = s;
      } else {
        ++before;
      }
    }
  }
  ASSERT_TRUE(seen);
  EXPECT_EQ(with_mag.mag_ut[0], static_cast<float>(-100 * 0.003 * 100.0));
  EXPECT_EQ(with_mag.mag_ut[1], static_cast<float>(200 * 0.003 * 100.0));
  EXPECT_EQ(with_mag.mag_ut[2], static_cast<float>(300 * 0.003 * 100.0));
  src.stop();
  EXPECT_EQ(tree.read(m + "buffer/enable"), "0\n");
  EXPECT_EQ(tree.read(FakeIioTree::dev_rel(0) + "buffer/enable"), "0\n");
}

TEST(IioSource, PolledModeReadsRawFilesOnTheSameTree) {
  FakeIioTree tree;
  FakeIioTree::ImuOptions o;
  o.magn = true;
  tree.add_imu(0, o);
  const std::string d = FakeIioTree::dev_rel(0);
  const std::array<int, 9> raw{-16384, 0, 16384, 100, -200, 300, 10, 20, -30};
  const char* files[] = {"in_accel_x_raw", "in_accel_y_raw", "in_accel_z_raw", "in_anglvel_x_raw", "in_anglvel_y_raw",
                         "in_anglvel_z_raw", "in_magn_x_raw", "in_magn_y_raw", "in_magn_z_raw"};
  for (std::size_t i = 0; i < 9; ++i) tree.write(d + files[i], std::to_string(raw[i]) + (i % 2 ? "\n" : std::string("\n\0", 2)));
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  Params p = params_for(tree);
  p.set("mode", std::string("polled"));
  p.set("poll_hz", 200.0);
  src.open(p, ctx);
  EXPECT_EQ(tree.read(d + "buffer/enable"), "0\n");  // polled mode leaves the buffer alone
  SensorQueue queue(1024);
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  const double before_s = static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
  src.start(queue);
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 5; })) << src.error();
  // A vanished file ends the stream with an error naming it.
  tree.remove(d + "in_anglvel_y_raw");
  ASSERT_TRUE(wait_for([&] { return src.finished(); }));
  EXPECT_NE(src.error().find(tree.path(d + "in_anglvel_y_raw")), std::string::npos) << src.error();
  EXPECT_NE(src.error().find("No such file"), std::string::npos) << src.error();
  src.stop();
  clock_gettime(CLOCK_MONOTONIC, &ts);
  const double after_s = static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
  const auto got = drain(queue);
  ASSERT_GE(got.size(), 5u);
  double last = 0.0;
  for (const ImuSample& s : got) {
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(s.accel_mps2[a], si(raw[a], kAccelScale));
      EXPECT_EQ(s.gyro_radps[a], si(raw[3 + a], kGyroScale));
      EXPECT_EQ(s.mag_ut[a], si(raw[6 + a], kMagnScale, 100.0));
    }
    EXPECT_TRUE(s.has_mag);
    EXPECT_GE(s.t_s, before_s);
    EXPECT_LE(s.t_s, after_s);
    EXPECT_GT(s.t_s, last);
    last = s.t_s;
  }
}

TEST(IioSource, PolledGarbageRawIsAnError) {
  FakeIioTree tree;
  tree.add_imu(0);
  const std::string d = FakeIioTree::dev_rel(0);
  Params p = params_for(tree);
  p.set("mode", std::string("polled"));
  tree.write(d + "in_accel_z_raw", "12abc\n");
  const std::string e = open_error(p);
  EXPECT_NE(e.find(tree.path(d + "in_accel_z_raw") + ": '12abc' has trailing characters"), std::string::npos) << e;

  // Turning bad while running: reported by the polling thread.
  tree.write(d + "in_accel_z_raw", "12\n");
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(p, ctx);
  SensorQueue queue(1024);
  src.start(queue);
  ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 1; })) << src.error();
  tree.write(d + "in_accel_z_raw", "oops\n");
  ASSERT_TRUE(wait_for([&] { return src.finished(); }));
  EXPECT_NE(src.error().find(tree.path(d + "in_accel_z_raw") + ": 'oops' is not an integer"), std::string::npos)
      << src.error();
  src.stop();
}

TEST(IioSource, MountMatrixRotatesIntoTheBodyFrame) {
  FakeIioTree tree;
  tree.add_imu(0);
  const std::string d = FakeIioTree::dev_rel(0);
  tree.write(d + "in_accel_mount_matrix", "0, 1, 0; 1, 0, 0; 0, 0, -1\n");
  tree.write(d + "in_accel_x_raw", "1000\n");
  tree.write(d + "in_accel_y_raw", "2000\n");
  tree.write(d + "in_accel_z_raw", "3000\n");
  for (const bool apply : {true, false}) {
    test::TestHost host;
    HostContext ctx = host.context("imu", "phone");
    IioImuSource src;
    Params p = params_for(tree);
    p.set("mode", std::string("polled"));
    p.set("apply_mount_matrix", apply);
    src.open(p, ctx);
    SensorQueue queue(1024);
    src.start(queue);
    ASSERT_TRUE(wait_for([&] { return src.samples_produced() >= 1; })) << src.error();
    src.stop();
    const auto got = drain(queue);
    ASSERT_FALSE(got.empty());
    if (apply) {
      EXPECT_EQ(got[0].accel_mps2[0], si(2000, kAccelScale));
      EXPECT_EQ(got[0].accel_mps2[1], si(1000, kAccelScale));
      EXPECT_EQ(got[0].accel_mps2[2], -si(3000, kAccelScale));
    } else {
      EXPECT_EQ(got[0].accel_mps2[0], si(1000, kAccelScale));
      EXPECT_EQ(got[0].accel_mps2[2], si(3000, kAccelScale));
    }
  }
}

TEST(IioSource, MalformedTreesGiveClearErrors) {
  FakeIioTree tree;
  tree.add_imu(0);
  const std::string d = FakeIioTree::dev_rel(0);
  const Params p = params_for(tree);
  ASSERT_EQ(open_error(p), "");

  tree.remove(d + "in_accel_scale");
  std::string e = open_error(p);
  EXPECT_NE(e.find("no in_accel_x_scale or in_accel_scale"), std::string::npos) << e;
  EXPECT_NE(e.find(tree.path(d.substr(0, d.size() - 1))), std::string::npos) << e;
  tree.write(d + "in_accel_scale", "fast\n");
  e = open_error(p);
  EXPECT_NE(e.find(tree.path(d + "in_accel_scale") + ": 'fast' is not a number"), std::string::npos) << e;
  tree.write(d + "in_accel_scale", "0.000598550\n");

  tree.write(d + "scan_elements/in_anglvel_y_type", "le:s16/16>>0>>1\n");
  e = open_error(p);
  EXPECT_NE(e.find(tree.path(d + "scan_elements/in_anglvel_y_type") + ": scan element type"), std::string::npos) << e;
  tree.write(d + "scan_elements/in_anglvel_y_type", "le:s16/16>>0\n");

  tree.remove(d + "scan_elements/in_anglvel_z_en");
  tree.remove(d + "scan_elements/in_anglvel_z_index");
  tree.remove(d + "scan_elements/in_anglvel_z_type");
  e = open_error(p);
  EXPECT_NE(e.find("no in_anglvel_z_en (expected scan elements for anglvel x/y/z)"), std::string::npos) << e;
  tree.write(d + "scan_elements/in_anglvel_z_en", "0\n");
  tree.write(d + "scan_elements/in_anglvel_z_index", "5\n");
  tree.write(d + "scan_elements/in_anglvel_z_type", "le:s16/16>>0\n");
  ASSERT_EQ(open_error(p), "");

  tree.remove("dev/iio:device0");
  e = open_error(p);
  EXPECT_NE(e.find("cannot open " + tree.path("dev/iio:device0")), std::string::npos) << e;
  tree.mkfifo("dev/iio:device0");

  Params q = p;
  q.set("device", std::string("bmi160"));
  e = open_error(q);
  EXPECT_NE(e.find("no IIO device 'bmi160'"), std::string::npos) << e;
  EXPECT_NE(e.find("iio:device0 (lsm6dsl)"), std::string::npos) << e;
  q.set("device", std::string("iio:device0"));
  q.set("mag_device", std::string("lsm6dsl"));
  e = open_error(q);
  EXPECT_NE(e.find("is the IMU device iio:device0 itself"), std::string::npos) << e;

  q = p;
  q.set("sampling_frequency_hz", 100.0);
  tree.remove(d + "sampling_frequency");
  e = open_error(q);
  EXPECT_NE(e.find("no sampling_frequency attribute"), std::string::npos) << e;

  Params empty = Params::defaults(iio_schema());
  FakeIioTree nothing;
  empty.set("root", nothing.root());
  e = open_error(empty);
  EXPECT_NE(e.find("no IIO device with accelerometer channels"), std::string::npos) << e;
}

TEST(IioSource, BufferedNeedsScanElementsAndATimeBase) {
  FakeIioTree tree;
  FakeIioTree::ImuOptions o;
  o.buffered = false;
  tree.add_imu(0, o);
  std::string e = open_error(params_for(tree));
  EXPECT_NE(e.find("scan_elements: missing (the device has no buffered interface; use mode: polled)"), std::string::npos)
      << e;

  FakeIioTree t2;
  FakeIioTree::ImuOptions o2;
  o2.timestamp = false;
  o2.sampling_frequency = "";
  t2.add_imu(0, o2);
  e = open_error(params_for(t2));
  EXPECT_NE(e.find("no in_timestamp scan element and no positive sampling_frequency"), std::string::npos) << e;
}

TEST(IioSource, PicksTheFirstDeviceWithAnAccelerometer) {
  FakeIioTree tree;
  // iio:device0: a pressure sensor, iio:device2: the IMU.
  tree.write(FakeIioTree::dev_rel(0) + "name", "bmp280\n");
  tree.write(FakeIioTree::dev_rel(0) + "in_pressure_raw", "1000\n");
  FakeIioTree::ImuOptions o;
  o.name = "bmi160";
  tree.add_imu(2, o);
  test::TestHost host;
  HostContext ctx = host.context("imu", "phone");
  IioImuSource src;
  src.open(params_for(tree), ctx);
  EXPECT_EQ(src.device().id, "iio:device2");
  EXPECT_EQ(src.device().name, "bmi160");
}

TEST(IioDevices, ListsDevicesWithChannels) {
  FakeIioTree tree;
  tree.add_imu(0);
  tree.write(FakeIioTree::dev_rel(1) + "name", "bmp280\n");
  tree.write(FakeIioTree::dev_rel(1) + "in_pressure_raw", "1000\n");
  tree.write("sys/bus/iio/devices/trigger0/name", "trig\n");
  const auto list = list_iio_devices(tree.root());
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0].backend, "iio");
  EXPECT_EQ(list[0].kind, "imu");
  EXPECT_EQ(list[0].id, "iio:device0");
  EXPECT_NE(list[0].description.find("lsm6dsl: channels accel_x accel_y accel_z anglvel_x"), std::string::npos)
      << list[0].description;
  EXPECT_NE(list[0].description.find("timestamp"), std::string::npos) << list[0].description;
  EXPECT_NE(list[0].description.find("buffered"), std::string::npos) << list[0].description;
  EXPECT_EQ(list[1].kind, "sensor");
  EXPECT_NE(list[1].description.find("bmp280: channels pressure; polled only"), std::string::npos) << list[1].description;

  FakeIioTree empty;
  const auto none = list_iio_devices(empty.root());
  ASSERT_EQ(none.size(), 1u);
  EXPECT_EQ(none[0].kind, "iio_unavailable");
  EXPECT_NE(none[0].description.find("no IIO devices in"), std::string::npos);
}

TEST(IioRegistry, IioIsABuiltinImuSource) {
  Registry registry;
  register_builtins(registry);
  const SensorSourceDescriptor* d = registry.find_sensor_source("iio");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->kind, SensorKind::Imu);
  auto src = registry.create_sensor_source("iio");
  ASSERT_NE(src, nullptr);
  EXPECT_EQ(src->kind(), SensorKind::Imu);
  EXPECT_TRUE(src->live());
}
