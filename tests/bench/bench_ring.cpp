// Benchmarks of locus::AudioRing against boost::lockfree::spsc_queue and JACK's jack_ringbuffer_t, all
// moving interleaved stereo float frames through a ring of 8192 frames:
//   BM_Frame/<impl>          push one frame, pop one frame (single thread, round trip)
//   BM_Block/<impl>/<N>      write a block of N frames, read it back (single thread, round trip)
//   BM_Stream/<impl>/<N>     producer thread writes blocks of N frames, consumer thread reads blocks of N
// Items are frames; bytes are frames * 8 (the audio moved through the ring once).
// Run: build/bin/locus_bench_ring --benchmark_min_time=0.2   (see docs/benchmarks.md)
// LOCUS_BENCH_ITERATIONS=<n> fixes the iteration count (e.g. to count instructions under callgrind).
// Builds without JACK support (LOCUS_WITH_JACK; LOCUS_BENCH_JACK_RING unset) leave the jack rows out.
#include "locus/audio_ring.hpp"

#include <benchmark/benchmark.h>
#if LOCUS_BENCH_JACK_RING
#include <jack/ringbuffer.h>
#endif

#include <algorithm>
#include <atomic>
#include <boost/lockfree/spsc_queue.hpp>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define LOCUS_CPU_RELAX() _mm_pause()
#else
#define LOCUS_CPU_RELAX() ((void)0)
#endif

// The adapters are glue, not the thing measured: keep them out of the way of the optimiser.
#define INLINE [[gnu::always_inline]] inline

namespace {

constexpr std::size_t kRingFrames = 8192;
constexpr std::uint32_t kChannels = 2;

struct StereoFrame {
  float left, right;
};
static_assert(sizeof(StereoFrame) == kChannels * sizeof(float));

// ------------------------------------------------------------------ adapters: same operations on each ring
// write(src, n) stores up to n frames (what fits) and returns how many; read(dst, n) likewise.

struct LocusRing {
  static constexpr const char* kName = "locus";
  locus::AudioRing ring{kChannels, kRingFrames};
  INLINE std::size_t write(const float* src, std::size_t n) {
    // What fits, through the zero-copy span (AudioRing::write would report the rest lost).
    auto span = ring.write_acquire(n);
    std::memcpy(span.first.data, src, span.first.frames * kChannels * sizeof(float));
    std::memcpy(span.second.data, src + span.first.frames * kChannels, span.second.frames * kChannels * sizeof(float));
    return ring.write_commit(span.frames());
  }
  // Frame round trips use the per-frame API; block round trips the copying helper, the way an audio
  // callback would.
  INLINE std::size_t push_frame(const float* src) { return ring.try_push_frame(src); }
  INLINE std::size_t pop_frame(float* dst) { return ring.try_pop_frame(dst); }
  INLINE std::size_t write_all(const float* src, std::size_t n) { return ring.write(src, n); }
  INLINE std::size_t read(float* dst, std::size_t n) { return ring.read(dst, n); }
};

struct BoostRing {
  static constexpr const char* kName = "boost";
  boost::lockfree::spsc_queue<StereoFrame> q{kRingFrames};
  INLINE std::size_t write(const float* src, std::size_t n) { return q.push(reinterpret_cast<const StereoFrame*>(src), n); }
  INLINE std::size_t write_all(const float* src, std::size_t n) { return write(src, n); }
  INLINE std::size_t read(float* dst, std::size_t n) { return q.pop(reinterpret_cast<StereoFrame*>(dst), n); }
  INLINE std::size_t push_frame(const float* src) { return q.push(*reinterpret_cast<const StereoFrame*>(src)); }
  INLINE std::size_t pop_frame(float* dst) { return q.pop(*reinterpret_cast<StereoFrame*>(dst)); }
};

#if LOCUS_BENCH_JACK_RING
struct JackRing {
  static constexpr const char* kName = "jack";
  static constexpr std::size_t kFrameBytes = sizeof(StereoFrame);
  jack_ringbuffer_t* rb = jack_ringbuffer_create(kRingFrames * kFrameBytes);  // usable: one byte less
  JackRing() = default;
  JackRing(const JackRing&) = delete;
  ~JackRing() { jack_ringbuffer_free(rb); }
  INLINE std::size_t write(const float* src, std::size_t n) {
    const std::size_t space = jack_ringbuffer_write_space(rb) / kFrameBytes;  // whole frames only
    const std::size_t frames = std::min(n, space);
    return jack_ringbuffer_write(rb, reinterpret_cast<const char*>(src), frames * kFrameBytes) / kFrameBytes;
  }
  INLINE std::size_t write_all(const float* src, std::size_t n) { return write(src, n); }
  INLINE std::size_t push_frame(const float* src) { return write(src, 1); }
  INLINE std::size_t pop_frame(float* dst) { return read(dst, 1); }
  INLINE std::size_t read(float* dst, std::size_t n) {
    const std::size_t avail = jack_ringbuffer_read_space(rb) / kFrameBytes;
    const std::size_t frames = std::min(n, avail);
    return jack_ringbuffer_read(rb, reinterpret_cast<char*>(dst), frames * kFrameBytes) / kFrameBytes;
  }
};
#endif  // LOCUS_BENCH_JACK_RING

std::vector<float> source_block(std::size_t frames) {
  std::vector<float> v(frames * kChannels);
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = static_cast<float>(i) * 0.25f;
  return v;
}

void set_counters(benchmark::State& state, std::size_t frames_per_iteration) {
  const auto frames = static_cast<std::int64_t>(state.iterations() * frames_per_iteration);
  state.SetItemsProcessed(frames);
  state.SetBytesProcessed(frames * static_cast<std::int64_t>(sizeof(StereoFrame)));
}

// ------------------------------------------------------------------ (a) per frame

template <typename Ring>
void BM_Frame(benchmark::State& state) {
  auto ring = std::make_unique<Ring>();
  const StereoFrame in{0.5f, -0.5f};
  StereoFrame out{};
  for (auto _ : state) {
    const std::size_t w = ring->push_frame(&in.left);
    const std::size_t r = ring->pop_frame(&out.left);
    benchmark::DoNotOptimize(w + r);
    benchmark::DoNotOptimize(out);
    if (w + r != 2) state.SkipWithError("ring refused a frame");
  }
  set_counters(state, 1);
}

// ------------------------------------------------------------------ (b) per block, single-threaded round trip

template <typename Ring>
void BM_Block(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  auto ring = std::make_unique<Ring>();
  const auto in = source_block(n);
  std::vector<float> out(n * kChannels);
  for (auto _ : state) {
    const std::size_t w = ring->write_all(in.data(), n);
    const std::size_t r = ring->read(out.data(), n);
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
    if (w != n || r != n) state.SkipWithError("ring refused a block");
  }
  set_counters(state, n);
}

// ------------------------------------------------------------------ (c) two threads, streaming

template <typename Ring>
void BM_Stream(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  auto ring = std::make_unique<Ring>();
  const auto in = source_block(n);
  std::atomic<std::uint64_t> produced_total{~std::uint64_t{0}};
  std::thread consumer([&] {
    std::vector<float> out(n * kChannels);
    std::uint64_t consumed = 0;
    unsigned idle = 0;
    while (consumed != produced_total.load(std::memory_order_acquire)) {
      const std::size_t got = ring->read(out.data(), n);
      benchmark::DoNotOptimize(out.data());
      consumed += got;
      if (got == 0 && ++idle % 256 == 0) std::this_thread::yield();
      else if (got == 0) LOCUS_CPU_RELAX();
    }
  });
  std::uint64_t produced = 0;
  for (auto _ : state) {
    std::size_t done = 0;
    unsigned idle = 0;
    while (done < n) {
      const std::size_t put = ring->write(in.data() + done * kChannels, n - done);
      done += put;
      if (put == 0 && ++idle % 256 == 0) std::this_thread::yield();
      else if (put == 0) LOCUS_CPU_RELAX();
    }
    produced += n;
  }
  produced_total.store(produced, std::memory_order_release);
  consumer.join();
  set_counters(state, n);
}

// Rows are grouped so that a table reads locus / boost / jack for each case; the argument (block size)
// becomes the last name component, e.g. BM_Block/locus/1024.
template <template <typename> class Bench>
void register_case(const char* what, int block, bool real_time) {
  auto reg = [&](auto* ring_tag) {
    using Ring = std::remove_pointer_t<decltype(ring_tag)>;
    auto* b = benchmark::RegisterBenchmark((std::string(what) + "/" + Ring::kName).c_str(), Bench<Ring>::run);
    if (block > 0) b->Arg(block);
    if (real_time) b->UseRealTime();
    // Fixed iteration count (for instruction counts under callgrind, see docs/benchmarks.md).
    if (const char* it = std::getenv("LOCUS_BENCH_ITERATIONS")) b->Iterations(std::strtoll(it, nullptr, 10));
  };
  reg(static_cast<LocusRing*>(nullptr));
  reg(static_cast<BoostRing*>(nullptr));
#if LOCUS_BENCH_JACK_RING
  reg(static_cast<JackRing*>(nullptr));
#endif
}

template <typename Ring> struct FrameBench { static void run(benchmark::State& s) { BM_Frame<Ring>(s); } };
template <typename Ring> struct BlockBench { static void run(benchmark::State& s) { BM_Block<Ring>(s); } };
template <typename Ring> struct StreamBench { static void run(benchmark::State& s) { BM_Stream<Ring>(s); } };

}  // namespace

int main(int argc, char** argv) {
  register_case<FrameBench>("BM_Frame", 0, false);
  for (int n : {64, 256, 1024, 4096}) register_case<BlockBench>("BM_Block", n, false);
  for (int n : {64, 256, 1024, 4096}) register_case<StreamBench>("BM_Stream", n, true);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
