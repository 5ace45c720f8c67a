// Proves that the real-time path never allocates, frees or takes a mutex after warm-up: the audio
// callback path (AudioRing write, including the overrun path), the detector thread's block step
// (AudioBlockRunner::step with every registered detector) and the event hand-over (RtEventQueue).
//
// The hooks count calls made by the current thread while a RtSection is open.
#include <gtest/gtest.h>
#include <dlfcn.h>
#include <pthread.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/event_bus.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace {
thread_local bool t_counting = false;
std::atomic<long> g_allocs{0};
std::atomic<long> g_frees{0};
std::atomic<long> g_locks{0};

void note_alloc() {
  if (t_counting) g_allocs.fetch_add(1, std::memory_order_relaxed);
}

void* aligned(std::size_t align, std::size_t n) {
  note_alloc();
  return __libc_memalign(align, n ? n : 1);
}

/// Counts allocations, frees and mutex locks made by this thread while alive.
struct RtSection {
  long allocs0 = g_allocs.load(), frees0 = g_frees.load(), locks0 = g_locks.load();
  long allocs_n = 0, frees_n = 0, locks_n = 0;
  RtSection() { t_counting = true; }
  ~RtSection() { end(); }
  /// Stops counting (call before any assertion: a failing assertion allocates).
  void end() {
    if (!t_counting) return;
    t_counting = false;
    allocs_n = g_allocs.load() - allocs0;
    frees_n = g_frees.load() - frees0;
    locks_n = g_locks.load() - locks0;
  }
  long allocs() { end(); return allocs_n; }
  long frees() { end(); return frees_n; }
  long locks() { end(); return locks_n; }
};
}  // namespace

extern "C" {
void* malloc(std::size_t n) {
  note_alloc();
  return __libc_malloc(n);
}
void* calloc(std::size_t a, std::size_t b) {
  note_alloc();
  return __libc_calloc(a, b);
}
void* realloc(void* p, std::size_t n) {
  note_alloc();
  return __libc_realloc(p, n);
}
void free(void* p) {
  if (t_counting && p) g_frees.fetch_add(1, std::memory_order_relaxed);
  __libc_free(p);
}
void* aligned_alloc(std::size_t align, std::size_t n) { return aligned(align, n); }
void* memalign(std::size_t align, std::size_t n) { return aligned(align, n); }
int posix_memalign(void** out, std::size_t align, std::size_t n) {
  *out = aligned(align, n);
  return *out ? 0 : 12;  // ENOMEM
}
int pthread_mutex_lock(pthread_mutex_t* m) {
  if (t_counting) g_locks.fetch_add(1, std::memory_order_relaxed);
  using LockFn = int (*)(pthread_mutex_t*);
  static LockFn real = reinterpret_cast<LockFn>(dlsym(RTLD_NEXT, "pthread_mutex_lock"));
  return real(m);
}
}

void* operator new(std::size_t n) {
  void* p = malloc(n ? n : 1);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  void* p = aligned(static_cast<std::size_t>(a), n);
  if (!p) throw std::bad_alloc();
  return p;
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return malloc(n ? n : 1); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return malloc(n ? n : 1); }
void operator delete(void* p) noexcept { free(p); }
void operator delete[](void* p) noexcept { free(p); }
void operator delete(void* p, std::size_t) noexcept { free(p); }
void operator delete[](void* p, std::size_t) noexcept { free(p); }
void operator delete(void* p, std::align_val_t) noexcept { free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { free(p); }

namespace locus {
namespace {

TEST(RtSafety, HooksSeeAllocationsAndLocks) {
  // The proof is only worth something if the hooks fire: check that they do.
  RtSection rt;
  std::vector<int>* v = new std::vector<int>(100);
  delete v;
  pthread_mutex_t m = PTHREAD_MUTEX_INITIALIZER;
  pthread_mutex_lock(&m);
  pthread_mutex_unlock(&m);
  EXPECT_GE(rt.allocs(), 2);
  EXPECT_GE(rt.frees(), 2);
  EXPECT_EQ(rt.locks(), 1);
}

TEST(RtSafety, AudioCallbackPathDoesNotAllocateOrLock) {
  AudioRing ring(2, 4096, 8);
  std::vector<float> period(2 * 256, 0.25f), out(2 * 4096);
  RtSection rt;
  for (int i = 0; i < 2000; ++i) {
    ring.write(period.data(), 256);  // overruns (ring full) on most iterations: the loss path too
    if (i % 40 == 0) ring.read(out.data(), 4096);
  }
  rt.end();
  EXPECT_GT(ring.overruns(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

TEST(RtSafety, EventHandOverDoesNotAllocateOrLock) {
  RtEventQueue queue("rt", 64);
  AudioDetection d;
  d.device = "A";
  Event out;
  RtSection rt;
  for (int i = 0; i < 1000; ++i) {
    d.frame = i;
    queue.emit(d);  // fills up, then counts drops
    if (i % 3 == 0) queue.pop(out);
  }
  rt.end();
  EXPECT_GT(queue.dropped(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

// Every registered audio detector, with its default parameters, through the detector thread's
// block step on a stream of noise with periodic tone bursts (so detectors actually fire).
TEST(RtSafety, EveryDetectorProcessDoesNotAllocateOrLock) {
  Registry registry;
  register_builtins(registry);
  for (const char* dir : {LOCUS_TEST_PLUGIN_DIR "/clip", LOCUS_TEST_PLUGIN_DIR "/good"}) {
    const auto failures = registry.load_directory(dir);
    ASSERT_TRUE(failures.empty()) << failures.front();
  }
  test::TestHost host;
  int checked = 0;
  for (const auto& entry : registry.plugins()) {
    const locus_plugin_descriptor* d = entry.descriptor;
    if (d->kind != LOCUS_PLUGIN_DETECTOR || !(d->inputs & kInputAudio)) continue;
    const Params params = Params::defaults(*d->schema());
    bool has_required = false;
    for (const ParamSpec& p : *d->schema()) has_required |= p.required();
    ASSERT_FALSE(has_required) << d->name << ": give it test parameters here";

    SCOPED_TRACE(d->name);
    constexpr std::uint32_t kChannels = 2, kBlock = 256;
    StreamInfo info;
    info.device = "A";
    info.channels = kChannels;
    info.sample_rate_hz = 44100.0;
    info.max_block_frames = kBlock;
    auto detector = registry.create_detector(d->name);
    HostContext ctx = host.context(d->name, "A");
    detector->configure(info, params, ctx);

    AudioRing ring(kChannels, 1 << 16);
    RtEventQueue queue("A", 1 << 14);
    AudioBlockRunner runner(ring, kBlock, {detector.get()}, queue);
    std::vector<float> block(kChannels * kBlock);
    std::uint64_t frame = 0;
    std::uint32_t seed = 12345;
    auto fill = [&] {
      for (std::uint32_t i = 0; i < kBlock; ++i, ++frame) {
        seed = seed * 1664525u + 1013904223u;
        const float noise = 1e-3f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
        const bool burst = (frame % 22050) < 2000;
        const float tone = burst ? 0.5f * std::sin(2.0f * 3.14159265f * 3000.0f * static_cast<float>(frame) / 44100.0f) : 0.0f;
        for (std::uint32_t c = 0; c < kChannels; ++c) block[i * kChannels + c] = tone + noise;
      }
    };
    // Warm-up (first blocks may touch lazily initialised state), then the measured section.
    for (int i = 0; i < 50; ++i) {
      fill();
      ring.write(block.data(), kBlock);
      runner.step(false);
    }
    const std::uint64_t delivered_before = queue.dropped();
    (void)delivered_before;
    RtSection rt;
    for (int i = 0; i < 2000; ++i) {
      fill();
      ring.write(block.data(), kBlock);
      runner.step(false);
      if (i == 1000) ring.write_lost(100);  // a gap: detectors reset their state
    }
    const long allocs = rt.allocs(), frees = rt.frees(), locks = rt.locks();
    EXPECT_EQ(allocs, 0) << d->name << " allocated in process_audio";
    EXPECT_EQ(frees, 0) << d->name << " freed in process_audio";
    EXPECT_EQ(locks, 0) << d->name << " locked a mutex in process_audio";
    EXPECT_EQ(runner.frames_lost(), 100u);
    ++checked;
  }
  EXPECT_GE(checked, 3) << "expected onset, clip_detector and fixture_level at least";
}

}  // namespace
}  // namespace locus
