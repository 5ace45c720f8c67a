// The playback callback path (PlaybackScheduler::render_* and skip, what an ALSA playback thread or a
// JACK process() runs) takes clips, mixes them, finishes them and hands them back without allocating,
// freeing or locking: clips are allocated by submit() and freed by reclaim() on the main side.
#include <gtest/gtest.h>

#include <vector>

#include "locus/playback.hpp"
#include "rt_hooks.hpp"

namespace locus {
namespace {

using rt_hooks::RtSection;

TEST(RtSafety, PlaybackRenderDoesNotAllocateOrLock) {
  PlaybackScheduler s(44100.0, 16);
  std::vector<float> interleaved(2 * 256), a(256), b(256);
  float* planar[2] = {a.data(), b.data()};
  long allocs = 0, frees = 0, locks = 0;
  for (int round = 0; round < 20; ++round) {
    for (int k = 0; k < 8; ++k) {
      ASSERT_TRUE(s.submit(std::vector<float>(700, 0.1f), s.frame() + 100 + 300 * k));
    }
    RtSection rt;
    for (int i = 0; i < 12; ++i) {
      if (i % 3 == 0) s.render_planar(planar, 256, 2);
      else if (i % 3 == 1) s.render_interleaved(interleaved.data(), 256, 2);
      else s.skip(64);
    }
    rt.end();
    allocs += rt.allocs();
    frees += rt.frees();
    locks += rt.locks();
    s.reclaim();
  }
  EXPECT_GT(s.clips_played(), 0u);
  EXPECT_EQ(allocs, 0);
  EXPECT_EQ(frees, 0);
  EXPECT_EQ(locks, 0);
}

}  // namespace
}  // namespace locus
