// Lock-free single-producer/single-consumer ring of interleaved multi-channel float audio frames.
//
// Why this shape: the audio callback (producer) must never block, allocate or lose data silently, and
// every detector downstream needs the exact sample clock of each frame it sees. So:
//  - capacity is a power of two fixed at construction; indices are free-running 64-bit counters;
//  - reads and writes hand out zero-copy spans of at most two contiguous segments (the wrap point);
//  - producer and consumer state live on separate cache lines, each caching the other's index so the
//    shared line is touched only when the cache says "full"/"empty"; acquire/release atomics only;
//  - when the producer cannot place frames (ring full), it reports them with `write_lost`: the stream
//    clock still advances, an overrun is counted, and the consumer is told, at the exact position in
//    the stream, how many frames it lost (`ReadSpan::lost_before`). Stream frame numbers (the sample
//    clock) therefore stay exact across overruns.
//
// Threading: one producer thread calls the [RT, producer] methods, one consumer thread calls the
// [RT, consumer] methods; [any] methods may be called from anywhere.
#pragma once

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <stdexcept>

#include "locus/spsc_queue.hpp"

// The copying fast paths are small once the rare cases (pending loss, gaps, large copies) are out of
// line; inlining them into the caller saves the call and register spills on per-frame use.
#if defined(__GNUC__)
#define LOCUS_RING_INLINE [[gnu::always_inline]] inline
#else
#define LOCUS_RING_INLINE inline
#endif

namespace locus {

class AudioRing {
 public:
  /// A contiguous run of interleaved frames inside the ring.
  struct Segment {
    float* data = nullptr;
    std::size_t frames = 0;
  };

  /// Free space handed to the producer: fill `first` then `second`, then `write_commit`.
  struct WriteSpan {
    Segment first, second;
    std::size_t frames() const noexcept { return first.frames + second.frames; }
  };

  /// Frames handed to the consumer: read `first` then `second`, then `read_release`.
  struct ReadSpan {
    Segment first, second;
    /// Stream frame number (sample clock) of the first frame of `first`.
    std::uint64_t first_frame = 0;
    /// Frames lost to an overrun immediately before `first_frame` (0 when the stream is contiguous).
    std::uint64_t lost_before = 0;
    std::size_t frames() const noexcept { return first.frames + second.frames; }
  };

  /// [main] `channels` >= 1; capacity rounded up to a power of two frames; `max_pending_gaps` bounds
  /// how many distinct overrun episodes can await the consumer (more are merged, never dropped);
  /// `start_frame` is the stream frame number of the first frame that will be written.
  AudioRing(std::uint32_t channels, std::size_t min_capacity_frames, std::size_t max_pending_gaps = 64,
            std::uint64_t start_frame = 0)
      : channels_(channels),
        capacity_(std::bit_ceil(std::max<std::size_t>(min_capacity_frames, 2))),
        mask_(capacity_ - 1),
        gaps_(max_pending_gaps) {
    if (channels == 0) throw std::invalid_argument("AudioRing: channels must be >= 1");
    storage_ = std::unique_ptr<float[], FreeDeleter>(static_cast<float*>(
        ::operator new[](capacity_ * channels_ * sizeof(float), std::align_val_t{kCacheLine})));
    std::memset(storage_.get(), 0, capacity_ * channels_ * sizeof(float));
    prod_.stream_frame = start_frame;
    cons_.stream_offset = start_frame;
  }

  AudioRing(const AudioRing&) = delete;
  AudioRing& operator=(const AudioRing&) = delete;

  std::uint32_t channels() const noexcept { return channels_; }
  std::size_t capacity_frames() const noexcept { return capacity_; }

  // ---------------------------------------------------------------- producer

  /// [RT, producer] Up to `max_frames` of free space as one or two segments (possibly empty).
  WriteSpan write_acquire(std::size_t max_frames) noexcept {
    const std::uint64_t w = prod_.write.load(std::memory_order_relaxed);
    std::size_t free_frames = capacity_ - static_cast<std::size_t>(w - prod_.read_cache);
    if (free_frames < max_frames) {
      prod_.read_cache = cons_.read.load(std::memory_order_acquire);
      free_frames = capacity_ - static_cast<std::size_t>(w - prod_.read_cache);
    }
    return make_span<WriteSpan>(w, std::min(max_frames, free_frames));
  }

  /// [RT, producer] Publishes the first `frames` frames of the last write span. Returns the frames
  /// published: 0 (and the frames are reported lost) only if an earlier loss could not yet be
  /// recorded because `max_pending_gaps` episodes are already waiting for the consumer.
  /// `write_commit(0)` publishes nothing but retries recording such a pending loss, so a producer that
  /// stops writing after an overrun can still let the consumer learn about it.
  std::size_t write_commit(std::size_t frames) noexcept {
    if (frames == 0) {
      if (prod_.pending_lost != 0) flush_pending_gap();
      return 0;
    }
    if (prod_.pending_lost != 0 && !flush_pending_gap()) {
      write_lost(frames);
      return 0;
    }
    const std::uint64_t w = prod_.write.load(std::memory_order_relaxed);
    prod_.write.store(w + frames, std::memory_order_release);
    prod_.stream_frame += frames;
    return frames;
  }

  /// [RT, producer] Declares that the next `frames` frames of the stream could not be stored. The
  /// stream clock advances past them, the loss is counted and the consumer will be told where.
  void write_lost(std::size_t frames) noexcept {
    if (frames == 0) return;
    prod_.pending_lost += frames;
    prod_.stream_frame += frames;
    frames_lost_.store(frames_lost_.load(std::memory_order_relaxed) + frames, std::memory_order_relaxed);
    overruns_.store(overruns_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    flush_pending_gap();
  }

  /// [RT, producer] Copies `frames` interleaved frames in; what does not fit is reported lost.
  /// Returns the number of frames stored.
  LOCUS_RING_INLINE std::size_t write(const float* interleaved, std::size_t frames) noexcept {
    if (prod_.pending_lost != 0) [[unlikely]] return write_slow(interleaved, frames);
    // Same steps as write_acquire + write_commit + write_lost, without building a span.
    const std::uint64_t w = prod_.write.load(std::memory_order_relaxed);
    std::size_t free_frames = capacity_ - static_cast<std::size_t>(w - prod_.read_cache);
    if (free_frames < frames) {
      prod_.read_cache = cons_.read.load(std::memory_order_acquire);
      free_frames = capacity_ - static_cast<std::size_t>(w - prod_.read_cache);
    }
    const std::size_t n = std::min(frames, free_frames);
    const std::size_t start = static_cast<std::size_t>(w & mask_);
    const std::size_t n1 = std::min(n, capacity_ - start);
    copy_samples(storage_.get() + start * channels_, interleaved, n1 * channels_);
    if (n1 != n) copy_samples(storage_.get(), interleaved + n1 * channels_, (n - n1) * channels_);
    if (n != 0) {
      prod_.write.store(w + n, std::memory_order_release);
      prod_.stream_frame += n;
    }
    if (n != frames) [[unlikely]] write_lost(frames - n);
    return n;
  }

  /// [RT, producer] Stores one interleaved frame (channels() floats) if there is room; returns false
  /// and stores nothing when the ring is full (a live producer then reports it with write_lost(1)).
  /// The lean path for frame-by-frame producers.
  LOCUS_RING_INLINE bool try_push_frame(const float* frame) noexcept {
    if (prod_.pending_lost != 0) [[unlikely]] return write_slow_frame(frame);
    const std::uint64_t w = prod_.write.load(std::memory_order_relaxed);
    if (w - prod_.read_cache >= capacity_) {
      prod_.read_cache = cons_.read.load(std::memory_order_acquire);
      if (w - prod_.read_cache >= capacity_) return false;
    }
    copy_samples(storage_.get() + static_cast<std::size_t>(w & mask_) * channels_, frame, channels_);
    prod_.write.store(w + 1, std::memory_order_release);
    ++prod_.stream_frame;
    return true;
  }

  /// [RT, producer] Stream frame number of the next frame the producer will write or lose.
  std::uint64_t producer_frame() const noexcept { return prod_.stream_frame; }

  // ---------------------------------------------------------------- consumer

  /// [RT, consumer] Up to `max_frames` readable frames. The span never straddles a loss: if frames
  /// were lost before the next readable frame, `lost_before` says how many, and `first_frame` is the
  /// frame after the gap. A span with 0 frames may still report `lost_before` > 0.
  ReadSpan read_acquire(std::size_t max_frames) noexcept {
    const std::uint64_t r = cons_.read.load(std::memory_order_relaxed);
    std::uint64_t lost_here = 0;
    ReadSpan span = make_span<ReadSpan>(r, readable_from(r, max_frames, lost_here));
    span.first_frame = r + cons_.stream_offset;
    span.lost_before = lost_here;
    return span;
  }

  /// [RT, consumer] Frees the first `frames` frames of the last read span.
  void read_release(std::size_t frames) noexcept {
    cons_.read.store(cons_.read.load(std::memory_order_relaxed) + frames, std::memory_order_release);
  }

  /// [RT, consumer] Copies up to `max_frames` contiguous-in-time frames into `dst`; see read_acquire.
  LOCUS_RING_INLINE std::size_t read(float* dst, std::size_t max_frames, std::uint64_t* first_frame = nullptr,
                                     std::uint64_t* lost_before = nullptr) noexcept {
    // Same steps as read_acquire + read_release, without building a span.
    const std::uint64_t r = cons_.read.load(std::memory_order_relaxed);
    std::uint64_t lost_here = 0;
    const std::size_t n = readable_from(r, max_frames, lost_here);
    const std::size_t start = static_cast<std::size_t>(r & mask_);
    const std::size_t n1 = std::min(n, capacity_ - start);
    copy_samples(dst, storage_.get() + start * channels_, n1 * channels_);
    if (n1 != n) copy_samples(dst + n1 * channels_, storage_.get(), (n - n1) * channels_);
    if (n != 0) cons_.read.store(r + n, std::memory_order_release);
    if (first_frame) *first_frame = r + cons_.stream_offset;
    if (lost_before) *lost_before = lost_here;
    return n;
  }

  /// [RT, consumer] Takes one frame into `frame` (channels() floats); false when none is readable.
  /// `stream_frame` (optional) receives its stream frame number; frames lost before it, if any, are
  /// reported through `lost_before` (optional), exactly as read() does.
  LOCUS_RING_INLINE bool try_pop_frame(float* frame, std::uint64_t* stream_frame = nullptr,
                                       std::uint64_t* lost_before = nullptr) noexcept {
    const std::uint64_t r = cons_.read.load(std::memory_order_relaxed);
    if (r == cons_.write_cache) {
      // Refresh, and poll the gap queue as readable_from() does on a refresh.
      cons_.write_cache = prod_.write.load(std::memory_order_acquire);
      if (!cons_.has_gap && gaps_.try_pop(cons_.gap)) [[unlikely]] cons_.has_gap = true;
      if (r == cons_.write_cache && !cons_.has_gap) return false;
    }
    if (cons_.has_gap) [[unlikely]] return read(frame, 1, stream_frame, lost_before) == 1;  // the general path
    copy_samples(frame, storage_.get() + static_cast<std::size_t>(r & mask_) * channels_, channels_);
    cons_.read.store(r + 1, std::memory_order_release);
    if (stream_frame) *stream_frame = r + cons_.stream_offset;
    if (lost_before) *lost_before = 0;
    return true;
  }

  // ---------------------------------------------------------------- statistics

  /// [any] Frames readable now (approximate while the producer runs).
  std::size_t readable_frames() const noexcept {
    // Read index first: it never passes the write index, which only grows, so the difference cannot
    // wrap around (loading `write` first could see a `read` that has moved past it since). Between
    // the two loads both sides may move on, so an observer on a third thread can see more than a full
    // ring: clamp to what the ring can actually hold. Exact when called by the consumer.
    const std::uint64_t r = cons_.read.load(std::memory_order_acquire);
    const std::uint64_t w = prod_.write.load(std::memory_order_acquire);
    return static_cast<std::size_t>(std::min<std::uint64_t>(w - r, capacity_));
  }
  /// [any] Total frames the producer reported lost.
  std::uint64_t frames_lost() const noexcept { return frames_lost_.load(std::memory_order_relaxed); }
  /// [any] Number of `write_lost` episodes (overruns).
  std::uint64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }

 private:
  struct Gap {
    std::uint64_t ring_pos;  // ring position before which the frames were lost
    std::uint64_t frames;
  };
  struct FreeDeleter {
    void operator()(float* p) const noexcept { ::operator delete[](p, std::align_val_t{kCacheLine}); }
  };

  /// write() while a loss is pending: the general path (a refused commit turns into lost frames).
  std::size_t write_slow(const float* interleaved, std::size_t frames) noexcept {
    WriteSpan span = write_acquire(frames);
    const std::size_t n1 = span.first.frames * channels_;
    copy_samples(span.first.data, interleaved, n1);
    copy_samples(span.second.data, interleaved + n1, span.second.frames * channels_);
    const std::size_t stored = write_commit(span.frames());  // a refused commit reports its own loss
    write_lost(frames - span.frames());
    return stored;
  }

  bool write_slow_frame(const float* frame) noexcept {
    WriteSpan span = write_acquire(1);
    if (span.frames() == 0) return false;
    copy_samples(span.first.data, frame, channels_);
    // A refused commit (gap queue full) has reported the frame lost: to the caller it was stored.
    write_commit(1);
    return true;
  }

  /// Consumer: frames readable from ring position `r` (at most `max_frames`), stopping at the next gap.
  /// Gaps recorded at `r` itself are consumed: their frames are added to `lost_here` and to the
  /// stream offset, so that `r + stream_offset` is the stream frame number of position `r`.
  LOCUS_RING_INLINE std::size_t readable_from(std::uint64_t r, std::size_t max_frames, std::uint64_t& lost_here) noexcept {
    std::size_t available = static_cast<std::size_t>(cons_.write_cache - r);
    bool refreshed = false;
    if (available < max_frames) {
      cons_.write_cache = prod_.write.load(std::memory_order_acquire);
      available = static_cast<std::size_t>(cons_.write_cache - r);
      refreshed = true;
    }
    // A gap at ring position p is queued before the write index passes p, so every gap inside
    // [r, write_cache) was visible when write_cache was loaded (acquire). Hence the gap queue needs
    // polling only on a refresh; a popped gap is held until reached, and applying it pops the next.
    // (A gap exactly at write_cache is found by the refresh that happens once r reaches it.)
    if (cons_.has_gap || (refreshed && gaps_.try_pop(cons_.gap))) [[unlikely]]
      available = apply_gaps(r, available, lost_here);
    return std::min(max_frames, available);
  }

  /// Consumer, a gap is in `cons_.gap`: consumes the gaps at `r`, limits `available` to the next one.
  std::size_t apply_gaps(std::uint64_t r, std::size_t available, std::uint64_t& lost_here) noexcept {
    cons_.has_gap = true;
    do {
      if (cons_.gap.ring_pos != r) {
        available = std::min<std::size_t>(available, static_cast<std::size_t>(cons_.gap.ring_pos - r));
        break;
      }
      lost_here += cons_.gap.frames;
      cons_.has_gap = false;
    } while (gaps_.try_pop(cons_.gap) && (cons_.has_gap = true));
    cons_.stream_offset += lost_here;
    return available;
  }

  /// Copies `samples` floats between non-overlapping buffers. Small copies (a few frames, the common
  /// case for the empty or short second segment and for frame-by-frame use) are done inline with
  /// fixed-size, possibly overlapping moves instead of a call into libc's memcpy.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
// With a runtime channel count GCC cannot rule out the wider branches for a caller's small buffer.
#pragma GCC diagnostic ignored "-Warray-bounds"
#pragma GCC diagnostic ignored "-Wstringop-overread"
#pragma GCC diagnostic ignored "-Wstringop-overflow"
#endif
  LOCUS_RING_INLINE static void copy_samples(float* dst, const float* src, std::size_t samples) noexcept {
    auto* d = reinterpret_cast<unsigned char*>(dst);
    const auto* s = reinterpret_cast<const unsigned char*>(src);
    const std::size_t bytes = samples * sizeof(float);
    if (bytes <= 16) {
      if (bytes >= 8) {
        std::memcpy(d, s, 8);
        std::memcpy(d + bytes - 8, s + bytes - 8, 8);
      } else if (bytes != 0) {
        std::memcpy(d, s, 4);  // bytes == 4: a single sample
      }
    } else if (bytes <= 32) {
      std::memcpy(d, s, 16);
      std::memcpy(d + bytes - 16, s + bytes - 16, 16);
    } else if (bytes <= 64) {
      std::memcpy(d, s, 32);
      std::memcpy(d + bytes - 32, s + bytes - 32, 32);
    } else {
      std::memcpy(d, s, bytes);
    }
  }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

  template <typename Span>
  Span make_span(std::uint64_t pos, std::size_t frames) const noexcept {
    const std::size_t start = static_cast<std::size_t>(pos & mask_);
    const std::size_t n1 = std::min(frames, capacity_ - start);
    Span s{};
    s.first = Segment{storage_.get() + start * channels_, n1};
    s.second = Segment{storage_.get(), frames - n1};
    return s;
  }

  bool flush_pending_gap() noexcept {
    if (!gaps_.try_push(Gap{prod_.write.load(std::memory_order_relaxed), prod_.pending_lost})) return false;
    prod_.pending_lost = 0;
    return true;
  }

  struct alignas(kCacheLine) Producer {
    std::atomic<std::uint64_t> write{0};
    std::uint64_t read_cache = 0;
    std::uint64_t stream_frame = 0;
    std::uint64_t pending_lost = 0;
  };
  struct alignas(kCacheLine) Consumer {
    std::atomic<std::uint64_t> read{0};
    std::uint64_t write_cache = 0;
    std::uint64_t stream_offset = 0;  // stream frame of ring position 0 plus all losses applied so far
    Gap gap{};
    bool has_gap = false;
  };

  const std::uint32_t channels_;
  const std::size_t capacity_;
  const std::size_t mask_;
  std::unique_ptr<float[], FreeDeleter> storage_;
  SpscQueue<Gap> gaps_;
  Producer prod_;
  Consumer cons_;
  alignas(kCacheLine) std::atomic<std::uint64_t> frames_lost_{0};
  std::atomic<std::uint64_t> overruns_{0};
};

}  // namespace locus
