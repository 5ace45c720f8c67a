// The allocation/lock hooks of the real-time safety test binary (locus_rt_safety_tests): every .cpp
// in tests/alloc is linked into it, and rt_hooks.cpp replaces malloc/free/operator new/
// pthread_mutex_lock so that an RtSection counts what the current thread calls while it is open.
// Backends add their own RT-path cases as tests/alloc/rt_<backend>.cpp using RtSection.
#pragma once

#include <atomic>

namespace locus::rt_hooks {

extern thread_local bool t_counting;
extern std::atomic<long> g_allocs;
extern std::atomic<long> g_frees;
extern std::atomic<long> g_locks;

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

}  // namespace locus::rt_hooks
