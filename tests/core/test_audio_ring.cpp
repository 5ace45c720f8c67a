// Unit tests for locus::AudioRing (core/include/locus/audio_ring.hpp): capacity, zero-copy spans at the
// wrap point, free-running 64-bit counters, overrun accounting (gaps reported at their exact position),
// the bounded gap queue (losses merge, never vanish) and the copying read()/write() helpers.
#include "locus/audio_ring.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

namespace {

using locus::AudioRing;

// Sample value of (stream frame, channel): exact in float for frame < 2^20 and channel < 8.
float value_of(std::uint64_t frame, std::uint32_t ch) {
  return static_cast<float>((frame % (1u << 20)) * 8 + ch);
}

std::vector<float> frames_block(std::uint64_t first_frame, std::size_t frames, std::uint32_t channels) {
  std::vector<float> v(frames * channels);
  for (std::size_t f = 0; f < frames; ++f)
    for (std::uint32_t c = 0; c < channels; ++c) v[f * channels + c] = value_of(first_frame + f, c);
  return v;
}

void fill(const AudioRing::Segment& s, std::uint64_t first_frame, std::uint32_t channels) {
  for (std::size_t f = 0; f < s.frames; ++f)
    for (std::uint32_t c = 0; c < channels; ++c) s.data[f * channels + c] = value_of(first_frame + f, c);
}

// Number of samples in `s` that do not hold value_of(first_frame + f, c).
std::size_t mismatches(const AudioRing::Segment& s, std::uint64_t first_frame, std::uint32_t channels) {
  std::size_t bad = 0;
  for (std::size_t f = 0; f < s.frames; ++f)
    for (std::uint32_t c = 0; c < channels; ++c) bad += s.data[f * channels + c] != value_of(first_frame + f, c);
  return bad;
}

// Writes `frames` frames numbered from `first_frame` through write_acquire/write_commit; returns committed.
std::size_t put(AudioRing& ring, std::uint64_t first_frame, std::size_t frames) {
  auto span = ring.write_acquire(frames);
  fill(span.first, first_frame, ring.channels());
  fill(span.second, first_frame + span.first.frames, ring.channels());
  return ring.write_commit(span.frames());
}

// Reads up to `max` frames, checks their values against their reported stream frame numbers and releases.
AudioRing::ReadSpan take(AudioRing& ring, std::size_t max) {
  auto span = ring.read_acquire(max);
  EXPECT_EQ(mismatches(span.first, span.first_frame, ring.channels()), 0u);
  EXPECT_EQ(mismatches(span.second, span.first_frame + span.first.frames, ring.channels()), 0u);
  ring.read_release(span.frames());
  return span;
}

// ------------------------------------------------------------------ construction

TEST(AudioRing, CapacityIsRoundedUpToAPowerOfTwoOfAtLeastTwoFrames) {
  EXPECT_EQ(AudioRing(2, 0).capacity_frames(), 2u);
  EXPECT_EQ(AudioRing(2, 1).capacity_frames(), 2u);
  EXPECT_EQ(AudioRing(2, 2).capacity_frames(), 2u);
  EXPECT_EQ(AudioRing(2, 3).capacity_frames(), 4u);
  EXPECT_EQ(AudioRing(1, 1000).capacity_frames(), 1024u);
  EXPECT_EQ(AudioRing(3, 1024).capacity_frames(), 1024u);
  EXPECT_EQ(AudioRing(3, 1025).capacity_frames(), 2048u);
  EXPECT_EQ(AudioRing(3, 1025).channels(), 3u);
}

TEST(AudioRing, ZeroChannelsIsRejected) { EXPECT_THROW(AudioRing(0, 16), std::invalid_argument); }

TEST(AudioRing, HoldsExactlyCapacityFrames) {
  AudioRing ring(2, 8);
  EXPECT_EQ(ring.write_acquire(100).frames(), 8u);
  EXPECT_EQ(put(ring, 0, 5), 5u);
  EXPECT_EQ(ring.readable_frames(), 5u);
  EXPECT_EQ(ring.write_acquire(100).frames(), 3u);
  EXPECT_EQ(put(ring, 5, 3), 3u);
  EXPECT_EQ(ring.write_acquire(1).frames(), 0u);  // full
  EXPECT_EQ(ring.readable_frames(), 8u);
  auto span = take(ring, 100);
  EXPECT_EQ(span.frames(), 8u);
  EXPECT_EQ(span.first_frame, 0u);
  EXPECT_EQ(span.lost_before, 0u);
  EXPECT_EQ(ring.readable_frames(), 0u);
  EXPECT_EQ(ring.frames_lost(), 0u);
  EXPECT_EQ(ring.overruns(), 0u);
}

TEST(AudioRing, EmptyRingReadsNothingAndNamesTheNextFrame) {
  AudioRing ring(2, 8, 4, 1000);
  auto span = ring.read_acquire(4);
  EXPECT_EQ(span.frames(), 0u);
  EXPECT_EQ(span.lost_before, 0u);
  EXPECT_EQ(span.first_frame, 1000u);
  EXPECT_EQ(ring.producer_frame(), 1000u);
  EXPECT_EQ(ring.write_commit(0), 0u);
  EXPECT_EQ(ring.producer_frame(), 1000u);
}

// ------------------------------------------------------------------ spans at the wrap point

TEST(AudioRing, SpansSplitIntoTwoSegmentsAtTheWrapPoint) {
  constexpr std::uint32_t kCh = 2;
  AudioRing ring(kCh, 8);
  ASSERT_EQ(put(ring, 0, 6), 6u);
  ASSERT_EQ(take(ring, 6).frames(), 6u);

  auto w = ring.write_acquire(7);
  ASSERT_EQ(w.frames(), 7u);
  EXPECT_EQ(w.first.frames, 2u);   // ring positions 6, 7
  EXPECT_EQ(w.second.frames, 5u);  // ring positions 0..4
  EXPECT_EQ(w.first.data - w.second.data, 6 * kCh);  // second segment starts at the storage base
  fill(w.first, 6, kCh);
  fill(w.second, 8, kCh);
  ASSERT_EQ(ring.write_commit(7), 7u);

  auto r = ring.read_acquire(100);
  EXPECT_EQ(r.frames(), 7u);
  EXPECT_EQ(r.first.frames, 2u);
  EXPECT_EQ(r.second.frames, 5u);
  EXPECT_EQ(r.first.data - r.second.data, 6 * kCh);
  EXPECT_EQ(r.first_frame, 6u);
  EXPECT_EQ(r.lost_before, 0u);
  EXPECT_EQ(mismatches(r.first, 6, kCh), 0u);
  EXPECT_EQ(mismatches(r.second, 8, kCh), 0u);
  ring.read_release(7);
}

TEST(AudioRing, SpanEndingExactlyAtTheWrapPointHasAnEmptySecondSegment) {
  AudioRing ring(1, 8);
  ASSERT_EQ(put(ring, 0, 4), 4u);
  ASSERT_EQ(take(ring, 4).frames(), 4u);
  auto w = ring.write_acquire(4);
  EXPECT_EQ(w.first.frames, 4u);
  EXPECT_EQ(w.second.frames, 0u);
  fill(w.first, 4, 1);
  ASSERT_EQ(ring.write_commit(4), 4u);
  auto r = ring.read_acquire(4);
  EXPECT_EQ(r.first.frames, 4u);
  EXPECT_EQ(r.second.frames, 0u);
  EXPECT_EQ(r.first_frame, 4u);
}

TEST(AudioRing, PartialCommitAndPartialReleasePublishOnlyThePrefix) {
  AudioRing ring(2, 8);
  auto w = ring.write_acquire(6);
  ASSERT_EQ(w.frames(), 6u);
  fill(w.first, 0, 2);
  ASSERT_EQ(ring.write_commit(4), 4u);  // frames 4 and 5 are not published
  EXPECT_EQ(ring.readable_frames(), 4u);
  EXPECT_EQ(ring.producer_frame(), 4u);
  auto r = ring.read_acquire(8);
  EXPECT_EQ(r.frames(), 4u);
  ring.read_release(1);  // only frame 0 consumed
  r = ring.read_acquire(8);
  EXPECT_EQ(r.first_frame, 1u);
  EXPECT_EQ(r.frames(), 3u);
  EXPECT_EQ(r.first.data[0], value_of(1, 0));
  ring.read_release(3);
  EXPECT_EQ(ring.write_acquire(100).frames(), 8u);
}

// ------------------------------------------------------------------ free-running counters

class AudioRingStartFrame : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(AudioRingStartFrame, StreamFrameNumbersStayExactOverManyWraps) {
  const std::uint64_t start = GetParam();
  constexpr std::uint32_t kCh = 3;
  AudioRing ring(kCh, 16, 8, start);
  std::mt19937 rng(42);
  std::uint64_t produced = start, consumed = start;
  for (int i = 0; i < 5000; ++i) {
    const std::size_t n = rng() % 17;
    produced += put(ring, produced, n);
    EXPECT_EQ(ring.producer_frame(), produced);
    auto r = take(ring, rng() % 17);
    if (r.frames() > 0 || r.lost_before > 0) {
      ASSERT_EQ(r.first_frame, consumed);
      ASSERT_EQ(r.lost_before, 0u);
    }
    consumed += r.frames();
  }
  consumed += take(ring, 16).frames();
  EXPECT_EQ(consumed, produced);
  EXPECT_GT(produced - start, 16u * 1000);  // wrapped the ring many times
}

INSTANTIATE_TEST_SUITE_P(Starts, AudioRingStartFrame,
                         ::testing::Values(0ull, 48000ull * 3600 * 24 * 365, (1ull << 32) - 5, (1ull << 63) - 7,
                                           (1ull << 63) + 1, std::numeric_limits<std::uint64_t>::max() - 100));

TEST(AudioRing, LossNearTwoToTheSixtyThreeIsReportedExactly) {
  const std::uint64_t start = (1ull << 63) - 3;
  AudioRing ring(2, 8, 4, start);
  ASSERT_EQ(put(ring, start, 2), 2u);
  ring.write_lost(5);  // crosses 2^63
  ASSERT_EQ(put(ring, start + 7, 3), 3u);
  EXPECT_EQ(ring.producer_frame(), start + 10);
  auto a = take(ring, 100);
  EXPECT_EQ(a.first_frame, start);
  EXPECT_EQ(a.frames(), 2u);
  auto b = take(ring, 100);
  EXPECT_EQ(b.lost_before, 5u);
  EXPECT_EQ(b.first_frame, (1ull << 63) + 4);
  EXPECT_EQ(b.frames(), 3u);
}

// ------------------------------------------------------------------ overruns and gaps

TEST(AudioRing, WriteLostIsCountedAndReportedAtItsExactPosition) {
  AudioRing ring(2, 64);
  ASSERT_EQ(put(ring, 0, 4), 4u);
  ring.write_lost(3);  // frames 4..6
  EXPECT_EQ(ring.producer_frame(), 7u);
  ASSERT_EQ(put(ring, 7, 5), 5u);
  EXPECT_EQ(ring.frames_lost(), 3u);
  EXPECT_EQ(ring.overruns(), 1u);
  EXPECT_EQ(ring.readable_frames(), 9u);

  auto a = take(ring, 100);  // stops right before the gap although 9 frames are readable
  EXPECT_EQ(a.frames(), 4u);
  EXPECT_EQ(a.first_frame, 0u);
  EXPECT_EQ(a.lost_before, 0u);
  auto b = take(ring, 100);
  EXPECT_EQ(b.frames(), 5u);
  EXPECT_EQ(b.first_frame, 7u);
  EXPECT_EQ(b.lost_before, 3u);
  auto c = take(ring, 100);
  EXPECT_EQ(c.frames(), 0u);
  EXPECT_EQ(c.lost_before, 0u);  // reported once only
  EXPECT_EQ(c.first_frame, 12u);
}

TEST(AudioRing, SmallReadsApproachTheGapWithoutCrossingIt) {
  AudioRing ring(1, 64);
  ASSERT_EQ(put(ring, 0, 10), 10u);
  ring.write_lost(6);
  ASSERT_EQ(put(ring, 16, 10), 10u);
  std::uint64_t next = 0, lost = 0;
  while (next < 26) {
    auto s = take(ring, 3);
    ASSERT_GT(s.frames(), 0u);
    if (s.first_frame < 10) {
      EXPECT_LE(s.first_frame + s.frames(), 10u) << "span straddles the gap";
    }
    if (s.lost_before) {
      EXPECT_EQ(s.first_frame, 16u);
      EXPECT_EQ(next, 10u);
    }
    lost += s.lost_before;
    next = s.first_frame + s.frames();
  }
  EXPECT_EQ(lost, 6u);
  EXPECT_EQ(next, 26u);
}

TEST(AudioRing, LossAfterTheConsumerCaughtUpGivesAnEmptySpanWithLostBefore) {
  AudioRing ring(2, 8);
  ASSERT_EQ(put(ring, 0, 4), 4u);
  ASSERT_EQ(take(ring, 8).frames(), 4u);
  ring.write_lost(3);
  auto s = take(ring, 8);
  EXPECT_EQ(s.frames(), 0u);
  EXPECT_EQ(s.lost_before, 3u);
  EXPECT_EQ(s.first_frame, 7u);
  ASSERT_EQ(put(ring, 7, 2), 2u);
  s = take(ring, 8);
  EXPECT_EQ(s.frames(), 2u);
  EXPECT_EQ(s.lost_before, 0u);
  EXPECT_EQ(s.first_frame, 7u);
}

TEST(AudioRing, LossesAtTheSamePositionAreSummed) {
  AudioRing ring(2, 16);
  ASSERT_EQ(put(ring, 0, 2), 2u);
  ring.write_lost(2);
  ring.write_lost(3);
  ring.write_lost(1);
  ASSERT_EQ(put(ring, 8, 2), 2u);
  EXPECT_EQ(ring.frames_lost(), 6u);
  EXPECT_EQ(ring.overruns(), 3u);
  EXPECT_EQ(take(ring, 16).frames(), 2u);
  auto s = take(ring, 16);
  EXPECT_EQ(s.lost_before, 6u);
  EXPECT_EQ(s.first_frame, 8u);
  EXPECT_EQ(s.frames(), 2u);
}

TEST(AudioRing, ManyConsecutiveGapsAreEachReportedWhereTheyHappened) {
  AudioRing ring(2, 4096, 64);
  std::uint64_t frame = 0;
  std::uint64_t total_lost = 0;
  for (std::size_t k = 1; k <= 60; ++k) {  // k frames kept, then k+1 lost
    ASSERT_EQ(put(ring, frame, k), k);
    frame += k;
    ring.write_lost(k + 1);
    frame += k + 1;
    total_lost += k + 1;
  }
  ASSERT_EQ(put(ring, frame, 1), 1u);  // a frame after the last gap
  EXPECT_EQ(ring.frames_lost(), total_lost);
  EXPECT_EQ(ring.overruns(), 60u);

  std::uint64_t expect = 0;
  for (std::size_t k = 1; k <= 60; ++k) {
    auto s = take(ring, 4096);
    EXPECT_EQ(s.first_frame, expect);
    EXPECT_EQ(s.frames(), k);
    EXPECT_EQ(s.lost_before, k == 1 ? 0u : k);  // the gap before block k had k frames
    expect += k + (k + 1);
  }
  auto last = take(ring, 4096);
  EXPECT_EQ(last.lost_before, 61u);
  EXPECT_EQ(last.first_frame, expect);
  EXPECT_EQ(last.frames(), 1u);
}

TEST(AudioRing, PartialWriteReportsTheRestLost) {
  constexpr std::uint32_t kCh = 2;
  AudioRing ring(kCh, 8);
  auto in = frames_block(0, 12, kCh);
  EXPECT_EQ(ring.write(in.data(), 12), 8u);
  EXPECT_EQ(ring.frames_lost(), 4u);
  EXPECT_EQ(ring.overruns(), 1u);
  EXPECT_EQ(ring.producer_frame(), 12u);
  EXPECT_EQ(ring.write(in.data(), 3), 0u);  // still full: everything lost, one more overrun
  EXPECT_EQ(ring.frames_lost(), 7u);
  EXPECT_EQ(ring.overruns(), 2u);

  std::vector<float> out(8 * kCh);
  std::uint64_t first = 99, lost = 99;
  EXPECT_EQ(ring.read(out.data(), 8, &first, &lost), 8u);
  EXPECT_EQ(first, 0u);
  EXPECT_EQ(lost, 0u);
  EXPECT_EQ(std::vector<float>(in.begin(), in.begin() + 8 * kCh), out);

  auto more = frames_block(15, 2, kCh);
  EXPECT_EQ(ring.write(more.data(), 2), 2u);
  EXPECT_EQ(ring.read(out.data(), 8, &first, &lost), 2u);
  EXPECT_EQ(first, 15u);
  EXPECT_EQ(lost, 7u);
  EXPECT_EQ(out[0], value_of(15, 0));
  EXPECT_EQ(out[3], value_of(16, 1));
}

// With room for only two pending gaps, further losses merge into one pending loss; commits are refused
// (and become losses) until the pending loss can be queued. Nothing vanishes and positions stay exact.
TEST(AudioRing, FullGapQueueMergesLossesAndRefusesCommits) {
  AudioRing ring(1, 64, 2);  // max_pending_gaps = 2
  ASSERT_EQ(put(ring, 0, 1), 1u);  // frame 0
  ring.write_lost(1);              // frame 1 -> gap A
  ASSERT_EQ(put(ring, 2, 1), 1u);  // frame 2
  ring.write_lost(1);              // frame 3 -> gap B (queue now full)
  ASSERT_EQ(put(ring, 4, 1), 1u);  // frame 4
  ring.write_lost(1);              // frame 5 -> pending (queue full)
  EXPECT_EQ(put(ring, 6, 1), 0u);  // frame 6: commit refused, becomes a loss
  ring.write_lost(2);              // frames 7, 8 -> merged into the pending loss
  EXPECT_EQ(ring.producer_frame(), 9u);
  EXPECT_EQ(ring.frames_lost(), 6u);  // frames 1, 3, 5, 6, 7, 8
  EXPECT_EQ(ring.overruns(), 5u);     // four write_lost calls + the refused commit
  EXPECT_EQ(ring.readable_frames(), 3u);

  auto s = take(ring, 64);
  EXPECT_EQ(s.first_frame, 0u);
  EXPECT_EQ(s.frames(), 1u);
  EXPECT_EQ(s.lost_before, 0u);
  s = take(ring, 64);
  EXPECT_EQ(s.first_frame, 2u);
  EXPECT_EQ(s.frames(), 1u);
  EXPECT_EQ(s.lost_before, 1u);
  // The consumer has taken the gaps off the queue: the next commit first records the merged loss.
  EXPECT_EQ(put(ring, 9, 2), 2u);  // frames 9, 10
  s = take(ring, 64);
  EXPECT_EQ(s.first_frame, 4u);
  EXPECT_EQ(s.frames(), 1u);
  EXPECT_EQ(s.lost_before, 1u);
  s = take(ring, 64);
  EXPECT_EQ(s.first_frame, 9u);
  EXPECT_EQ(s.frames(), 2u);
  EXPECT_EQ(s.lost_before, 4u);  // frames 5..8 merged into one gap at their exact position
  EXPECT_EQ(ring.frames_lost(), 6u);
}

TEST(AudioRing, WriteWhileGapQueueIsFullLosesEverythingAndCountsIt) {
  constexpr std::uint32_t kCh = 2;
  AudioRing ring(kCh, 64, 2);
  auto in = frames_block(0, 64, kCh);
  std::uint64_t frame = 0;
  for (int i = 0; i < 3; ++i) {  // three losses, only two fit in the gap queue
    ASSERT_EQ(ring.write(in.data() + frame * kCh, 1), 1u);
    ++frame;
    ring.write_lost(1);
    ++frame;
  }
  EXPECT_EQ(ring.write(in.data() + frame * kCh, 4), 0u);  // refused commit: 4 more frames lost
  frame += 4;
  EXPECT_EQ(ring.frames_lost(), 7u);
  EXPECT_EQ(ring.producer_frame(), frame);

  std::uint64_t received = 0, lost = 0, next = 0;
  std::vector<float> out(64 * kCh);
  for (int i = 0; i < 10; ++i) {
    std::uint64_t first = 0, lb = 0;
    const std::size_t n = ring.read(out.data(), 64, &first, &lb);
    if (n == 0 && lb == 0) {
      // Nothing readable: let the producer record its pending loss by committing the next frames.
      if (frame < 12 && ring.write(in.data() + frame * kCh, 2) == 2) frame += 2;
      continue;
    }
    EXPECT_EQ(first, next + lb);
    for (std::size_t f = 0; f < n; ++f) EXPECT_EQ(out[f * kCh + 1], value_of(first + f, 1));
    received += n;
    lost += lb;
    next = first + n;
  }
  EXPECT_EQ(next, frame);
  EXPECT_EQ(lost, ring.frames_lost());
  EXPECT_EQ(received + lost, frame);
}

// ------------------------------------------------------------------ copying helpers

TEST(AudioRing, WriteAndReadCopyInterleavedFramesAcrossTheWrap) {
  constexpr std::uint32_t kCh = 3;
  AudioRing ring(kCh, 16, 4, 500);
  std::mt19937 rng(7);
  std::uint64_t wframe = 500, rframe = 500;
  std::vector<float> out(16 * kCh);
  for (int i = 0; i < 2000; ++i) {
    const std::size_t n = rng() % 10;
    if (ring.readable_frames() + n <= 16) {
      auto in = frames_block(wframe, n, kCh);
      ASSERT_EQ(ring.write(in.data(), n), n);
      wframe += n;
    }
    std::uint64_t first = 0;
    const std::size_t got = ring.read(out.data(), rng() % 10, &first);
    if (got == 0) continue;
    ASSERT_EQ(first, rframe);
    for (std::size_t f = 0; f < got; ++f)
      for (std::uint32_t c = 0; c < kCh; ++c) ASSERT_EQ(out[f * kCh + c], value_of(rframe + f, c));
    rframe += got;
  }
  EXPECT_EQ(ring.frames_lost(), 0u);
  EXPECT_EQ(ring.read(out.data(), 16), wframe - rframe);  // null first_frame/lost_before are fine
}

// ------------------------------------------------------------------ two threads (short; see tests/stress)

TEST(AudioRing, TwoThreadsLiveProducerAccountsForEveryFrame) {
  constexpr std::uint32_t kCh = 2;
  constexpr std::uint64_t kFrames = 300000;
  AudioRing ring(kCh, 256, 4);
  std::atomic<bool> done{false};
  std::thread producer([&] {
    std::mt19937 rng(1);
    std::uint64_t frame = 0;
    while (frame < kFrames) {
      const std::size_t n = std::min<std::uint64_t>(1 + rng() % 100, kFrames - frame);
      auto span = ring.write_acquire(n);
      fill(span.first, frame, kCh);
      fill(span.second, frame + span.first.frames, kCh);
      ring.write_commit(span.frames());  // a refused commit reports its own frames lost
      ring.write_lost(n - span.frames());
      frame += n;
      if (rng() % 8 == 0) std::this_thread::yield();
    }
    // Keep committing nothing until the consumer has seen the end: flushes a loss still pending.
    while (!done.load()) {
      ring.write_commit(0);
      std::this_thread::yield();
    }
  });
  std::uint64_t received = 0, lost = 0, next = 0, bad = 0, misplaced = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (next < kFrames && std::chrono::steady_clock::now() < deadline) {
    auto s = ring.read_acquire(1 + received % 97);
    if (s.frames() == 0 && s.lost_before == 0) {
      std::this_thread::yield();
      continue;
    }
    misplaced += s.first_frame != next + s.lost_before;
    bad += mismatches(s.first, s.first_frame, kCh) + mismatches(s.second, s.first_frame + s.first.frames, kCh);
    ring.read_release(s.frames());
    received += s.frames();
    lost += s.lost_before;
    next = s.first_frame + s.frames();
  }
  done = true;
  producer.join();
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(misplaced, 0u);
  EXPECT_EQ(next, kFrames);
  EXPECT_EQ(received + lost, kFrames);
  EXPECT_EQ(lost, ring.frames_lost());
}

}  // namespace

namespace locus {
namespace {

TEST(AudioRingFrameApi, PushPopFramesKeepValuesOrderAndStreamNumbers) {
  AudioRing ring(3, 8, 4, 1000);
  float f[3];
  std::uint64_t frame = 0, lost = 0;
  EXPECT_FALSE(ring.try_pop_frame(f, &frame, &lost));
  for (int i = 0; i < 8; ++i) {
    const float in[3] = {float(i), float(i) + 0.5f, -float(i)};
    ASSERT_TRUE(ring.try_push_frame(in));
  }
  const float extra[3] = {9, 9, 9};
  EXPECT_FALSE(ring.try_push_frame(extra));  // full: nothing stored
  ring.write_lost(1);                        // a live producer reports it
  for (int i = 0; i < 8; ++i) {
    ASSERT_TRUE(ring.try_pop_frame(f, &frame, &lost));
    EXPECT_EQ(f[0], float(i));
    EXPECT_EQ(f[1], float(i) + 0.5f);
    EXPECT_EQ(f[2], -float(i));
    EXPECT_EQ(frame, 1000u + i);
    EXPECT_EQ(lost, 0u);
  }
  const float next[3] = {42, 43, 44};
  ASSERT_TRUE(ring.try_push_frame(next));  // goes through the pending-loss path
  ASSERT_TRUE(ring.try_pop_frame(f, &frame, &lost));
  EXPECT_EQ(f[0], 42.0f);
  EXPECT_EQ(frame, 1009u);  // frame 1008 was lost
  EXPECT_EQ(lost, 1u);
  EXPECT_FALSE(ring.try_pop_frame(f, &frame, &lost));
}

TEST(AudioRingFrameApi, FramePopSeesAGapQueuedAfterItsLastRefresh) {
  AudioRing ring(1, 16);
  float x = 1;
  ASSERT_TRUE(ring.try_push_frame(&x));
  float y;
  std::uint64_t frame = 0, lost = 0;
  ASSERT_TRUE(ring.try_pop_frame(&y, &frame, &lost));
  ring.write_lost(5);  // loss at the position the consumer has reached
  x = 2;
  ASSERT_TRUE(ring.try_push_frame(&x));
  ASSERT_TRUE(ring.try_pop_frame(&y, &frame, &lost));
  EXPECT_EQ(y, 2.0f);
  EXPECT_EQ(frame, 6u);
  EXPECT_EQ(lost, 5u);
}

}  // namespace
}  // namespace locus
