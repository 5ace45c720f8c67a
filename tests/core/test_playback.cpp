// PlaybackScheduler and SchedulerEmitter: clips land at their scheduled frame exactly, late and cut
// clips are counted, the schedule is bounded, and the emitter renders scene-format signals.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

#include "locus/dsp/signals.hpp"
#include "locus/playback.hpp"

namespace locus {
namespace {

std::vector<float> ramp(std::size_t n) {
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = 0.001f * static_cast<float>(i + 1);
  return v;
}

TEST(PlaybackScheduler, ClipStartsAtItsFrameAcrossBlocks) {
  PlaybackScheduler s(44100.0, 8);
  const std::vector<float> clip = ramp(300);
  ASSERT_TRUE(s.submit(clip, 1000));
  std::vector<float> out(2 * 128), all;
  for (int b = 0; b < 16; ++b) {
    s.render_interleaved(out.data(), 128, 2);
    for (std::size_t f = 0; f < 128; ++f) {
      EXPECT_EQ(out[2 * f], out[2 * f + 1]);  // every channel
      all.push_back(out[2 * f]);
    }
  }
  EXPECT_EQ(s.frame(), 16u * 128u);
  for (std::size_t f = 0; f < all.size(); ++f) {
    const float want = (f >= 1000 && f < 1300) ? clip[f - 1000] : 0.0f;
    ASSERT_EQ(all[f], want) << "frame " << f;
  }
  EXPECT_EQ(s.clips_played(), 1u);
  EXPECT_EQ(s.late_clips(), 0u);
  EXPECT_EQ(s.reclaim(), 1u);
}

TEST(PlaybackScheduler, PlanarOverlappingClipsMix) {
  PlaybackScheduler s(48000.0, 4);
  ASSERT_TRUE(s.submit(std::vector<float>(10, 0.25f), 5));
  ASSERT_TRUE(s.submit(std::vector<float>(10, 0.5f), 10));
  std::vector<float> a(32), b(32);
  float* ch[3] = {a.data(), nullptr, b.data()};
  s.render_planar(ch, 32, 3);
  for (std::size_t f = 0; f < 32; ++f) {
    float want = 0.0f;
    if (f >= 5 && f < 15) want += 0.25f;
    if (f >= 10 && f < 20) want += 0.5f;
    EXPECT_FLOAT_EQ(a[f], want) << f;
    EXPECT_FLOAT_EQ(b[f], want) << f;
  }
}

TEST(PlaybackScheduler, LateClipIsCutAndCounted) {
  PlaybackScheduler s(44100.0, 4);
  std::vector<float> out(64);
  s.render_interleaved(out.data(), 64, 1);  // frame is now 64
  const std::vector<float> clip = ramp(100);
  ASSERT_TRUE(s.submit(clip, 50));  // 14 frames already played
  s.render_interleaved(out.data(), 64, 1);
  EXPECT_EQ(out[0], clip[14]);
  EXPECT_EQ(s.late_clips(), 1u);
}

TEST(PlaybackScheduler, SkipAdvancesTheClockAndCountsCutClips) {
  PlaybackScheduler s(44100.0, 4);
  const std::vector<float> clip = ramp(100);
  ASSERT_TRUE(s.submit(clip, 100));
  ASSERT_TRUE(s.submit(ramp(10), 1000));
  std::vector<float> out(128);
  s.render_interleaved(out.data(), 128, 1);  // plays clip frames 0..27
  s.skip(50);                                // an xrun loses clip frames 28..77
  EXPECT_EQ(s.frame(), 178u);
  s.render_interleaved(out.data(), 128, 1);  // frames 178..305: clip frames 78..99
  EXPECT_EQ(out[0], clip[78]);
  EXPECT_EQ(out[21], clip[99]);
  EXPECT_EQ(out[22], 0.0f);
  EXPECT_EQ(s.late_clips(), 1u);
}

TEST(PlaybackScheduler, BoundedPending) {
  PlaybackScheduler s(44100.0, 2);
  EXPECT_TRUE(s.submit(ramp(10), 0));
  EXPECT_TRUE(s.submit(ramp(10), 20));
  EXPECT_FALSE(s.submit(ramp(10), 40));  // full until the RT side finishes one
  std::vector<float> out(16);
  s.render_interleaved(out.data(), 16, 1);  // first clip done
  EXPECT_TRUE(s.submit(ramp(10), 40));     // submit() reclaims first
}

TEST(SchedulerEmitter, RendersSceneFormatSignals) {
  PlaybackScheduler s(44100.0, 4);
  SchedulerEmitter e(s);
  std::string err;
  dsp::SignalSpec spec;
  spec.type = "lfm";
  spec.f0_hz = 18000;
  spec.f1_hz = 22000;
  spec.duration_s = 0.05;
  spec.fade_s = 0.005;
  ASSERT_TRUE(e.schedule(spec, 256, 0.5, &err)) << err;
  const std::vector<float> want = dsp::render_signal(spec, 44100.0);
  std::vector<float> out(256 + want.size() + 64);
  s.render_interleaved(out.data(), static_cast<std::uint32_t>(out.size()), 1);
  for (std::size_t i = 0; i < want.size(); ++i) ASSERT_FLOAT_EQ(out[256 + i], 0.5f * want[i]) << i;
  EXPECT_EQ(out[255], 0.0f);
}

TEST(SchedulerEmitter, RefusesBadRequestsWithReasons) {
  PlaybackScheduler s(44100.0, 4);
  SchedulerEmitter e(s);
  std::string err;
  SignalSpec f0_only;  // an lfm without its duration
  f0_only.type = "lfm";
  f0_only.f0_hz = 18000;
  EXPECT_FALSE(e.schedule(f0_only, 0, 1.0, &err));
  EXPECT_NE(err.find("duration"), std::string::npos) << err;
  EXPECT_FALSE(e.schedule(parse_signal(R"({"type":"ble","address":"AA:BB:CC:DD:EE:FF","tx_power_dbm":-59,"interval_s":0.1})"),
                          0, 1.0, &err));
  EXPECT_NE(err.find("not acoustic"), std::string::npos) << err;
  SignalSpec loud = parse_signal(R"({"type":"lfm","f0":1000,"f1":2000,"duration":0.01})");
  loud.amplitude = 1.5;  // out of 0..1: typed data is checked by the same rules as parsed text
  EXPECT_FALSE(e.schedule(loud, 0, 1.0, &err));
  EXPECT_NE(err.find("amplitude: value 1.5 out of range (expected 0..1)"), std::string::npos) << err;
  const SignalSpec ok = parse_signal(R"({"type":"lfm","f0":1000,"f1":2000,"duration":0.01})");
  EXPECT_FALSE(e.schedule(ok, 0, 2.0, &err));
  std::vector<float> out(64);
  s.render_interleaved(out.data(), 64, 1);
  EXPECT_FALSE(e.schedule(ok, 10, 1.0, &err));
  EXPECT_NE(err.find("already been played"), std::string::npos) << err;
  EXPECT_EQ(e.late_emissions(), 5u);
}

}  // namespace
}  // namespace locus
