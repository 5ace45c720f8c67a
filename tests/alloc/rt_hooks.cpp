// Definitions of the hooks declared in rt_hooks.hpp (see there).
#include "rt_hooks.hpp"

#include <dlfcn.h>
#include <pthread.h>

#include <cstdlib>
#include <new>

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void __libc_free(void*);
}

namespace locus::rt_hooks {
thread_local bool t_counting = false;
std::atomic<long> g_allocs{0};
std::atomic<long> g_frees{0};
std::atomic<long> g_locks{0};
}  // namespace locus::rt_hooks

namespace {
using namespace locus::rt_hooks;

void note_alloc() {
  if (t_counting) g_allocs.fetch_add(1, std::memory_order_relaxed);
}

void* aligned(std::size_t align, std::size_t n) {
  note_alloc();
  return __libc_memalign(align, n ? n : 1);
}
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

