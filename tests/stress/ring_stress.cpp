// Two-thread stress test of locus::AudioRing (core/include/locus/audio_ring.hpp).
//
// Phase 1 ("blocking"): a producer and a consumer thread move N frames through the ring with random block
// sizes on both sides, mixing the zero-copy span API and the copying read()/write() helpers. Every sample
// encodes its stream frame number and channel; the consumer checks every sample and the order, and that no
// loss is ever reported. Runs for stereo and for 3 channels (the latter from a start frame beyond 2^62).
//
// Phase 2 ("live"): the producer never waits; what does not fit is reported with write_lost (or lost by
// write()). The consumer stalls now and then to force overruns. It checks that first_frame/lost_before
// account for every frame exactly: first_frame == previous end + lost_before, received + lost == produced,
// lost == frames_lost(), and sample values still match their frame numbers after every gap. Run with a
// tiny gap queue too, so losses merge and commits get refused.
//
// Frames per phase-1 run: 10^8 (10^7 when built with sanitizers, LOCUS_SANITIZED); override with the
// environment variable LOCUS_STRESS_FRAMES. Exit status 0 on success, 1 on any mismatch.
#include "locus/audio_ring.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define LOCUS_CPU_RELAX() _mm_pause()
#else
#define LOCUS_CPU_RELAX() ((void)0)
#endif

namespace {

using locus::AudioRing;
using Clock = std::chrono::steady_clock;

#ifdef LOCUS_SANITIZED
constexpr std::uint64_t kDefaultFrames = 10'000'000;
#else
constexpr std::uint64_t kDefaultFrames = 100'000'000;
#endif

// The bit pattern of sample (frame, ch): unique per (frame, channel) modulo 2^32 samples.
inline std::uint32_t code(std::uint64_t frame, std::uint32_t channels, std::uint32_t ch) {
  return static_cast<std::uint32_t>(frame * channels + ch) * 0x9E3779B1u;
}

inline void fill(float* dst, std::uint64_t first_frame, std::size_t frames, std::uint32_t channels) {
  for (std::size_t f = 0; f < frames; ++f)
    for (std::uint32_t c = 0; c < channels; ++c) dst[f * channels + c] = std::bit_cast<float>(code(first_frame + f, channels, c));
}

// Number of samples that do not match their frame/channel code.
inline std::uint64_t check(const float* src, std::uint64_t first_frame, std::size_t frames, std::uint32_t channels) {
  std::uint64_t bad = 0;
  for (std::size_t f = 0; f < frames; ++f)
    for (std::uint32_t c = 0; c < channels; ++c)
      bad += std::bit_cast<std::uint32_t>(src[f * channels + c]) != code(first_frame + f, channels, c);
  return bad;
}

// Spin briefly, then give the core away (the machine may have fewer cores than busy threads).
struct Backoff {
  unsigned n = 0;
  void operator()() {
    if (++n < 64) {
      LOCUS_CPU_RELAX();
    } else {
      std::this_thread::yield();
      n = 0;
    }
  }
};

// Random block size: mostly audio-like sizes, sometimes tiny, sometimes large.
std::size_t block_size(std::mt19937_64& rng, std::size_t max_block) {
  switch (rng() % 4) {
    case 0: return 1 + rng() % 8;
    case 1: return std::min(max_block, std::size_t{1} << (rng() % 11));  // powers of two up to 1024
    default: return 1 + rng() % max_block;
  }
}

struct Failure {
  std::uint64_t count = 0;
  void report(const char* what, std::uint64_t a, std::uint64_t b) {
    if (count++ < 10) std::fprintf(stderr, "  MISMATCH %s: got %" PRIu64 ", expected %" PRIu64 "\n", what, a, b);
  }
};

struct Result {
  std::uint64_t frames = 0;
  double seconds = 0;
  bool ok = false;
};

// ------------------------------------------------------------------ phase 1: nothing may be lost

Result blocking_run(std::uint32_t channels, std::uint64_t frames, std::uint64_t start_frame, std::size_t capacity,
                    std::size_t max_block, std::uint64_t seed) {
  AudioRing ring(channels, capacity, 64, start_frame);
  const std::uint64_t end_frame = start_frame + frames;
  Failure fail;

  const auto t0 = Clock::now();
  std::thread producer([&] {
    std::mt19937_64 rng(seed);
    std::vector<float> buf(max_block * channels);
    std::uint64_t frame = start_frame;
    Backoff backoff;
    while (frame != end_frame) {
      const std::size_t want = std::min<std::uint64_t>(block_size(rng, max_block), end_frame - frame);
      if (rng() % 4 == 0) {  // copying helper: write only what fits now (nothing may be lost here)
        const std::size_t n = ring.write_acquire(want).frames();
        if (n == 0) {
          backoff();
          continue;
        }
        fill(buf.data(), frame, n, channels);
        if (ring.write(buf.data(), n) != n) fail.report("write() stored", 0, n);
        frame += n;
      } else {  // zero-copy: fill the spans in place (possibly a partial block)
        auto span = ring.write_acquire(want);
        if (span.frames() == 0) {
          backoff();
          continue;
        }
        fill(span.first.data, frame, span.first.frames, channels);
        fill(span.second.data, frame + span.first.frames, span.second.frames, channels);
        if (ring.write_commit(span.frames()) != span.frames()) fail.report("write_commit", 0, span.frames());
        frame += span.frames();
      }
    }
  });

  std::uint64_t bad = 0;
  {
    std::mt19937_64 rng(seed * 31 + 7);
    std::vector<float> buf(max_block * channels);
    std::uint64_t next = start_frame;
    Backoff backoff;
    while (next != end_frame) {
      const std::size_t want = block_size(rng, max_block);
      std::uint64_t first = 0, lost = 0;
      std::size_t n;
      if (rng() % 4 == 0) {
        n = ring.read(buf.data(), want, &first, &lost);
        bad += check(buf.data(), first, n, channels);
      } else {
        auto span = ring.read_acquire(want);
        n = span.frames();
        first = span.first_frame;
        lost = span.lost_before;
        bad += check(span.first.data, first, span.first.frames, channels);
        bad += check(span.second.data, first + span.first.frames, span.second.frames, channels);
        ring.read_release(n);
      }
      if (lost != 0) fail.report("lost_before in blocking mode", lost, 0);
      if (n == 0) {
        backoff();
        continue;
      }
      if (first != next) fail.report("first_frame", first, next);
      if (n > want) fail.report("span larger than asked", n, want);
      next = first + n;
    }
  }
  producer.join();
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();
  if (bad) fail.report("bad samples", bad, 0);
  if (ring.frames_lost() != 0 || ring.overruns() != 0) fail.report("frames_lost", ring.frames_lost(), 0);
  if (ring.readable_frames() != 0) fail.report("left in ring", ring.readable_frames(), 0);
  if (ring.producer_frame() != end_frame) fail.report("producer_frame", ring.producer_frame(), end_frame);

  const double bytes = static_cast<double>(frames) * channels * sizeof(float);
  std::printf("blocking  %u ch, ring %5zu frames, blocks 1..%zu: %" PRIu64 " frames in %.2f s = %.1f Mframes/s, %.0f MB/s  %s\n",
              channels, ring.capacity_frames(), max_block, frames, secs, frames / secs / 1e6, bytes / secs / 1e6,
              fail.count ? "FAILED" : "ok");
  return {frames, secs, fail.count == 0};
}

// ------------------------------------------------------------------ phase 2: live producer, exact loss accounting

// `rate`: the producer's average frame rate (frames/s), chosen below the blocking throughput so that the
// consumer normally keeps up and losses come from its stalls, bursts and preemption.
Result live_run(std::uint32_t channels, std::uint64_t frames, std::uint64_t start_frame, std::size_t capacity,
                std::size_t max_block, std::size_t max_gaps, double rate, std::uint64_t seed) {
  AudioRing ring(channels, capacity, max_gaps, start_frame);
  const std::uint64_t end_frame = start_frame + frames;
  std::atomic<bool> producer_finished{false};
  std::atomic<bool> consumer_finished{false};
  Failure fail;

  const auto t0 = Clock::now();
  std::thread producer([&] {
    std::mt19937_64 rng(seed);
    std::vector<float> buf(max_block * channels);
    std::uint64_t frame = start_frame;
    while (frame != end_frame) {
      const std::size_t n = std::min<std::uint64_t>(block_size(rng, max_block), end_frame - frame);
      if (rng() % 3 == 0) {  // copying helper: stores what fits, reports the rest lost
        fill(buf.data(), frame, n, channels);
        ring.write(buf.data(), n);
      } else {  // zero-copy: fill what fits, commit it (a refused commit reports itself), lose the rest
        auto span = ring.write_acquire(n);
        fill(span.first.data, frame, span.first.frames, channels);
        fill(span.second.data, frame + span.first.frames, span.second.frames, channels);
        ring.write_commit(span.frames());
        ring.write_lost(n - span.frames());
      }
      frame += n;
      if (ring.producer_frame() != frame) fail.report("producer_frame", ring.producer_frame(), frame);
      // Pace like an audio device: blocks are due at `rate` frames/s on average; the producer waits for
      // the clock (never for the ring). Now and then it skips the wait, producing a burst.
      if (rng() % 32 != 0) {
        const auto due = t0 + std::chrono::duration_cast<Clock::duration>(
                                  std::chrono::duration<double>((frame - start_frame) / rate));
        for (Backoff backoff; Clock::now() < due;) backoff();
      }
    }
    producer_finished.store(true, std::memory_order_release);
    // A loss may still wait for room in the gap queue: keep retrying until the consumer has seen the end.
    while (!consumer_finished.load(std::memory_order_acquire)) {
      ring.write_commit(0);
      std::this_thread::yield();
    }
  });

  std::uint64_t received = 0, lost = 0, gaps = 0, bad = 0;
  std::uint64_t next = start_frame;
  {
    std::mt19937_64 rng(seed * 31 + 7);
    std::vector<float> buf(max_block * channels);
    Backoff backoff;
    const auto deadline = Clock::now() + std::chrono::seconds(120);
    while (next != end_frame) {
      const std::size_t want = block_size(rng, max_block);
      std::uint64_t first = 0, lost_before = 0;
      std::size_t n;
      if (rng() % 4 == 0) {
        n = ring.read(buf.data(), want, &first, &lost_before);
        bad += check(buf.data(), first, n, channels);
      } else {
        auto span = ring.read_acquire(want);
        n = span.frames();
        first = span.first_frame;
        lost_before = span.lost_before;
        bad += check(span.first.data, first, span.first.frames, channels);
        bad += check(span.second.data, first + span.first.frames, span.second.frames, channels);
        ring.read_release(n);
      }
      if (n == 0 && lost_before == 0) {
        if (Clock::now() > deadline) {
          fail.report("timeout waiting for frame", next, end_frame);
          break;
        }
        backoff();
        continue;
      }
      if (first != next + lost_before) fail.report("first_frame after gap", first, next + lost_before);
      received += n;
      lost += lost_before;
      gaps += lost_before != 0;
      next = first + n;
      // Stall now and then, up to ~3 ring lengths of stream time, so the live producer overruns the ring.
      if (rng() % 256 == 0) {
        const double stall = (rng() % 1000) / 1000.0 * 3.0 * static_cast<double>(ring.capacity_frames()) / rate;
        const auto until = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(stall));
        for (Backoff backoff; Clock::now() < until;) backoff();
      }
    }
  }
  consumer_finished.store(true, std::memory_order_release);
  producer.join();
  const double secs = std::chrono::duration<double>(Clock::now() - t0).count();

  if (bad) fail.report("bad samples", bad, 0);
  if (next != end_frame) fail.report("last frame", next, end_frame);
  if (received + lost != frames) fail.report("received + lost", received + lost, frames);
  if (lost != ring.frames_lost()) fail.report("lost vs frames_lost()", lost, ring.frames_lost());
  if (gaps > ring.overruns()) fail.report("gaps seen vs overruns()", gaps, ring.overruns());
  if (ring.readable_frames() != 0) fail.report("left in ring", ring.readable_frames(), 0);
  if (lost == 0 || received == 0) std::printf("  note: live run saw %s\n", lost == 0 ? "no loss" : "no data");

  std::printf("live      %u ch, ring %5zu frames, gap queue %2zu, %.1f Mframes/s: %" PRIu64 " frames: %" PRIu64
              " received, %" PRIu64 " lost in %" PRIu64 " gaps (%" PRIu64 " overruns) in %.2f s  %s\n",
              channels, ring.capacity_frames(), max_gaps, rate / 1e6, frames, received, lost, gaps, ring.overruns(), secs,
              fail.count ? "FAILED" : "ok");
  return {frames, secs, fail.count == 0};
}

}  // namespace

int main() {
  std::uint64_t frames = kDefaultFrames;
  if (const char* env = std::getenv("LOCUS_STRESS_FRAMES")) {
    char* end = nullptr;
    const unsigned long long v = std::strtoull(env, &end, 10);
    if (end == env || v == 0) {
      std::fprintf(stderr, "LOCUS_STRESS_FRAMES must be a positive integer, got '%s'\n", env);
      return 2;
    }
    frames = v;
  }
  std::printf("locus_ring_stress: %" PRIu64 " frames per blocking run (LOCUS_STRESS_FRAMES overrides), %u hardware threads\n",
              frames, std::thread::hardware_concurrency());

  bool ok = true;
  std::uint64_t total_frames = 0, total_bytes = 0;
  double total_secs = 0;
  auto account = [&](const Result& r, std::uint32_t ch) {
    ok = ok && r.ok;
    total_frames += r.frames;
    total_bytes += r.frames * ch * sizeof(float);
    total_secs += r.seconds;
  };

  const Result b2 = blocking_run(2, frames, 0, 8192, 1024, 1);
  const Result b3 = blocking_run(3, std::max<std::uint64_t>(frames / 2, 1), (1ull << 62) + 12345, 4096, 1024, 2);
  account(b2, 2);
  account(b3, 3);

  // Live runs at a third of the measured blocking throughput, for ~0.1 * frames stream frames each.
  const std::uint64_t live_frames = std::max<std::uint64_t>(frames / 10, 1);
  const Result l1 = live_run(2, live_frames, 0, 2048, 512, 64, b2.frames / b2.seconds / 3, 3);
  const Result l2 = live_run(3, live_frames, (1ull << 63) - 1000, 1024, 512, 2, b3.frames / b3.seconds / 3, 4);
  ok = ok && l1.ok && l2.ok;

  std::printf("throughput (blocking runs): %" PRIu64 " frames in %.2f s = %.1f Mframes/s, %.0f MB/s\n", total_frames,
              total_secs, total_frames / total_secs / 1e6, total_bytes / total_secs / 1e6);
  std::printf("%s\n", ok ? "PASS" : "FAIL");
  return ok ? 0 : 1;
}
