// The body of the JACK process callback, without libjack: one object per JACK client that moves one
// period of audio between the client's port buffers and the node (capture ports -> AudioRing,
// PlaybackScheduler -> playback ports) and keeps the stream clock exact.
//
// Why it is separate from the libjack glue (jack_client.cpp): the callback body is the real-time
// path, so it must be provable allocation- and lock-free (tests/alloc/rt_jack.cpp calls it directly
// with plain buffers) and its clock arithmetic must be testable without a server (tests/hal/jack).
//
// The clock: one client has ONE frame counter (`frame()`), advanced by every period processed and by
// every frame found missing. Capture (the ring's producer frame) and playback (the scheduler's frame)
// are kept equal to it, so a sound scheduled at playback frame F leaves in the same cycle as capture
// frame F is taken: a device can find its own emission in its capture at a fixed, known offset.
// Missing frames come from two places:
//   - skipped cycles (an xrun made the server run cycles without us, or a slow cycle): the server's
//     frame time at the start of a cycle (jack_last_frame_time) is ahead of where the previous cycle
//     ended; the difference is the exact count;
//   - a server outage (jackd went away and came back): the new server's frame time is unrelated to the
//     old one, so the gap is estimated from the monotonic clock between the last cycle before the loss
//     and the first one after, times the sample rate (mark_reconnected() tells the next cycle).
// Frames lost are reported where they belong: AudioRing::write_lost (the consumer sees `lost_before`
// at the exact stream position) and PlaybackScheduler::skip (clips in that span are counted cut).
//
// Threads: process() and the begin/end_cycle() pair run on the JACK process thread ([RT]); attach/
// detach run on the main side and never block the RT thread (publication through atomics; detach waits,
// on the main side only, until a cycle that may still hold the old pointer has finished).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "locus/audio_ring.hpp"
#include "locus/playback.hpp"

namespace locus::hal::jack {

/// Most ports one part (capture or playback) of a client may have.
inline constexpr std::uint32_t kMaxPorts = 64;

class JackProcessor {
 public:
  explicit JackProcessor(double sample_rate_hz) noexcept : sample_rate_hz_(sample_rate_hz) {}
  JackProcessor(const JackProcessor&) = delete;
  JackProcessor& operator=(const JackProcessor&) = delete;

  double sample_rate_hz() const noexcept { return sample_rate_hz_; }

  // ------------------------------------------------------------------ main side

  /// [main] From the next cycle on, captured frames go to `ring` (its channels = the capture ports;
  /// missing ports read as silence). If the client's counter is already past the ring's producer
  /// frame (the capture started after the client), the frames in between are reported lost so that
  /// the ring's frame numbers are the client's.
  void attach_capture(AudioRing* ring) noexcept;
  /// [main] No cycle touches the ring after this returns.
  void detach_capture() noexcept;
  /// [main] From the next cycle on, the playback ports are rendered from `scheduler` (skipped forward
  /// to the client's frame counter first, if it is behind).
  void attach_playback(PlaybackScheduler* scheduler) noexcept;
  /// [main] No cycle touches the scheduler after this returns (the ports then play silence).
  void detach_playback() noexcept;
  /// [main] Waits until a cycle in progress (if any) has ended: afterwards every new cycle sees what
  /// was published before the call.
  void quiesce() const noexcept;
  /// [main] The next cycle is the first one of a new server connection: estimate the frames lost
  /// since the last cycle of the old connection from the monotonic clock.
  void mark_reconnected() noexcept { reconnected_.store(true, std::memory_order_release); }

  // ------------------------------------------------------------------ RT side

  /// [RT] Brackets a whole callback (including fetching the port buffers) for quiesce().
  void begin_cycle() noexcept { cycle_seq_.fetch_add(1, std::memory_order_seq_cst); }
  void end_cycle() noexcept { cycle_seq_.fetch_add(1, std::memory_order_release); }

  /// [RT] One process cycle of `nframes` frames: `inputs` are the capture port buffers (`n_inputs`,
  /// nullptr entries read as silence), `outputs` the playback port buffers (`n_outputs`, always all
  /// written: rendered or zeroed). `frame_time` is the server's frame time at the start of the cycle
  /// (jack_last_frame_time), `now_ns` the monotonic clock (CLOCK_MONOTONIC) at the callback.
  /// Never allocates, locks, logs or blocks.
  void process(const float* const* inputs, std::uint32_t n_inputs, float* const* outputs, std::uint32_t n_outputs,
               std::uint32_t nframes, std::uint32_t frame_time, std::int64_t now_ns) noexcept;

  /// [any, from a libjack notification thread] One xrun reported by the server.
  void count_xrun() noexcept { xruns_.fetch_add(1, std::memory_order_relaxed); }

  // ------------------------------------------------------------------ statistics [any]

  /// The client's frame counter: next frame a cycle will process.
  std::uint64_t frame() const noexcept { return frame_pub_.load(std::memory_order_acquire); }
  std::uint64_t cycles() const noexcept { return cycles_.load(std::memory_order_relaxed); }
  std::uint64_t xruns() const noexcept { return xruns_.load(std::memory_order_relaxed); }
  /// Frames the client did not process (skipped cycles + outages), all reported to ring and scheduler.
  std::uint64_t frames_lost() const noexcept { return frames_lost_.load(std::memory_order_relaxed); }
  /// Cycles that found frames missing since the previous one (skipped cycles, not outages).
  std::uint64_t skip_events() const noexcept { return skip_events_.load(std::memory_order_relaxed); }
  /// Outages the stream resumed from, and the frames the last one cost (estimated).
  std::uint64_t resumes() const noexcept { return resumes_.load(std::memory_order_acquire); }
  std::uint64_t last_resume_gap_frames() const noexcept { return resume_gap_.load(std::memory_order_relaxed); }
  /// Where the stream meets the current server's clock: the client frame `anchor_frame()` was processed
  /// in the cycle that started at server frame time `anchor_frame_time()` (taken at the first cycle of a
  /// connection; both read with the same `anchor_seq()` before and after are consistent).
  std::uint64_t anchor_frame() const noexcept { return anchor_frame_.load(std::memory_order_acquire); }
  std::uint32_t anchor_frame_time() const noexcept { return anchor_frame_time_.load(std::memory_order_acquire); }
  std::uint64_t anchor_seq() const noexcept { return anchor_seq_.load(std::memory_order_acquire); }

 private:
  void capture(AudioRing& ring, const float* const* inputs, std::uint32_t n_inputs, std::uint32_t nframes) noexcept;

  const double sample_rate_hz_;

  // Published by the main side.
  std::atomic<AudioRing*> ring_{nullptr};
  std::atomic<PlaybackScheduler*> scheduler_{nullptr};
  std::atomic<bool> reconnected_{false};
  std::atomic<std::uint64_t> cycle_seq_{0};  // odd while a cycle runs

  // RT-owned state.
  bool have_prev_ = false;
  std::uint32_t next_frame_time_ = 0;  // server frame time where the previous cycle ended
  std::int64_t last_cycle_ns_ = 0;     // monotonic time of the previous cycle
  std::uint64_t frame_ = 0;            // the client's frame counter

  // Published by the RT side.
  std::atomic<std::uint64_t> frame_pub_{0};
  std::atomic<std::uint64_t> cycles_{0};
  std::atomic<std::uint64_t> xruns_{0};
  std::atomic<std::uint64_t> frames_lost_{0};
  std::atomic<std::uint64_t> skip_events_{0};
  std::atomic<std::uint64_t> resumes_{0};
  std::atomic<std::uint64_t> resume_gap_{0};
  std::atomic<std::uint64_t> anchor_frame_{0};
  std::atomic<std::uint32_t> anchor_frame_time_{0};
  std::atomic<std::uint64_t> anchor_seq_{0};
};

}  // namespace locus::hal::jack
