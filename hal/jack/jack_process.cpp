// JackProcessor: the JACK process-callback body (see jack_process.hpp for the clock model).
#include "jack/jack_process.hpp"

#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

namespace locus::hal::jack {

// ---------------------------------------------------------------- main side

void JackProcessor::attach_capture(AudioRing* ring) noexcept { ring_.store(ring, std::memory_order_seq_cst); }

void JackProcessor::detach_capture() noexcept {
  ring_.store(nullptr, std::memory_order_seq_cst);
  quiesce();
}

void JackProcessor::attach_playback(PlaybackScheduler* scheduler) noexcept {
  scheduler_.store(scheduler, std::memory_order_seq_cst);
}

void JackProcessor::detach_playback() noexcept {
  scheduler_.store(nullptr, std::memory_order_seq_cst);
  quiesce();
}

void JackProcessor::quiesce() const noexcept {
  // The pointer stores above and this load are seq_cst, as is the RT side's begin_cycle(): a cycle
  // that began before this load is seen as odd here (and waited for); one that begins after it sees
  // the stores. A cycle never blocks, so the wait is one period at most.
  const std::uint64_t s = cycle_seq_.load(std::memory_order_seq_cst);
  if ((s & 1u) == 0) return;
  while (cycle_seq_.load(std::memory_order_acquire) == s) std::this_thread::sleep_for(std::chrono::microseconds(200));
}

// ---------------------------------------------------------------- RT side

void JackProcessor::capture(AudioRing& ring, const float* const* inputs, std::uint32_t n_inputs,
                            std::uint32_t nframes) noexcept {
  const std::uint32_t ch = ring.channels();
  AudioRing::WriteSpan span = ring.write_acquire(nframes);
  std::size_t done = 0;
  for (const AudioRing::Segment& seg : {span.first, span.second}) {
    for (std::uint32_t c = 0; c < ch; ++c) {
      const float* src = c < n_inputs ? inputs[c] : nullptr;
      float* dst = seg.data + c;
      if (src == nullptr) {
        for (std::size_t i = 0; i < seg.frames; ++i) dst[i * ch] = 0.0f;
      } else {
        src += done;
        for (std::size_t i = 0; i < seg.frames; ++i) dst[i * ch] = src[i];
      }
    }
    done += seg.frames;
  }
  ring.write_commit(span.frames());  // a refused commit reports its own loss
  if (span.frames() < nframes) ring.write_lost(nframes - span.frames());  // ring full: an overrun
}

void JackProcessor::process(const float* const* inputs, std::uint32_t n_inputs, float* const* outputs,
                            std::uint32_t n_outputs, std::uint32_t nframes, std::uint32_t frame_time,
                            std::int64_t now_ns) noexcept {
  // 1. Frames missing since the previous cycle.
  std::uint64_t lost = 0;
  bool new_connection = !have_prev_;
  if (reconnected_.exchange(false, std::memory_order_acq_rel)) {
    new_connection = true;
    if (have_prev_) {
      // Data of this cycle covers [now - nframes/fs, now]; the last cycle's ended at last_cycle_ns_.
      const double gap = static_cast<double>(now_ns - last_cycle_ns_) * 1e-9 * sample_rate_hz_ -
                         static_cast<double>(nframes);
      lost = gap > 0.0 ? static_cast<std::uint64_t>(std::llround(gap)) : 0;
      resume_gap_.store(lost, std::memory_order_relaxed);
      resumes_.fetch_add(1, std::memory_order_release);
    }
  } else if (have_prev_) {
    const std::uint32_t d = frame_time - next_frame_time_;  // modulo 2^32: the frame time wraps
    if (d != 0 && d < 0x80000000u) {  // ahead: skipped cycles (behind would be a server clock reset)
      lost = d;
      skip_events_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  have_prev_ = true;
  next_frame_time_ = frame_time + nframes;
  last_cycle_ns_ = now_ns;
  if (lost != 0) {
    frame_ += lost;
    frames_lost_.fetch_add(lost, std::memory_order_relaxed);
  }
  if (new_connection) {
    anchor_seq_.fetch_add(1, std::memory_order_acq_rel);  // odd: updating
    anchor_frame_.store(frame_, std::memory_order_relaxed);
    anchor_frame_time_.store(frame_time, std::memory_order_relaxed);
    anchor_seq_.fetch_add(1, std::memory_order_release);
  }

  // 2. Capture: align the ring to the client's counter (losses, a late start), then copy.
  if (AudioRing* ring = ring_.load(std::memory_order_seq_cst)) {
    const std::uint64_t pf = ring->producer_frame();
    if (pf < frame_) ring->write_lost(static_cast<std::size_t>(frame_ - pf));
    capture(*ring, inputs, n_inputs, nframes);
  }

  // 3. Playback: align the scheduler the same way, then render (or play silence).
  if (PlaybackScheduler* sched = scheduler_.load(std::memory_order_seq_cst)) {
    const std::uint64_t sf = sched->frame();
    if (sf < frame_) sched->skip(frame_ - sf);
    sched->render_planar(outputs, nframes, n_outputs);
  } else {
    for (std::uint32_t c = 0; c < n_outputs; ++c)
      if (outputs[c] != nullptr) std::memset(outputs[c], 0, sizeof(float) * nframes);
  }

  frame_ += nframes;
  frame_pub_.store(frame_, std::memory_order_release);
  cycles_.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace locus::hal::jack
