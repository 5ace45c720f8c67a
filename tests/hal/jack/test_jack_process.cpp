// JackProcessor, the JACK process-callback body, driven directly with plain buffers and synthetic
// server frame times / monotonic times (no server): exact capture into the ring, exact counts of
// frames lost to skipped cycles (including the 32-bit frame-time wrap), the outage gap estimated from
// the monotonic clock, playback rendered at the scheduled frame on the same clock as capture, late
// attachment aligned to the client's counter, and detach guaranteeing no further access.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "jack/jack_process.hpp"
#include "locus/audio_ring.hpp"
#include "locus/playback.hpp"

namespace locus::hal::jack {
namespace {

constexpr double kRate = 44100.0;
constexpr std::uint32_t kPeriod = 256;

// A fake server: N input port buffers filled with a per-(channel, server frame) value, M outputs.
struct FakeCycle {
  std::uint32_t n_in, n_out;
  std::vector<std::vector<float>> in, out;
  std::vector<const float*> in_ptrs;
  std::vector<float*> out_ptrs;
  FakeCycle(std::uint32_t ni, std::uint32_t no, std::uint32_t frames = kPeriod)
      : n_in(ni), n_out(no), in(ni, std::vector<float>(frames)), out(no, std::vector<float>(frames, 99.0f)) {
    for (auto& v : in) in_ptrs.push_back(v.data());
    for (auto& v : out) out_ptrs.push_back(v.data());
  }
  static float value(std::uint32_t c, std::uint64_t server_frame) {
    return static_cast<float>(c + 1) * 1000.0f + static_cast<float>(server_frame % 4093) * 0.125f;
  }
  void run(JackProcessor& p, std::uint32_t frame_time, std::int64_t now_ns, std::uint32_t frames = kPeriod) {
    for (std::uint32_t c = 0; c < n_in; ++c)
      for (std::uint32_t i = 0; i < frames; ++i) in[c][i] = value(c, static_cast<std::uint32_t>(frame_time + i));
    p.begin_cycle();
    p.process(in_ptrs.data(), n_in, out_ptrs.data(), n_out, frames, frame_time, now_ns);
    p.end_cycle();
  }
};

std::int64_t ns_of_frame(std::uint64_t f) { return static_cast<std::int64_t>(static_cast<double>(f) / kRate * 1e9); }

struct Read {
  std::vector<float> data;
  std::uint64_t first_frame = 0, lost_before = 0;
  std::size_t frames = 0;
};
Read read_all(AudioRing& ring, std::size_t max = 1 << 16) {
  Read r;
  r.data.resize(max * ring.channels());
  r.frames = ring.read(r.data.data(), max, &r.first_frame, &r.lost_before);
  r.data.resize(r.frames * ring.channels());
  return r;
}

TEST(JackProcessor, CaptureInterleavesEveryPortExactly) {
  JackProcessor p(kRate);
  AudioRing ring(2, 1 << 14);
  p.attach_capture(&ring);
  FakeCycle cyc(2, 0);
  const std::uint32_t ft0 = 123456;
  for (std::uint32_t k = 0; k < 8; ++k) cyc.run(p, ft0 + k * kPeriod, ns_of_frame(k * kPeriod));
  Read r = read_all(ring);
  ASSERT_EQ(r.frames, 8u * kPeriod);
  EXPECT_EQ(r.first_frame, 0u);
  EXPECT_EQ(r.lost_before, 0u);
  for (std::size_t i = 0; i < r.frames; ++i)
    for (std::uint32_t c = 0; c < 2; ++c) ASSERT_EQ(r.data[i * 2 + c], FakeCycle::value(c, ft0 + i)) << i << "," << c;
  EXPECT_EQ(p.frame(), 8u * kPeriod);
  EXPECT_EQ(p.frames_lost(), 0u);
  EXPECT_EQ(p.cycles(), 8u);
  EXPECT_EQ(p.anchor_frame(), 0u);
  EXPECT_EQ(p.anchor_frame_time(), ft0);
}

TEST(JackProcessor, SkippedCyclesAreReportedAsExactGapsInRingAndScheduler) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1 << 14);
  PlaybackScheduler sched(kRate);
  p.attach_capture(&ring);
  p.attach_playback(&sched);
  FakeCycle cyc(1, 1);
  cyc.run(p, 1000, 0);
  cyc.run(p, 1000 + kPeriod, 1);
  cyc.run(p, 1000 + 4 * kPeriod, 2);  // two cycles (512 frames) skipped
  cyc.run(p, 1000 + 5 * kPeriod, 3);
  EXPECT_EQ(p.frames_lost(), 2u * kPeriod);
  EXPECT_EQ(p.skip_events(), 1u);
  EXPECT_EQ(p.frame(), 6u * kPeriod);
  EXPECT_EQ(sched.frame(), 6u * kPeriod) << "playback counter skips with capture";
  EXPECT_EQ(ring.frames_lost(), 2u * kPeriod);
  Read a = read_all(ring);
  ASSERT_EQ(a.frames, 2u * kPeriod);
  EXPECT_EQ(a.first_frame, 0u);
  Read b = read_all(ring);
  ASSERT_EQ(b.frames, 2u * kPeriod);
  EXPECT_EQ(b.lost_before, 2u * kPeriod);
  EXPECT_EQ(b.first_frame, 4u * kPeriod) << "stream frame numbers stay true to the server clock";
  EXPECT_EQ(b.data[0], FakeCycle::value(0, 1000 + 4 * kPeriod));
}

TEST(JackProcessor, FrameTimeWrapAroundIsContiguousAndGapsAcrossItAreExact) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1 << 14);
  p.attach_capture(&ring);
  FakeCycle cyc(1, 0);
  const std::uint32_t near_wrap = 0xFFFFFFFFu - kPeriod + 1;  // the next cycle starts at 0
  cyc.run(p, near_wrap - kPeriod, 0);
  cyc.run(p, near_wrap, 1);
  cyc.run(p, 0, 2);
  EXPECT_EQ(p.frames_lost(), 0u);
  cyc.run(p, 3 * kPeriod, 3);  // 2 periods skipped just after the wrap
  EXPECT_EQ(p.frames_lost(), 2u * kPeriod);
  EXPECT_EQ(p.frame(), 6u * kPeriod);
}

TEST(JackProcessor, ServerClockGoingBackwardsIsNotALoss) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1 << 14);
  p.attach_capture(&ring);
  FakeCycle cyc(1, 0);
  cyc.run(p, 50000, 0);
  cyc.run(p, 100, 1);
  EXPECT_EQ(p.frames_lost(), 0u);
  EXPECT_EQ(ring.frames_lost(), 0u);
  EXPECT_EQ(p.frame(), 2u * kPeriod);
}

TEST(JackProcessor, OutageGapIsEstimatedFromTheMonotonicClockAndTheCounterContinues) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1 << 18);
  PlaybackScheduler sched(kRate);
  p.attach_capture(&ring);
  p.attach_playback(&sched);
  FakeCycle cyc(1, 1);
  const std::int64_t t0 = 5'000'000'000;
  for (std::uint32_t k = 0; k < 4; ++k) cyc.run(p, 7000 + k * kPeriod, t0 + ns_of_frame(k * kPeriod));
  const std::int64_t last = t0 + ns_of_frame(3 * kPeriod);
  // The server goes away and a new one (frame time restarting near 0) runs 2.5 s later.
  p.mark_reconnected();
  const std::int64_t back = last + 2'500'000'000;
  cyc.run(p, 512, back);
  const std::uint64_t expected = static_cast<std::uint64_t>(std::llround(2.5 * kRate)) - kPeriod;
  EXPECT_EQ(p.resumes(), 1u);
  EXPECT_EQ(p.last_resume_gap_frames(), expected);
  EXPECT_EQ(p.frames_lost(), expected);
  EXPECT_EQ(p.skip_events(), 0u) << "an outage is not a skipped cycle";
  EXPECT_EQ(p.frame(), 5u * kPeriod + expected);
  EXPECT_EQ(sched.frame(), p.frame());
  EXPECT_EQ(p.anchor_frame(), 4u * kPeriod + expected) << "the new server's clock meets the stream here";
  EXPECT_EQ(p.anchor_frame_time(), 512u);
  cyc.run(p, 512 + kPeriod, back + ns_of_frame(kPeriod));  // contiguous on the new clock
  EXPECT_EQ(p.frames_lost(), expected);
  Read a = read_all(ring);
  EXPECT_EQ(a.frames, 4u * kPeriod);
  Read b = read_all(ring);
  EXPECT_EQ(b.lost_before, expected);
  EXPECT_EQ(b.first_frame, 4u * kPeriod + expected);
  EXPECT_EQ(b.frames, 2u * kPeriod);
  EXPECT_EQ(b.data[0], FakeCycle::value(0, 512));
}

TEST(JackProcessor, ReconnectFasterThanAPeriodLosesNothing) {
  JackProcessor p(kRate);
  FakeCycle cyc(0, 0);
  cyc.run(p, 0, 1'000'000'000);
  p.mark_reconnected();
  cyc.run(p, 0, 1'000'000'000 + ns_of_frame(kPeriod));  // exactly one period later: contiguous
  EXPECT_EQ(p.frames_lost(), 0u);
  EXPECT_EQ(p.resumes(), 1u);
}

TEST(JackProcessor, PlaybackRendersAClipAtItsScheduledFrameOnTheCaptureClock) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1 << 14);
  PlaybackScheduler sched(kRate);
  p.attach_capture(&ring);
  p.attach_playback(&sched);
  std::vector<float> clip(300);
  for (std::size_t i = 0; i < clip.size(); ++i) clip[i] = 0.001f * static_cast<float>(i + 1);
  const std::uint64_t start = 700;
  ASSERT_TRUE(sched.submit(clip, start));
  FakeCycle cyc(1, 2);
  std::vector<std::vector<float>> played(2);
  for (std::uint32_t k = 0; k < 6; ++k) {
    cyc.run(p, k * kPeriod, ns_of_frame(k * kPeriod));
    for (int c = 0; c < 2; ++c) played[c].insert(played[c].end(), cyc.out[c].begin(), cyc.out[c].end());
  }
  for (int c = 0; c < 2; ++c) {
    for (std::size_t f = 0; f < played[c].size(); ++f) {
      const float want = (f >= start && f < start + clip.size()) ? clip[f - start] : 0.0f;
      ASSERT_EQ(played[c][f], want) << "channel " << c << " frame " << f;
    }
  }
  EXPECT_EQ(sched.frame(), p.frame());
  EXPECT_EQ(ring.producer_frame(), p.frame());
}

TEST(JackProcessor, AClipSpanningSkippedCyclesContinuesAtTheRightSample) {
  JackProcessor p(kRate);
  PlaybackScheduler sched(kRate);
  p.attach_playback(&sched);
  std::vector<float> clip(1500);
  for (std::size_t i = 0; i < clip.size(); ++i) clip[i] = 0.0005f * static_cast<float>(i + 1);
  ASSERT_TRUE(sched.submit(clip, 300));
  FakeCycle cyc(0, 1);
  cyc.run(p, 0, 0);
  cyc.run(p, kPeriod, 1);
  cyc.run(p, 4 * kPeriod, 2);  // frames 512..1023 lost
  // Stream frame 1024 is clip sample 724.
  EXPECT_EQ(cyc.out[0][0], clip[1024 - 300]);
  EXPECT_GE(sched.late_clips(), 1u);
}

TEST(JackProcessor, APartAttachedLateIsAlignedToTheClientCounter) {
  JackProcessor p(kRate);
  FakeCycle cyc(1, 1);
  for (std::uint32_t k = 0; k < 10; ++k) cyc.run(p, k * kPeriod, ns_of_frame(k * kPeriod));
  for (float v : cyc.out[0]) ASSERT_EQ(v, 0.0f) << "no scheduler: silence";
  AudioRing ring(1, 1 << 14);
  PlaybackScheduler sched(kRate);
  p.attach_capture(&ring);
  p.attach_playback(&sched);
  cyc.run(p, 10 * kPeriod, ns_of_frame(10 * kPeriod));
  EXPECT_EQ(sched.frame(), 11u * kPeriod);
  Read r = read_all(ring);
  EXPECT_EQ(r.lost_before, 10u * kPeriod);
  EXPECT_EQ(r.first_frame, 10u * kPeriod);
  EXPECT_EQ(r.frames, kPeriod);
  EXPECT_EQ(p.frames_lost(), 0u) << "the client itself lost nothing";
}

TEST(JackProcessor, DetachEndsAllAccessAndMissingPortsReadAsSilence) {
  JackProcessor p(kRate);
  AudioRing ring(3, 1 << 14);
  PlaybackScheduler sched(kRate);
  p.attach_capture(&ring);
  p.attach_playback(&sched);
  FakeCycle cyc(2, 1);  // 2 ports for a 3-channel ring: the third reads as silence
  cyc.run(p, 0, 0);
  p.detach_capture();
  p.detach_playback();
  const std::uint64_t sched_frame = sched.frame();
  for (std::uint32_t k = 1; k < 4; ++k) cyc.run(p, k * kPeriod, k);
  EXPECT_EQ(ring.producer_frame(), kPeriod);
  EXPECT_EQ(sched.frame(), sched_frame);
  for (float v : cyc.out[0]) ASSERT_EQ(v, 0.0f);
  Read r = read_all(ring);
  ASSERT_EQ(r.frames, kPeriod);
  for (std::size_t i = 0; i < r.frames; ++i) {
    ASSERT_EQ(r.data[i * 3 + 0], FakeCycle::value(0, i));
    ASSERT_EQ(r.data[i * 3 + 1], FakeCycle::value(1, i));
    ASSERT_EQ(r.data[i * 3 + 2], 0.0f);
  }
}

TEST(JackProcessor, AFullRingReportsTheOverflowAndKeepsFrameNumbersTrue) {
  JackProcessor p(kRate);
  AudioRing ring(1, 1024);  // room for 4 periods
  p.attach_capture(&ring);
  FakeCycle cyc(1, 0);
  for (std::uint32_t k = 0; k < 6; ++k) cyc.run(p, k * kPeriod, k);
  EXPECT_EQ(ring.frames_lost(), 2u * kPeriod);
  EXPECT_EQ(p.frames_lost(), 0u) << "an overrun of the consumer is the ring's loss, not the client's";
  Read a = read_all(ring);
  EXPECT_EQ(a.frames, 4u * kPeriod);
  cyc.run(p, 6 * kPeriod, 6);
  Read b = read_all(ring);
  EXPECT_EQ(b.lost_before, 2u * kPeriod);
  EXPECT_EQ(b.first_frame, 6u * kPeriod);
  EXPECT_EQ(b.data[0], FakeCycle::value(0, 6 * kPeriod));
}

}  // namespace
}  // namespace locus::hal::jack
