// Real-time safety of the JACK process callback body (hal/jack JackProcessor, what the libjack callback
// runs between fetching the port buffers and returning): capture into the ring (including a full ring),
// playback rendering with a clip playing, skipped cycles (write_lost + skip), an outage resume (gap from
// the monotonic clock) and a late-attached part must not allocate, free or lock after warm-up.
#include <gtest/gtest.h>

#include <cstdint>
#include <ctime>
#include <vector>

#include "jack/jack_process.hpp"
#include "locus/audio_ring.hpp"
#include "locus/playback.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus {
namespace {

std::int64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

TEST(RtSafety, JackProcessCallbackDoesNotAllocateOrLock) {
  constexpr std::uint32_t kPeriod = 256, kIn = 4, kOut = 2;
  hal::jack::JackProcessor proc(44100.0);
  AudioRing ring(kIn, 4096, 8);
  PlaybackScheduler sched(44100.0, 16);
  std::vector<std::vector<float>> in(kIn, std::vector<float>(kPeriod, 0.25f)), out(kOut, std::vector<float>(kPeriod));
  std::vector<const float*> in_ptrs;
  std::vector<float*> out_ptrs;
  for (auto& v : in) in_ptrs.push_back(v.data());
  for (auto& v : out) out_ptrs.push_back(v.data());
  std::vector<float> drain(4096 * kIn);
  std::uint32_t ft = 1000;
  auto cycle = [&](std::uint32_t skip_periods = 0) {
    ft += skip_periods * kPeriod;
    proc.begin_cycle();
    proc.process(in_ptrs.data(), kIn, out_ptrs.data(), kOut, kPeriod, ft, mono_ns());
    proc.end_cycle();
    ft += kPeriod;
  };
  // Warm-up (the scheduler's first render, the ring's first wrap), then clips queued on the main side.
  proc.attach_capture(&ring);
  for (int i = 0; i < 20; ++i) cycle();
  ring.read(drain.data(), 4096);
  for (int i = 0; i < 8; ++i) ASSERT_TRUE(sched.submit(std::vector<float>(3000, 0.5f), proc.frame() + 1000 + 5000 * i));

  RtSection rt;
  proc.attach_playback(&sched);  // late attach: aligned by skip() inside the cycle
  for (int i = 0; i < 400; ++i) {
    cycle(i % 37 == 5 ? 2 : 0);              // skipped cycles now and then
    if (i == 200) proc.mark_reconnected();   // an outage resume
    if (i % 30 == 0) ring.read(drain.data(), 4096);  // the consumer is slow: the ring overflows too
  }
  rt.end();
  EXPECT_GT(proc.frames_lost(), 0u);
  EXPECT_GT(ring.overruns(), 0u);
  EXPECT_GT(sched.clips_played(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

}  // namespace
}  // namespace locus
