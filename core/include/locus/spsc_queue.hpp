// Bounded single-producer/single-consumer queue of trivially copyable values.
//
// Why: the real-time side (audio callback, detector thread) hands messages to the non-real-time side
// without allocating, locking or making a syscall. Capacity is fixed at construction (rounded up to a
// power of two); `try_push` never allocates and fails (returning false) when the queue is full, like
// moodycamel's `try_enqueue` in CannotAlloc mode. Each side caches the other side's index so that the
// shared cache line is read only when the cached value says the queue looks full/empty.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <optional>
#include <stdexcept>
#include <type_traits>

namespace locus {

/// Destructive-interference size used to keep producer and consumer state on separate cache lines.
inline constexpr std::size_t kCacheLine = 64;

template <typename T>
class SpscQueue {
  static_assert(std::is_trivially_copyable_v<T>, "SpscQueue holds trivially copyable values only");

 public:
  /// [main] Allocates storage for at least `min_capacity` values (rounded up to a power of two).
  explicit SpscQueue(std::size_t min_capacity)
      : capacity_(std::bit_ceil(min_capacity < 2 ? std::size_t{2} : min_capacity)),
        mask_(capacity_ - 1),
        slots_(std::make_unique<T[]>(capacity_)) {}

  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  /// [RT, producer] Appends `value`; returns false (and changes nothing) when full. Never allocates.
  bool try_push(const T& value) noexcept {
    const std::uint64_t w = prod_.write.load(std::memory_order_relaxed);
    if (w - prod_.read_cache >= capacity_) {
      prod_.read_cache = cons_.read.load(std::memory_order_acquire);
      if (w - prod_.read_cache >= capacity_) return false;
    }
    slots_[w & mask_] = value;
    prod_.write.store(w + 1, std::memory_order_release);
    return true;
  }

  /// [RT, consumer] Removes the oldest value into `out`; returns false when empty.
  bool try_pop(T& out) noexcept {
    const std::uint64_t r = cons_.read.load(std::memory_order_relaxed);
    if (r == cons_.write_cache) {
      cons_.write_cache = prod_.write.load(std::memory_order_acquire);
      if (r == cons_.write_cache) return false;
    }
    out = slots_[r & mask_];
    cons_.read.store(r + 1, std::memory_order_release);
    return true;
  }

  /// [any] Approximate number of queued values (exact when both sides are idle).
  std::size_t size_approx() const noexcept {
    // Read index first: it never passes the write index, which only grows, so the difference cannot
    // wrap around (loading `write` first could see a `read` that has moved past it since). Between
    // the two loads both sides may move on, so an observer on a third thread can see more than a full
    // ring: clamp to what the ring can actually hold. Exact when called by the consumer.
    const std::uint64_t r = cons_.read.load(std::memory_order_acquire);
    const std::uint64_t w = prod_.write.load(std::memory_order_acquire);
    return static_cast<std::size_t>(std::min<std::uint64_t>(w - r, capacity_));
  }

  std::size_t capacity() const noexcept { return capacity_; }

 private:
  struct alignas(kCacheLine) Producer {
    std::atomic<std::uint64_t> write{0};
    std::uint64_t read_cache = 0;
  };
  struct alignas(kCacheLine) Consumer {
    std::atomic<std::uint64_t> read{0};
    std::uint64_t write_cache = 0;
  };

  const std::size_t capacity_;
  const std::size_t mask_;
  std::unique_ptr<T[]> slots_;
  Producer prod_;
  Consumer cons_;
};

}  // namespace locus
