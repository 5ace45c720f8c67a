// `alsa` audio source: capture from any ALSA PCM by name (hw:1,0, plughw:1,0, default, a PCM defined
// in an extra config file) into the device's AudioRing.
//
// Threads:
//  - the capture thread runs CaptureLoop::step() only: snd_pcm_readi (non-blocking) into a
//    preallocated raw buffer, conversion to float, AudioRing::write; on an overrun (-EPIPE) or a
//    suspend (-ESTRPIPE) it recovers (snd_pcm_recover / snd_pcm_resume), counts the episode, reports
//    the exact frames lost with AudioRing::write_lost so the stream clock stays true, and pushes a
//    notice into a lock-free queue. It never allocates, logs or blocks longer than one poll timeout
//    (20 ms), so stop() returns promptly whatever the device does.
//  - the supervisor thread (not real-time) starts the capture thread, drains the notice queue into
//    the log every 50 ms, and on a device loss (-ENODEV, -EBADFD, -EIO, any other read error, or no
//    data for stall_timeout_s) closes the PCM, reopens it with exponential backoff up to retry_max
//    times, and reports the gap as lost frames when capture resumes; if it cannot, the stream ends
//    with error() naming the PCM and the errno text.
//
// Frames lost in an overrun, exactly (see docs/hal-alsa.md): at the xrun the PCM stops; its status
// then holds the stop time (trigger timestamp) and `avail` = frames the device captured that were not
// read (hw_ptr - appl_ptr, which may exceed the buffer size: those frames were overwritten). After
// snd_pcm_recover and snd_pcm_start, the status holds the restart time. Lost frames =
// avail + round((t_restart - t_stop) * rate): the device clock runs only for that short interval
// between two timestamps of the same clock, so no drift accumulates. A stop timestamp is valid only if
// it lies between the last successful read and the moment the loop saw the error; plugin PCMs that do
// not stamp the xrun (ioplug, e.g. `jack`, keeps its start time and reports avail 0) fall back to the
// host clock: every frame since the last successful read is lost, round((t_restart - t_last_read) *
// rate) (within about a period; the notice says "estimated on the host clock").
#pragma once

#include <alsa/asoundlib.h>

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "alsa/alsa_format.hpp"
#include "alsa/alsa_pcm.hpp"
#include "locus/audio_source.hpp"
#include "locus/params.hpp"
#include "locus/spsc_queue.hpp"

namespace locus::hal::alsa {

/// Validated settings of the source (and, without max_frames' meaning, of the sink).
struct AlsaStreamConfig {
  PcmRequest request;
  std::uint64_t max_frames = 0;      ///< 0 = unlimited
  std::uint32_t retry_max = 10;      ///< reopen attempts after a device loss (0 = none)
  double retry_backoff_s = 0.5;      ///< first backoff, doubled per attempt
  double retry_backoff_max_s = 8.0;  ///< backoff cap
  double stall_timeout_s = 2.0;      ///< no data for this long = device lost (0 = never)
  int rt_priority = 0;               ///< SCHED_FIFO priority of the RT thread (0 = leave the default)

  /// Reads every key of alsa_source_schema()/alsa_sink_schema(); throws std::runtime_error naming
  /// the key ("alsa source: sample_rate_hz must be a whole number of Hz (got 44100.5)").
  static AlsaStreamConfig from_params(const Params& params, snd_pcm_stream_t stream);
};

const ParamSchema& alsa_source_schema();
/// The sink's schema (same keys; max_frames = frames to play before draining and stopping).
const ParamSchema& alsa_sink_schema();

/// What the RT side tells the logging side (trivially copyable, through an SpscQueue).
struct AlsaNotice {
  enum class Kind : std::uint8_t { Overrun, Underrun, Suspend };
  Kind kind = Kind::Overrun;
  std::uint64_t frame = 0;        ///< stream frame at which it happened
  std::uint64_t frames_lost = 0;  ///< frames reported lost for it
  bool timestamps_valid = true;   ///< false: lost frames from the loop's clock, not PCM timestamps
};

/// Counters readable from any thread.
struct AlsaCounters {
  std::atomic<std::uint64_t> frames{0};          ///< frames read (or played)
  std::atomic<std::uint64_t> xruns{0};           ///< overruns/underruns recovered
  std::atomic<std::uint64_t> xrun_frames_lost{0};
  std::atomic<std::uint64_t> suspends{0};
  std::atomic<std::uint64_t> device_losses{0};
  std::atomic<std::uint64_t> reconnects{0};
  std::atomic<std::uint64_t> gap_frames_lost{0};  ///< frames reported lost across device losses
  std::atomic<std::uint64_t> notices_dropped{0};
};

/// The capture thread's work over one open, prepared PCM. Buffers are allocated in the constructor;
/// step() is [RT]. Exposed for tests (RT-safety proof, xrun accounting).
class CaptureLoop {
 public:
  enum class Status : std::uint8_t { Frames, Idle, Recovered, Ended, DeviceLost, Stopped };

  /// `max_frames`: stream frames (read or lost) after which step() returns Ended (0 = no limit).
  /// `notices` may be nullptr. `gap_since_s` >= 0: the stream had a gap since that monotonic time;
  /// the frames until this loop's start are reported lost before the first frame.
  CaptureLoop(snd_pcm_t* pcm, const PcmSetup& setup, AudioRing& ring, AlsaCounters& counters,
              SpscQueue<AlsaNotice>* notices, std::uint64_t max_frames, double stall_timeout_s,
              const std::atomic<bool>* stop, double gap_since_s = -1.0);
  ~CaptureLoop();
  CaptureLoop(const CaptureLoop&) = delete;
  CaptureLoop& operator=(const CaptureLoop&) = delete;

  /// [RT] One read (or one wait of at most `wait_ms`). Never allocates, logs or locks (libasound
  /// itself may take the PCM's own uncontended mutex on plugin PCMs).
  Status step(int wait_ms) noexcept;

  std::uint64_t produced() const noexcept { return produced_; }       ///< stream frames (read + lost)
  std::uint64_t frames_read() const noexcept { return read_; }
  int error() const noexcept { return error_; }                        ///< why DeviceLost (negative errno)
  double last_data_s() const noexcept { return last_data_s_; }        ///< monotonic time of the last frames
  /// [main, before the first step()] On the first frames read, publish into `out` the CLOCK_MONOTONIC
  /// time of stream frame 0, given that this loop's first frame is stream frame `base_frames`: from the
  /// PCM's htimestamp (monotonic, see alsa_pcm.cpp) and the frames captured by then (read + avail);
  /// without a usable timestamp, from the loop's clock at that moment. nullptr: publish nothing.
  void publish_frame_zero(std::atomic<double>* out, std::uint64_t base_frames) noexcept {
    frame_zero_out_ = out;
    base_frames_ = base_frames;
  }

 private:
  bool start() noexcept;
  bool recover(int err) noexcept;
  void notify(const AlsaNotice& n) noexcept;
  double status_trigger_s(snd_pcm_state_t* state, snd_pcm_uframes_t* avail) noexcept;
  void lose(std::uint64_t frames) noexcept;
  void estimate_frame_zero(std::uint64_t frames_read_now) noexcept;

  snd_pcm_t* pcm_;
  PcmSetup setup_;
  AudioRing& ring_;
  AlsaCounters& counters_;
  SpscQueue<AlsaNotice>* notices_;
  std::uint64_t max_frames_;
  double stall_timeout_s_;
  const std::atomic<bool>* stop_;
  double gap_since_s_;
  std::vector<unsigned char> raw_;
  std::vector<float> samples_;
  snd_pcm_status_t* status_ = nullptr;
  bool started_ = false;
  std::uint64_t produced_ = 0;
  std::uint64_t read_ = 0;
  double last_data_s_ = 0.0;
  int error_ = 0;
  std::atomic<double>* frame_zero_out_ = nullptr;
  std::uint64_t base_frames_ = 0;
};

class AlsaSource final : public AudioSource {
 public:
  AlsaSource() = default;
  ~AlsaSource() override;

  /// [main] Validates the params and opens the PCM (so a bad name, rate or format fails here).
  void open(const Params& params, HostContext& ctx) override;
  /// Same from a ready config; `log` must outlive the source.
  void open(const AlsaStreamConfig& config, Logger& log);
  std::uint32_t channels() const override { return config_.request.channels; }
  double sample_rate_hz() const override { return config_.request.rate_hz; }
  bool live() const override { return true; }
  void start(AudioRing& ring) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override;
  /// Stream frame 0's CLOCK_MONOTONIC time, set from the first frames read (CaptureLoop::
  /// publish_frame_zero); a reopen after a device loss keeps it (the gap is counted as lost frames).
  double frame_zero_monotonic_s() const noexcept override { return frame_zero_s_.load(std::memory_order_acquire); }

  /// [any] Counters (xruns, frames lost, device losses, reconnects).
  const AlsaCounters& counters() const noexcept { return *counters_; }
  /// [main] What the PCM was configured to (after open()).
  const PcmSetup& setup() const noexcept { return setup_; }

 private:
  void supervise();
  void drain_notices();
  bool sleep_unless_stopped(double seconds);

  AlsaStreamConfig config_;
  Logger* log_ = nullptr;
  Pcm pcm_;
  PcmSetup setup_;
  AudioRing* ring_ = nullptr;
  std::unique_ptr<AlsaCounters> counters_ = std::make_unique<AlsaCounters>();
  std::unique_ptr<SpscQueue<AlsaNotice>> notices_ = std::make_unique<SpscQueue<AlsaNotice>>(256);
  std::thread supervisor_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<bool> has_error_{false};
  std::string error_;  // written by the supervisor before has_error_ (release)
  std::atomic<double> frame_zero_s_{std::numeric_limits<double>::quiet_NaN()};
};

}  // namespace locus::hal::alsa
