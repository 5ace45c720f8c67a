// See alsa_sink.hpp: the playback loop (RT) and its supervisor (reopen with backoff, logging).
#include "alsa/alsa_sink.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include "number_text.hpp"

namespace locus::hal::alsa {

// ---------------------------------------------------------------- playback loop

PlaybackLoop::PlaybackLoop(snd_pcm_t* pcm, const PcmSetup& setup, PlaybackScheduler& scheduler,
                           AlsaCounters& counters, SpscQueue<AlsaNotice>* notices, std::uint64_t max_frames,
                           double stall_timeout_s, const std::atomic<bool>* stop, double gap_since_s)
    : pcm_(pcm),
      setup_(setup),
      scheduler_(scheduler),
      counters_(counters),
      notices_(notices),
      max_frames_(max_frames),
      stall_timeout_s_(stall_timeout_s),
      stop_(stop),
      gap_since_s_(gap_since_s),
      raw_(setup.period_frames * setup.frame_bytes()),
      silence_(setup.period_frames * setup.frame_bytes()),
      samples_(setup.period_frames * setup.channels) {
  snd_pcm_status_malloc(&status_);
  // Silence in the PCM's format (all our formats are signed or float: zero bytes are silence).
  std::fill(silence_.begin(), silence_.end(), static_cast<unsigned char>(0));
}

PlaybackLoop::~PlaybackLoop() { snd_pcm_status_free(status_); }

void PlaybackLoop::notify(const AlsaNotice& n) noexcept {
  if (notices_ && !notices_->try_push(n)) counters_.notices_dropped.fetch_add(1, std::memory_order_relaxed);
}

void PlaybackLoop::skip(std::uint64_t frames) noexcept {
  if (frames == 0) return;
  scheduler_.skip(frames);
  played_limit_ += frames;
}

bool PlaybackLoop::recover(int err) noexcept {
  const double t_seen = monotonic_s();
  snd_pcm_state_t state = snd_pcm_state(pcm_);
  snd_pcm_uframes_t avail = 0;
  double t_stop = 0.0;
  if (snd_pcm_status(pcm_, status_) >= 0) {
    state = snd_pcm_status_get_state(status_);
    avail = snd_pcm_status_get_avail(status_);
    snd_htimestamp_t t{};
    snd_pcm_status_get_trigger_htstamp(status_, &t);
    t_stop = to_seconds(t);
  }
  const bool stopped_state = state == SND_PCM_STATE_XRUN || state == SND_PCM_STATE_SUSPENDED;
  // The stop must lie between the last successful write and now (see CaptureLoop::recover).
  bool valid = stopped_state && t_stop >= last_data_s_ - 1e-3 && t_stop <= t_seen + 1e-3;
  if (!valid) t_stop = t_seen;
  const std::uint64_t excess = stopped_state && avail > setup_.buffer_frames ? avail - setup_.buffer_frames : 0;

  int r;
  if (err == -ESTRPIPE) {
    counters_.suspends.fetch_add(1, std::memory_order_relaxed);
    r = snd_pcm_resume(pcm_);
    for (int i = 0; r == -EAGAIN && i < 500 && !(stop_ && stop_->load(std::memory_order_acquire)); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      r = snd_pcm_resume(pcm_);
    }
    if (r < 0) r = snd_pcm_prepare(pcm_);
  } else {
    r = snd_pcm_recover(pcm_, err, 1);
  }
  if (r < 0) {
    error_ = r;
    return false;
  }
  // Rendered frames not yet written are dropped: their time has passed.
  const std::uint64_t unplayed = pending_frames_;
  pending_frames_ = 0;
  pending_offset_ = 0;
  std::uint64_t silence = 0;
  if (snd_pcm_state(pcm_) == SND_PCM_STATE_PREPARED) {
    const snd_pcm_sframes_t w = snd_pcm_writei(pcm_, silence_.data(), setup_.period_frames);
    if (w < 0 && w != -EAGAIN) {
      error_ = static_cast<int>(w);
      return false;
    }
    silence = w > 0 ? static_cast<std::uint64_t>(w) : 0;
    if (snd_pcm_state(pcm_) == SND_PCM_STATE_PREPARED && (r = snd_pcm_start(pcm_)) < 0) {
      error_ = r;
      return false;
    }
  }
  const double t_after = monotonic_s();
  double t_restart = 0.0;
  if (snd_pcm_status(pcm_, status_) >= 0) {
    snd_htimestamp_t t{};
    snd_pcm_status_get_trigger_htstamp(status_, &t);
    t_restart = to_seconds(t);
  }
  if (!valid || !(t_restart >= t_stop && t_restart <= t_after + 1e-3)) {
    t_restart = t_after;
    valid = false;
  }
  // Exact: played past the data, the stopped interval, the silence written before the restart, minus
  // rendered frames never written. Without a valid stop timestamp: the device ran out of data one
  // buffer after the last successful write (the buffer was full then, in steady state).
  const std::int64_t stopped_frames =
      valid ? static_cast<std::int64_t>(excess) + std::llround(std::max(0.0, t_restart - t_stop) * setup_.rate_hz)
            : std::llround(std::max(0.0, t_restart - last_data_s_) * setup_.rate_hz) -
                  static_cast<std::int64_t>(setup_.buffer_frames);
  const auto gap = std::max<std::int64_t>(0, stopped_frames) + static_cast<std::int64_t>(silence) -
                   static_cast<std::int64_t>(unplayed);
  const std::uint64_t frame = scheduler_.frame();
  const std::uint64_t lost = gap > 0 ? static_cast<std::uint64_t>(gap) : 0;
  skip(lost);
  if (err == -EPIPE) {
    counters_.xruns.fetch_add(1, std::memory_order_relaxed);
    counters_.xrun_frames_lost.fetch_add(lost, std::memory_order_relaxed);
  }
  notify(AlsaNotice{err == -EPIPE ? AlsaNotice::Kind::Underrun : AlsaNotice::Kind::Suspend, frame, lost, valid});
  last_data_s_ = monotonic_s();
  return true;
}

PlaybackLoop::Status PlaybackLoop::step(int wait_ms) noexcept {
  if (stop_ && stop_->load(std::memory_order_acquire)) return Status::Stopped;
  if (!gap_done_) {
    gap_done_ = true;
    if (gap_since_s_ >= 0.0) {
      const double gap = std::max(0.0, monotonic_s() - gap_since_s_);
      skip(static_cast<std::uint64_t>(std::llround(gap * setup_.rate_hz)));
      counters_.gap_frames_lost.fetch_add(static_cast<std::uint64_t>(std::llround(gap * setup_.rate_hz)),
                                          std::memory_order_relaxed);
    }
    last_data_s_ = monotonic_s();
  }
  if (pending_frames_ == 0) {
    if (max_frames_ != 0 && played_limit_ >= max_frames_) return Status::Ended;
    std::uint64_t want = setup_.period_frames;
    if (max_frames_ != 0) want = std::min<std::uint64_t>(want, max_frames_ - played_limit_);
    const auto frames = static_cast<std::uint32_t>(want);
    scheduler_.render_interleaved(samples_.data(), frames, setup_.channels);
    float_to_raw(setup_.format, samples_.data(), raw_.data(), std::size_t{frames} * setup_.channels);
    pending_offset_ = 0;
    pending_frames_ = frames;
    rendered_ += frames;
    played_limit_ += frames;
  }
  snd_pcm_sframes_t n =
      snd_pcm_writei(pcm_, raw_.data() + pending_offset_ * setup_.frame_bytes(), pending_frames_);
  if (n > 0) {
    const auto frames = static_cast<std::size_t>(n);
    pending_offset_ += frames;
    pending_frames_ -= frames;
    written_ += frames;
    counters_.frames.fetch_add(frames, std::memory_order_relaxed);
    last_data_s_ = monotonic_s();
    return Status::Frames;
  }
  if (n == 0 || n == -EAGAIN) {
    const int w = snd_pcm_wait(pcm_, wait_ms);
    if (w >= 0) {
      if (n == 0 && w == 1) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      if (stall_timeout_s_ > 0.0 && monotonic_s() - last_data_s_ > stall_timeout_s_) {
        error_ = -ETIMEDOUT;
        return Status::DeviceLost;
      }
      return Status::Idle;
    }
    n = w;
  }
  if (n == -EPIPE || n == -ESTRPIPE) return recover(static_cast<int>(n)) ? Status::Recovered : Status::DeviceLost;
  error_ = static_cast<int>(n);
  return Status::DeviceLost;
}

void PlaybackLoop::finish(double timeout_s) noexcept {
  if (snd_pcm_state(pcm_) == SND_PCM_STATE_PREPARED && written_ > 0) snd_pcm_start(pcm_);
  const double deadline = monotonic_s() + timeout_s;
  while (monotonic_s() < deadline && !(stop_ && stop_->load(std::memory_order_acquire))) {
    if (snd_pcm_state(pcm_) != SND_PCM_STATE_RUNNING) break;
    const snd_pcm_sframes_t avail = snd_pcm_avail(pcm_);
    if (avail < 0 || static_cast<snd_pcm_uframes_t>(avail) >= setup_.buffer_frames) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// ---------------------------------------------------------------- sink

AlsaSink::~AlsaSink() { stop(); }

void AlsaSink::open(const Params& params, HostContext& ctx) {
  open(AlsaStreamConfig::from_params(params, SND_PCM_STREAM_PLAYBACK), ctx.log);
}

void AlsaSink::open(const AlsaStreamConfig& config, Logger& log) {
  if (supervisor_.joinable()) throw std::runtime_error("alsa sink: open() while running");
  config_ = config;
  config_.request.stream = SND_PCM_STREAM_PLAYBACK;
  config_.request.role = "alsa sink";
  log_ = &log;
  pcm_ = Pcm::open(config_.request);
  setup_ = pcm_.setup();
  counters_ = std::make_unique<AlsaCounters>();
  finished_.store(false, std::memory_order_release);
  has_error_.store(false, std::memory_order_release);
  error_.clear();
  std::ostringstream os;
  os << "alsa sink: PCM '" << config_.request.pcm << "' open for playback: " << setup_.channels << " ch, "
     << format_name(setup_.format) << ", " << setup_.rate_hz << " Hz, period " << setup_.period_frames
     << " frames, buffer " << setup_.buffer_frames << " frames";
  log.info(os.str());
}

void AlsaSink::start(PlaybackScheduler& scheduler) {
  if (!log_) throw std::runtime_error("alsa sink: start() before open()");
  if (supervisor_.joinable()) throw std::runtime_error("alsa sink: start() while already running");
  if (std::abs(scheduler.sample_rate_hz() - config_.request.rate_hz) > 1e-6)
    throw std::runtime_error("alsa sink: the scheduler runs at " + num(scheduler.sample_rate_hz()) + " Hz but PCM '" +
                             config_.request.pcm + "' at " + std::to_string(config_.request.rate_hz) + " Hz");
  if (!pcm_) {
    pcm_ = Pcm::open(config_.request);
    setup_ = pcm_.setup();
  }
  scheduler_ = &scheduler;
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  supervisor_ = std::thread([this] { supervise(); });
}

void AlsaSink::stop() {
  stop_.store(true, std::memory_order_release);
  if (!supervisor_.joinable()) return;
  supervisor_.join();
  pcm_.close();
  drain_notices();
  const AlsaCounters& c = *counters_;
  std::ostringstream os;
  os << "alsa sink: PCM '" << config_.request.pcm << "': " << c.frames.load() << " frames played, " << c.xruns.load()
     << " underruns (" << c.xrun_frames_lost.load() << " frames skipped), " << c.suspends.load() << " suspends, "
     << c.device_losses.load() << " device losses, " << c.reconnects.load() << " reconnects";
  if (c.notices_dropped.load() != 0) os << ", " << c.notices_dropped.load() << " notices not logged";
  log_->info(os.str());
}

std::string AlsaSink::error() const {
  if (!has_error_.load(std::memory_order_acquire)) return {};
  return error_;
}

void AlsaSink::drain_notices() {
  AlsaNotice n;
  while (notices_->try_pop(n)) {
    std::ostringstream os;
    os << "alsa sink: PCM '" << config_.request.pcm << "': "
       << (n.kind == AlsaNotice::Kind::Suspend ? "suspend" : "underrun") << " at playback frame " << n.frame << ", "
       << n.frames_lost << " frames skipped (recovered"
       << (n.timestamps_valid ? ", from the PCM's timestamps)" : ", estimated on the host clock)");
    log_->warn(os.str());
  }
}

bool AlsaSink::sleep_unless_stopped(double seconds) {
  const double until = monotonic_s() + seconds;
  while (!stop_.load(std::memory_order_acquire)) {
    const double left = until - monotonic_s();
    if (left <= 0) return true;
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(left, 0.02)));
    drain_notices();
  }
  return false;
}

void AlsaSink::supervise() {
  const std::string pcm_name = "PCM '" + config_.request.pcm + "'";
  double gap_since = -1.0;
  std::uint32_t failures = 0;
  double backoff = config_.retry_backoff_s;
  std::uint64_t done_total = 0;  // frames counted against max_frames (played + skipped)
  for (;;) {
    if (config_.max_frames != 0 && done_total >= config_.max_frames) break;
    const std::uint64_t remaining = config_.max_frames == 0 ? 0 : config_.max_frames - done_total;
    const std::uint64_t frame0 = scheduler_->frame();
    PlaybackLoop loop(pcm_.get(), setup_, *scheduler_, *counters_, notices_.get(), remaining, config_.stall_timeout_s,
                      &stop_, gap_since);
    std::atomic<bool> done{false};
    PlaybackLoop::Status status = PlaybackLoop::Status::Stopped;
    bool rt_ok = true;
    std::thread playback([&] {
      rt_ok = set_rt_priority(config_.rt_priority);
      for (;;) {
        status = loop.step(20);
        if (status == PlaybackLoop::Status::Ended || status == PlaybackLoop::Status::DeviceLost ||
            status == PlaybackLoop::Status::Stopped)
          break;
      }
      done.store(true, std::memory_order_release);
    });
    while (!done.load(std::memory_order_acquire)) {
      drain_notices();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    playback.join();
    drain_notices();
    if (!rt_ok)
      log_->warn("alsa sink: could not make the playback thread SCHED_FIFO " + std::to_string(config_.rt_priority) +
                 " (needs CAP_SYS_NICE or an rtprio limit); running at normal priority");
    done_total += scheduler_->frame() - frame0;
    if (status == PlaybackLoop::Status::Stopped) break;
    if (status == PlaybackLoop::Status::Ended) {
      const double buffer_s = static_cast<double>(setup_.buffer_frames) / setup_.rate_hz;
      loop.finish(buffer_s + 1.0);
      log_->info("alsa sink: " + pcm_name + ": max_frames (" + std::to_string(config_.max_frames) + ") played");
      break;
    }
    counters_->device_losses.fetch_add(1, std::memory_order_relaxed);
    if (loop.frames_played() > 0) {
      failures = 0;
      backoff = config_.retry_backoff_s;
    }
    const std::string why = loop.error() == -ETIMEDOUT
                                ? "took no data for " + num(config_.stall_timeout_s) + " s (stall_timeout_s)"
                                : alsa_error_text(loop.error());
    pcm_.close();
    gap_since = loop.last_data_s();
    bool reopened = false;
    std::string last_failure;
    while (!reopened && failures < config_.retry_max && !stop_.load(std::memory_order_acquire)) {
      ++failures;
      log_->warn("alsa sink: " + pcm_name + " lost (" + why + ") at playback frame " +
                 std::to_string(scheduler_->frame()) + "; reopening in " + num(backoff) + " s (attempt " +
                 std::to_string(failures) + " of " + std::to_string(config_.retry_max) + ")");
      if (!sleep_unless_stopped(backoff)) break;
      backoff = std::min(backoff * 2.0, config_.retry_backoff_max_s);
      try {
        pcm_ = Pcm::open(config_.request);
        reopened = true;
      } catch (const std::exception& e) {
        last_failure = e.what();
        log_->warn(std::string("alsa sink: reopen attempt ") + std::to_string(failures) + " failed: " + e.what());
      }
    }
    if (stop_.load(std::memory_order_acquire)) break;
    if (!reopened) {
      error_ = "alsa sink: " + pcm_name + " lost (" + why + ") at playback frame " +
               std::to_string(scheduler_->frame()) +
               (config_.retry_max == 0 ? " (retry_max is 0: no reopen attempt)"
                                       : " and not reopened after " + std::to_string(failures) +
                                             " attempt(s); last attempt: " + last_failure);
      has_error_.store(true, std::memory_order_release);
      log_->error(error_);
      break;
    }
    setup_ = pcm_.setup();
    counters_->reconnects.fetch_add(1, std::memory_order_relaxed);
    log_->info("alsa sink: " + pcm_name + " reopened after " + std::to_string(failures) +
               " attempt(s); the gap is skipped on the playback clock");
  }
  finished_.store(true, std::memory_order_release);
}

}  // namespace locus::hal::alsa
