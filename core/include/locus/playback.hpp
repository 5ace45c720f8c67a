// Playback: the hand-over from the main thread (which renders scheduled sounds) to a playback
// backend's real-time callback (ALSA playback thread, JACK process()), and the backend interface.
//
//   Emitter::schedule (plugin, [main]) -> render samples (main) -> PlaybackScheduler::submit
//        --SPSC queue of clips--> PlaybackScheduler::render (RT: mixes active clips into the output)
//        --SPSC queue of finished clips--> PlaybackScheduler::reclaim (main: frees them)
//
// The RT side never allocates or frees: clips are allocated by submit() and freed by reclaim().
// The scheduler owns the playback frame counter: render() advances it by the frames it produced and
// skip() by frames the device lost (an underrun/xrun the backend reports), so a schedule in frames
// stays true to the device's own playback clock.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "locus/emitter.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"
#include "locus/spsc_queue.hpp"

namespace locus {

class PlaybackScheduler {
 public:
  /// `max_pending`: clips that may be queued or playing at once (fixed; rounded up to a power of two).
  explicit PlaybackScheduler(double sample_rate_hz, std::uint32_t max_pending = 64);
  ~PlaybackScheduler();
  PlaybackScheduler(const PlaybackScheduler&) = delete;
  PlaybackScheduler& operator=(const PlaybackScheduler&) = delete;

  /// [main] Queues mono `samples` to start at playback frame `start_frame` on every output channel.
  /// Returns false (nothing queued) when `max_pending` clips are pending. Frees finished clips first.
  bool submit(std::vector<float> samples, std::uint64_t start_frame);
  /// [main] Frees clips the RT side has finished with. Returns how many.
  std::size_t reclaim();

  /// [RT] Renders the next `frames` frames into `out` (interleaved, `channels` per frame), zeroing
  /// first, and advances the frame counter. Never allocates, locks or blocks.
  void render_interleaved(float* out, std::uint32_t frames, std::uint32_t channels) noexcept;
  /// [RT] Same into planar buffers (`channels` pointers of `frames` floats; nullptr entries skipped).
  void render_planar(float* const* out, std::uint32_t frames, std::uint32_t channels) noexcept;
  /// [RT] Advances the frame counter by `frames` the device lost (xrun/underrun) without rendering;
  /// parts of clips in that span are counted as cut.
  void skip(std::uint64_t frames) noexcept;

  /// [any] The next frame render() will produce.
  std::uint64_t frame() const noexcept { return frame_.load(std::memory_order_acquire); }
  double sample_rate_hz() const noexcept { return sample_rate_hz_; }
  /// [any] Clips whose start frame had already passed when the RT side took them, or that lost
  /// frames to skip(): their beginning was cut.
  std::uint64_t late_clips() const noexcept { return late_.load(std::memory_order_relaxed); }
  /// [any] Clips played to their end.
  std::uint64_t clips_played() const noexcept { return played_.load(std::memory_order_relaxed); }

 private:
  struct Clip {
    std::vector<float> samples;
    std::uint64_t start_frame = 0;
    bool cut = false;  ///< counted in late_ (its beginning was missed or it lost frames to skip())
  };
  template <typename Write>
  void render_common(std::uint32_t frames, Write&& write) noexcept;
  void take_new_clips() noexcept;

  double sample_rate_hz_;
  std::uint32_t max_pending_;
  SpscQueue<Clip*> incoming_;
  SpscQueue<Clip*> finished_;
  std::vector<Clip*> active_;        // RT-owned, capacity max_pending_, never reallocates
  std::size_t active_count_ = 0;
  std::atomic<std::uint64_t> frame_{0};
  std::atomic<std::uint64_t> late_{0};
  std::atomic<std::uint64_t> played_{0};
  std::atomic<std::uint32_t> outstanding_{0};  // submitted and not yet reclaimed
};

/// The Emitter a device's plugins get (HostContext::emitter) when the device has a `playback:`
/// section: checks the signal (check_signal), renders it with the DSP toolbox and submits it.
class SchedulerEmitter final : public Emitter {
 public:
  explicit SchedulerEmitter(PlaybackScheduler& scheduler) : scheduler_(scheduler) {}
  bool schedule(const SignalSpec& signal, std::uint64_t start_frame, double gain, std::string* error) override;
  std::uint64_t playback_frame() const noexcept override { return scheduler_.frame(); }
  double sample_rate_hz() const noexcept override { return scheduler_.sample_rate_hz(); }
  std::uint64_t late_emissions() const noexcept override { return scheduler_.late_clips() + refused_; }

 private:
  PlaybackScheduler& scheduler_;
  std::uint64_t refused_ = 0;
};

/// A HAL playback backend (ALSA PCM, JACK output ports, ...). Host-side, like AudioSource.
class AudioSink {
 public:
  virtual ~AudioSink() = default;
  /// [main] Validated params; decide channels and rate. Throw std::runtime_error naming what failed.
  virtual void open(const Params& params, HostContext& ctx) = 0;
  virtual std::uint32_t channels() const = 0;
  virtual double sample_rate_hz() const = 0;
  /// [main] Starts pulling from `scheduler` on the backend's RT thread or callback (which calls only
  /// render_*() and skip()). Must return quickly.
  virtual void start(PlaybackScheduler& scheduler) = 0;
  /// [main] Stops; idempotent. After it returns nothing calls the scheduler.
  virtual void stop() = 0;
  /// [any] Underruns/xruns seen so far (each also reported to skip() with the frames lost).
  virtual std::uint64_t xruns() const noexcept { return 0; }
  /// [main] Error that stopped playback ("" if none).
  virtual std::string error() const { return {}; }
};

}  // namespace locus
