// `alsa` playback sink: plays what a PlaybackScheduler renders through any ALSA PCM by name.
//
// The playback thread runs PlaybackLoop::step() only: it renders one period with
// PlaybackScheduler::render_interleaved, converts it to the PCM's format (clipping) and writes it
// (non-blocking, waits of at most 20 ms, so stop() returns promptly). The scheduler's frame counter is
// the device's playback clock: frame 0 is the first frame the device plays.
//
// Underrun (-EPIPE) or suspend (-ESTRPIPE): the PCM stopped at its trigger timestamp t_stop after
// playing `excess` = avail - buffer_size frames past the data (garbage/silence); the loop recovers
// (snd_pcm_recover), writes one period of silence, restarts (trigger timestamp t_restart) and calls
// scheduler.skip(excess + round((t_restart - t_stop) * rate) + silence - unplayed), where `unplayed`
// are frames already rendered but not written before the underrun (they are dropped). The next
// rendered frame then plays at the device time its frame number says. Counted (xruns()) and logged
// by the supervisor thread from a lock-free notice queue, never from the playback thread.
//
// Device loss: like the source (alsa_source.hpp): the supervisor reopens with backoff up to
// retry_max, then skip()s the gap measured on the monotonic clock, or ends with error().
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "alsa/alsa_source.hpp"
#include "locus/playback.hpp"

namespace locus::hal::alsa {

/// The playback thread's work over one open, prepared PCM. Buffers allocated in the constructor;
/// step() is [RT]. Exposed for tests.
class PlaybackLoop {
 public:
  enum class Status : std::uint8_t { Frames, Idle, Recovered, Ended, DeviceLost, Stopped };

  /// `max_frames`: frames to play in total (0 = no limit). `gap_since_s` >= 0: playback was
  /// interrupted since that monotonic time; the gap is skip()ped when this loop starts.
  PlaybackLoop(snd_pcm_t* pcm, const PcmSetup& setup, PlaybackScheduler& scheduler, AlsaCounters& counters,
               SpscQueue<AlsaNotice>* notices, std::uint64_t max_frames, double stall_timeout_s,
               const std::atomic<bool>* stop, double gap_since_s = -1.0);
  ~PlaybackLoop();
  PlaybackLoop(const PlaybackLoop&) = delete;
  PlaybackLoop& operator=(const PlaybackLoop&) = delete;

  /// [RT] One write (or one wait of at most `wait_ms`).
  Status step(int wait_ms) noexcept;
  /// [supervisor] After Ended: waits (at most `timeout_s`) until the device has played what was
  /// written, starting it if it never filled its buffer.
  void finish(double timeout_s) noexcept;

  std::uint64_t frames_played() const noexcept { return written_; }  ///< frames written to the PCM
  std::uint64_t frames_rendered() const noexcept { return rendered_; }
  int error() const noexcept { return error_; }
  double last_data_s() const noexcept { return last_data_s_; }

 private:
  bool recover(int err) noexcept;
  void skip(std::uint64_t frames) noexcept;
  void notify(const AlsaNotice& n) noexcept;

  snd_pcm_t* pcm_;
  PcmSetup setup_;
  PlaybackScheduler& scheduler_;
  AlsaCounters& counters_;
  SpscQueue<AlsaNotice>* notices_;
  std::uint64_t max_frames_;
  double stall_timeout_s_;
  const std::atomic<bool>* stop_;
  double gap_since_s_;
  std::vector<unsigned char> raw_;
  std::vector<unsigned char> silence_;
  std::vector<float> samples_;
  snd_pcm_status_t* status_ = nullptr;
  std::size_t pending_offset_ = 0;  // frames of raw_ already written
  std::size_t pending_frames_ = 0;  // frames of raw_ still to write
  std::uint64_t rendered_ = 0;
  std::uint64_t written_ = 0;
  std::uint64_t played_limit_ = 0;  // frames counted against max_frames (rendered + skipped)
  double last_data_s_ = 0.0;
  bool gap_done_ = false;
  int error_ = 0;
};

class AlsaSink final : public AudioSink {
 public:
  AlsaSink() = default;
  ~AlsaSink() override;

  void open(const Params& params, HostContext& ctx) override;
  void open(const AlsaStreamConfig& config, Logger& log);
  std::uint32_t channels() const override { return config_.request.channels; }
  double sample_rate_hz() const override { return config_.request.rate_hz; }
  void start(PlaybackScheduler& scheduler) override;
  void stop() override;
  std::uint64_t xruns() const noexcept override { return counters_->xruns.load(std::memory_order_relaxed); }
  std::string error() const override;

  /// [any] True once max_frames were played (and drained) or playback ended with an error.
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }
  const AlsaCounters& counters() const noexcept { return *counters_; }
  const PcmSetup& setup() const noexcept { return setup_; }

 private:
  void supervise();
  void drain_notices();
  bool sleep_unless_stopped(double seconds);

  AlsaStreamConfig config_;
  Logger* log_ = nullptr;
  Pcm pcm_;
  PcmSetup setup_;
  PlaybackScheduler* scheduler_ = nullptr;
  std::unique_ptr<AlsaCounters> counters_ = std::make_unique<AlsaCounters>();
  std::unique_ptr<SpscQueue<AlsaNotice>> notices_ = std::make_unique<SpscQueue<AlsaNotice>>(256);
  std::thread supervisor_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<bool> has_error_{false};
  std::string error_;
};

}  // namespace locus::hal::alsa
