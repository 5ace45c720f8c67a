// Real-time safety of the IIO source's per-scan path: decoding a packed scan (unpack, scale, mount
// matrix, timestamp) and handing the ImuSample to the SensorQueue never allocates or locks. (The
// reading thread's poll()/read() loop around it only uses buffers allocated in open().)
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "iio/iio_parse.hpp"
#include "iio/iio_source.hpp"
#include "locus/sensor_source.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus {
namespace {

TEST(RtSafety, IioScanDecodeDoesNotAllocateOrLock) {
  using namespace hal::iio;
  std::vector<ScanChannel> channels;
  const char* names[] = {"in_accel_x", "in_accel_y", "in_accel_z", "in_anglvel_x", "in_anglvel_y", "in_anglvel_z",
                         "in_timestamp"};
  for (int i = 0; i < 7; ++i) {
    ScanChannel c;
    c.name = names[i];
    c.index = i;
    c.enabled = true;
    c.type = parse_scan_type(i < 6 ? "be:s12/16>>4" : "le:s64/64>>0");
    channels.push_back(c);
  }
  const ScanLayout layout = compute_layout(channels);
  ScanDecoder dec;
  dec.has_accel = dec.has_gyro = true;
  dec.accel.type = "accel";
  dec.gyro.type = "anglvel";
  for (auto& c : dec.accel.conv) c.scale = 0.000598550;
  for (auto& c : dec.gyro.conv) c.scale = 0.000152716;
  dec.accel.mount = Matrix3{{{0, 1, 0}, {1, 0, 0}, {0, 0, -1}}};
  dec.bind(layout);
  ASSERT_EQ(dec.scan_bytes, 24u);

  std::vector<std::uint8_t> scans(24 * 256);
  for (std::size_t k = 0; k < 256; ++k) {
    for (std::size_t i = 0; i < 6; ++i) pack_value(scans.data() + 24 * k, layout.slots[i].offset, layout.slots[i].type, static_cast<std::int64_t>(k) - 100);
    pack_value(scans.data() + 24 * k, 16, layout.slots[6].type, static_cast<std::int64_t>(k) * 1000000);
  }
  SensorQueue queue(64);  // fills up: the drop path too
  double sum = 0.0;
  RtSection rt;
  for (int rep = 0; rep < 10; ++rep) {
    for (std::size_t k = 0; k < 256; ++k) {
      const std::uint8_t* p = scans.data() + 24 * k;
      ImuSample s;
      dec.decode(p, s);
      sum += s.accel_mps2[0] + s.t_s;
      if (!queue.try_push(Event(s))) queue.count_drop();
    }
  }
  rt.end();
  EXPECT_NE(sum, 0.0);
  EXPECT_GT(queue.dropped(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

}  // namespace
}  // namespace locus
