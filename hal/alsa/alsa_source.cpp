// See alsa_source.hpp: the capture loop (RT), the supervisor (reopen with backoff, logging) and the
// parameter schemas of the `alsa` source and sink.
#include "alsa/alsa_source.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include "number_text.hpp"

namespace locus::hal::alsa {

namespace {

ParamSchema make_schema(bool capture) {
  ParamSchema s;
  s.push_back(string_param("pcm", std::string("default"),
                           "ALSA PCM name: hw:1,0, plughw:1,0 (resamples/converts), default, or a PCM defined in "
                           "config_file."));
  s.push_back(int_param("channels", std::int64_t{1}, 1, 32, "", "Number of channels."));
  s.push_back(enum_param("format", std::string("auto"), format_choices(),
                         "Sample format: auto (tries float, s32, s24, s24_3, s16), s16, s24 (S24_LE in 32 bits), "
                         "s24_3 (packed S24_3LE), s32, float."));
  s.push_back(float_param("sample_rate_hz", 44100.0, 1000.0, 768000.0, "Hz",
                          "Exact sample rate asked of the PCM (a whole number of Hz); a PCM that cannot do it is "
                          "refused (plughw: resamples)."));
  s.push_back(int_param("period_frames", std::int64_t{256}, 16, 65536, "",
                        "Period size asked of the PCM (the nearest it accepts is used)."));
  s.push_back(int_param("periods", std::int64_t{4}, 2, 64, "", "Periods per buffer."));
  s.push_back(string_param("config_file", std::string(""),
                           "Extra ALSA configuration file loaded on top of the system one (defines PCMs without "
                           "touching /etc); \"\" = none."));
  s.push_back(int_param("max_frames", std::int64_t{0}, 0, 9.0e18, "",
                        capture ? "Stop after this many stream frames (0 = unlimited); needed for `type file` infile "
                                  "PCMs, which repeat stale frames past the end of the file."
                                : "Stop after playing this many frames (drained first; 0 = unlimited)."));
  s.push_back(int_param("retry_max", std::int64_t{10}, 0, 100000, "",
                        "Reopen attempts after a device loss (unplug) before the stream ends with an error "
                        "(0 = none)."));
  s.push_back(float_param("retry_backoff_s", 0.5, 0.001, 3600.0, "s",
                          "Wait before the first reopen attempt; doubled after each failed attempt."));
  s.push_back(float_param("retry_backoff_max_s", 8.0, 0.001, 3600.0, "s", "Cap of the reopen backoff."));
  s.push_back(float_param("stall_timeout_s", 2.0, 0.0, 3600.0, "s",
                          "A running PCM that gives no data (capture) or takes none (playback) for this long is "
                          "treated as lost (0 = never)."));
  s.push_back(int_param("rt_priority", std::int64_t{0}, 0, 99, "",
                        "SCHED_FIFO priority of the audio thread (0 = normal scheduling; needs CAP_SYS_NICE)."));
  return s;
}

void sleep_s(double seconds) { std::this_thread::sleep_for(std::chrono::duration<double>(seconds)); }

}  // namespace

const ParamSchema& alsa_source_schema() {
  static const ParamSchema schema = make_schema(true);
  return schema;
}

const ParamSchema& alsa_sink_schema() {
  static const ParamSchema schema = make_schema(false);
  return schema;
}

AlsaStreamConfig AlsaStreamConfig::from_params(const Params& p, snd_pcm_stream_t stream) {
  AlsaStreamConfig c;
  const std::string role = stream == SND_PCM_STREAM_CAPTURE ? "alsa source" : "alsa sink";
  auto fail = [&](const std::string& m) { throw std::runtime_error(role + ": " + m); };
  try {
    c.request.role = role;
    c.request.stream = stream;
    c.request.pcm = p.get_string("pcm");
    if (c.request.pcm.empty()) fail("pcm is empty (expected a PCM name such as default, hw:1,0, plughw:1,0)");
    const std::int64_t ch = p.get_int("channels");
    if (ch < 1 || ch > 32) fail("channels must be 1..32 (got " + std::to_string(ch) + ")");
    c.request.channels = static_cast<std::uint32_t>(ch);
    c.request.format = p.get_string("format");
    try {
      (void)formats_for_name(c.request.format);
    } catch (const std::invalid_argument& e) {
      fail(e.what());
    }
    const double rate = p.get_float("sample_rate_hz");
    if (!std::isfinite(rate) || rate < 1000 || rate > 768000 || rate != std::floor(rate))
      fail("sample_rate_hz must be a whole number of Hz in [1000, 768000] (got " + num(rate) + ")");
    c.request.rate_hz = static_cast<std::uint32_t>(rate);
    const std::int64_t period = p.get_int("period_frames");
    if (period < 16 || period > 65536) fail("period_frames must be 16..65536 (got " + std::to_string(period) + ")");
    c.request.period_frames = static_cast<std::uint32_t>(period);
    const std::int64_t periods = p.get_int("periods");
    if (periods < 2 || periods > 64) fail("periods must be 2..64 (got " + std::to_string(periods) + ")");
    c.request.periods = static_cast<std::uint32_t>(periods);
    c.request.config_file = p.get_string("config_file");
    const std::int64_t maxf = p.get_int("max_frames");
    if (maxf < 0) fail("max_frames must be >= 0 (got " + std::to_string(maxf) + ")");
    c.max_frames = static_cast<std::uint64_t>(maxf);
    const std::int64_t retries = p.get_int("retry_max");
    if (retries < 0 || retries > 100000) fail("retry_max must be 0..100000 (got " + std::to_string(retries) + ")");
    c.retry_max = static_cast<std::uint32_t>(retries);
    c.retry_backoff_s = p.get_float("retry_backoff_s");
    c.retry_backoff_max_s = p.get_float("retry_backoff_max_s");
    if (!(c.retry_backoff_s > 0) || !std::isfinite(c.retry_backoff_s))
      fail("retry_backoff_s must be > 0 s (got " + num(c.retry_backoff_s) + ")");
    if (!(c.retry_backoff_max_s >= c.retry_backoff_s) || !std::isfinite(c.retry_backoff_max_s))
      fail("retry_backoff_max_s (" + num(c.retry_backoff_max_s) + ") must be >= retry_backoff_s (" +
           num(c.retry_backoff_s) + ")");
    c.stall_timeout_s = p.get_float("stall_timeout_s");
    if (!(c.stall_timeout_s >= 0) || !std::isfinite(c.stall_timeout_s))
      fail("stall_timeout_s must be >= 0 s (got " + num(c.stall_timeout_s) + ")");
    const std::int64_t prio = p.get_int("rt_priority");
    if (prio < 0 || prio > 99) fail("rt_priority must be 0..99 (got " + std::to_string(prio) + ")");
    c.rt_priority = static_cast<int>(prio);
  } catch (const std::out_of_range& e) {
    fail(std::string("missing or mistyped parameter: ") + e.what());
  }
  return c;
}

// ---------------------------------------------------------------- capture loop

CaptureLoop::CaptureLoop(snd_pcm_t* pcm, const PcmSetup& setup, AudioRing& ring, AlsaCounters& counters,
                         SpscQueue<AlsaNotice>* notices, std::uint64_t max_frames, double stall_timeout_s,
                         const std::atomic<bool>* stop, double gap_since_s)
    : pcm_(pcm),
      setup_(setup),
      ring_(ring),
      counters_(counters),
      notices_(notices),
      max_frames_(max_frames),
      stall_timeout_s_(stall_timeout_s),
      stop_(stop),
      gap_since_s_(gap_since_s),
      raw_(setup.period_frames * setup.frame_bytes()),
      samples_(setup.period_frames * setup.channels) {
  snd_pcm_status_malloc(&status_);
}

CaptureLoop::~CaptureLoop() { snd_pcm_status_free(status_); }

void CaptureLoop::notify(const AlsaNotice& n) noexcept {
  if (notices_ && !notices_->try_push(n)) counters_.notices_dropped.fetch_add(1, std::memory_order_relaxed);
}

void CaptureLoop::lose(std::uint64_t frames) noexcept {
  if (max_frames_ != 0) frames = std::min(frames, max_frames_ - std::min(max_frames_, produced_));
  if (frames == 0) return;
  ring_.write_lost(frames);
  produced_ += frames;
}

double CaptureLoop::status_trigger_s(snd_pcm_state_t* state, snd_pcm_uframes_t* avail) noexcept {
  if (snd_pcm_status(pcm_, status_) < 0) {
    *state = snd_pcm_state(pcm_);
    *avail = 0;
    return 0.0;
  }
  *state = snd_pcm_status_get_state(status_);
  *avail = snd_pcm_status_get_avail(status_);
  snd_htimestamp_t t{};
  snd_pcm_status_get_trigger_htstamp(status_, &t);
  return to_seconds(t);
}

void CaptureLoop::estimate_frame_zero(std::uint64_t frames_read_now) noexcept {
  // At time t the device had captured up to stream frame base + produced (incl. this read) + avail:
  // that frame is the one being captured at t. The htimestamp is taken at the last hardware pointer
  // update, with the avail of that moment (snd_pcm_htimestamp), on CLOCK_MONOTONIC (sw params).
  const double now = monotonic_s();
  snd_pcm_uframes_t avail = 0;
  snd_htimestamp_t ts{};
  double t = 0.0;
  if (snd_pcm_htimestamp(pcm_, &avail, &ts) == 0) t = to_seconds(ts);
  if (!(t > 0.0 && t <= now + 1e-3 && t >= now - 10.0)) {  // plugin PCMs may give none: use the clock now
    t = now;
    const snd_pcm_sframes_t a = snd_pcm_avail_update(pcm_);
    avail = a > 0 ? static_cast<snd_pcm_uframes_t>(a) : 0;
  }
  const std::uint64_t captured = base_frames_ + produced_ + frames_read_now + avail;
  frame_zero_out_->store(t - static_cast<double>(captured) / setup_.rate_hz, std::memory_order_release);
  frame_zero_out_ = nullptr;  // once per loop
}

bool CaptureLoop::start() noexcept {
  const double t_call = monotonic_s();
  snd_pcm_state_t state = snd_pcm_state(pcm_);
  if (state == SND_PCM_STATE_PREPARED) {
    const int err = snd_pcm_start(pcm_);
    if (err < 0) {
      error_ = err;
      return false;
    }
  }
  started_ = true;
  snd_pcm_uframes_t avail = 0;
  double t_start = status_trigger_s(&state, &avail);
  if (!(t_start >= t_call - 1.0 && t_start <= monotonic_s() + 1.0)) t_start = t_call;  // no usable timestamp
  if (gap_since_s_ >= 0.0) {
    const double gap = std::max(0.0, t_start - gap_since_s_);
    const auto lost = static_cast<std::uint64_t>(std::llround(gap * setup_.rate_hz));
    const std::uint64_t before = produced_;
    lose(lost);
    counters_.gap_frames_lost.fetch_add(produced_ - before, std::memory_order_relaxed);
    gap_since_s_ = -1.0;
  }
  last_data_s_ = monotonic_s();
  return true;
}

bool CaptureLoop::recover(int err) noexcept {
  const double t_seen = monotonic_s();
  snd_pcm_state_t state{};
  snd_pcm_uframes_t avail = 0;
  double t_stop = status_trigger_s(&state, &avail);
  const bool stopped_state = state == SND_PCM_STATE_XRUN || state == SND_PCM_STATE_SUSPENDED;
  // The stop must lie between the last successful read (the PCM was running then) and now; a plugin
  // that does not stamp the xrun (ioplug keeps its start time) fails this and falls back to now.
  bool valid = stopped_state && t_stop >= last_data_s_ - 1e-3 && t_stop <= t_seen + 1e-3;
  if (!valid) t_stop = t_seen;
  if (!stopped_state) avail = setup_.buffer_frames;  // the best estimate of what the buffer held

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
    r = snd_pcm_recover(pcm_, err, 1);  // silent: the notice is logged by the supervisor
  }
  if (r < 0) {
    error_ = r;
    return false;
  }
  if (snd_pcm_state(pcm_) == SND_PCM_STATE_PREPARED) {
    r = snd_pcm_start(pcm_);
    if (r < 0) {
      error_ = r;
      return false;
    }
  }
  const double t_after = monotonic_s();
  snd_pcm_uframes_t unused = 0;
  double t_restart = status_trigger_s(&state, &unused);
  if (!valid || !(t_restart >= t_stop && t_restart <= t_after + 1e-3)) {
    t_restart = t_after;
    valid = false;
  }
  const std::uint64_t frame = produced_;
  // Exact: frames captured but not read at the stop, plus the stopped interval. Without a valid stop
  // timestamp (plugin PCMs such as ioplug/jack stamp nothing and may report avail 0), every frame since
  // the last successful read is gone: the device kept capturing into the buffer until it overflowed,
  // prepare() dropped it, and nothing was captured until the restart.
  const auto lost =
      valid ? static_cast<std::uint64_t>(avail) +
                  static_cast<std::uint64_t>(std::llround(std::max(0.0, t_restart - t_stop) * setup_.rate_hz))
            : static_cast<std::uint64_t>(std::llround(std::max(0.0, t_restart - last_data_s_) * setup_.rate_hz));
  lose(lost);
  if (err == -EPIPE) {
    counters_.xruns.fetch_add(1, std::memory_order_relaxed);
    counters_.xrun_frames_lost.fetch_add(produced_ - frame, std::memory_order_relaxed);
  }
  notify(AlsaNotice{err == -EPIPE ? AlsaNotice::Kind::Overrun : AlsaNotice::Kind::Suspend, frame, produced_ - frame,
                    valid});
  last_data_s_ = monotonic_s();
  return true;
}

CaptureLoop::Status CaptureLoop::step(int wait_ms) noexcept {
  if (stop_ && stop_->load(std::memory_order_acquire)) return Status::Stopped;
  if (!started_ && !start()) return Status::DeviceLost;
  if (max_frames_ != 0 && produced_ >= max_frames_) return Status::Ended;
  snd_pcm_uframes_t want = setup_.period_frames;
  if (max_frames_ != 0) want = static_cast<snd_pcm_uframes_t>(std::min<std::uint64_t>(want, max_frames_ - produced_));
  snd_pcm_sframes_t n = snd_pcm_readi(pcm_, raw_.data(), want);
  if (n > 0) {
    const auto frames = static_cast<std::size_t>(n);
    if (frame_zero_out_ != nullptr) estimate_frame_zero(frames);  // before the frames become visible
    raw_to_float(setup_.format, raw_.data(), samples_.data(), frames * setup_.channels);
    ring_.write(samples_.data(), frames);  // a full ring reports the rest lost (write_lost)
    produced_ += frames;
    read_ += frames;
    counters_.frames.fetch_add(frames, std::memory_order_relaxed);
    last_data_s_ = monotonic_s();
    return Status::Frames;
  }
  if (n == 0 || n == -EAGAIN) {
    const int w = snd_pcm_wait(pcm_, wait_ms);
    if (w >= 0) {
      // A plugin that says "ready" but gives nothing (a `type file` infile at its end): do not spin.
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

// ---------------------------------------------------------------- source

AlsaSource::~AlsaSource() { stop(); }

void AlsaSource::open(const Params& params, HostContext& ctx) {
  open(AlsaStreamConfig::from_params(params, SND_PCM_STREAM_CAPTURE), ctx.log);
}

void AlsaSource::open(const AlsaStreamConfig& config, Logger& log) {
  if (supervisor_.joinable()) throw std::runtime_error("alsa source: open() while running");
  config_ = config;
  config_.request.stream = SND_PCM_STREAM_CAPTURE;
  config_.request.role = "alsa source";
  log_ = &log;
  pcm_ = Pcm::open(config_.request);
  setup_ = pcm_.setup();
  counters_ = std::make_unique<AlsaCounters>();
  finished_.store(false, std::memory_order_release);
  has_error_.store(false, std::memory_order_release);
  error_.clear();
  std::ostringstream os;
  os << "alsa source: PCM '" << config_.request.pcm << "' open for capture: " << setup_.channels << " ch, "
     << format_name(setup_.format) << ", " << setup_.rate_hz << " Hz, period " << setup_.period_frames
     << " frames, buffer " << setup_.buffer_frames << " frames";
  log.info(os.str());
}

void AlsaSource::start(AudioRing& ring) {
  if (!log_) throw std::runtime_error("alsa source: start() before open()");
  if (supervisor_.joinable()) throw std::runtime_error("alsa source: start() while already running");
  if (ring.channels() != config_.request.channels)
    throw std::runtime_error("alsa source: ring has " + std::to_string(ring.channels()) + " channels, PCM '" +
                             config_.request.pcm + "' has " + std::to_string(config_.request.channels));
  if (!pcm_) {  // stopped before: open again
    pcm_ = Pcm::open(config_.request);
    setup_ = pcm_.setup();
  }
  ring_ = &ring;
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  frame_zero_s_.store(std::numeric_limits<double>::quiet_NaN(), std::memory_order_release);
  supervisor_ = std::thread([this] { supervise(); });
}

void AlsaSource::stop() {
  stop_.store(true, std::memory_order_release);
  if (!supervisor_.joinable()) return;
  supervisor_.join();
  pcm_.close();
  drain_notices();
  const AlsaCounters& c = *counters_;
  std::ostringstream os;
  os << "alsa source: PCM '" << config_.request.pcm << "': " << c.frames.load() << " frames captured, "
     << c.xruns.load() << " overruns (" << c.xrun_frames_lost.load() << " frames lost), " << c.suspends.load()
     << " suspends, " << c.device_losses.load() << " device losses, " << c.reconnects.load() << " reconnects ("
     << c.gap_frames_lost.load() << " frames lost in gaps)";
  if (c.notices_dropped.load() != 0) os << ", " << c.notices_dropped.load() << " notices not logged";
  log_->info(os.str());
}

std::string AlsaSource::error() const {
  if (!has_error_.load(std::memory_order_acquire)) return {};
  return error_;
}

void AlsaSource::drain_notices() {
  AlsaNotice n;
  while (notices_->try_pop(n)) {
    std::ostringstream os;
    os << "alsa source: PCM '" << config_.request.pcm << "': "
       << (n.kind == AlsaNotice::Kind::Suspend ? "suspend" : "overrun") << " at frame " << n.frame << ", "
       << n.frames_lost << " frames lost (recovered"
       << (n.timestamps_valid ? ", from the PCM's timestamps)" : ", estimated on the host clock)");
    log_->warn(os.str());
  }
}

bool AlsaSource::sleep_unless_stopped(double seconds) {
  const double until = monotonic_s() + seconds;
  while (!stop_.load(std::memory_order_acquire)) {
    const double left = until - monotonic_s();
    if (left <= 0) return true;
    sleep_s(std::min(left, 0.02));
    drain_notices();
  }
  return false;
}

void AlsaSource::supervise() {
  const std::string pcm_name = "PCM '" + config_.request.pcm + "'";
  double gap_since = -1.0;
  std::uint32_t failures = 0;
  double backoff = config_.retry_backoff_s;
  std::uint64_t produced_total = 0;
  for (;;) {
    if (config_.max_frames != 0 && produced_total >= config_.max_frames) break;
    const std::uint64_t remaining = config_.max_frames == 0 ? 0 : config_.max_frames - produced_total;
    CaptureLoop loop(pcm_.get(), setup_, *ring_, *counters_, notices_.get(), remaining, config_.stall_timeout_s,
                     &stop_, gap_since);
    // The origin is taken once per stream (later loops continue its frame count through the gap).
    if (std::isnan(frame_zero_s_.load(std::memory_order_acquire))) loop.publish_frame_zero(&frame_zero_s_, produced_total);
    std::atomic<bool> done{false};
    CaptureLoop::Status status = CaptureLoop::Status::Stopped;
    bool rt_ok = true;
    std::thread capture([&] {
      rt_ok = set_rt_priority(config_.rt_priority);
      for (;;) {
        status = loop.step(20);
        if (status == CaptureLoop::Status::Ended || status == CaptureLoop::Status::DeviceLost ||
            status == CaptureLoop::Status::Stopped)
          break;
      }
      done.store(true, std::memory_order_release);
    });
    while (!done.load(std::memory_order_acquire)) {
      drain_notices();
      sleep_s(0.05);
    }
    capture.join();
    drain_notices();
    if (!rt_ok)
      log_->warn("alsa source: could not make the capture thread SCHED_FIFO " + std::to_string(config_.rt_priority) +
                 " (needs CAP_SYS_NICE or an rtprio limit); running at normal priority");
    produced_total += loop.produced();
    if (status == CaptureLoop::Status::Stopped) break;
    if (status == CaptureLoop::Status::Ended) {
      log_->info("alsa source: " + pcm_name + ": max_frames (" + std::to_string(config_.max_frames) + ") reached");
      break;
    }
    // Device lost.
    counters_->device_losses.fetch_add(1, std::memory_order_relaxed);
    if (loop.frames_read() > 0) {
      failures = 0;
      backoff = config_.retry_backoff_s;
    }
    const std::string why = loop.error() == -ETIMEDOUT
                                ? "no data for " + num(config_.stall_timeout_s) + " s (stall_timeout_s)"
                                : alsa_error_text(loop.error());
    pcm_.close();
    gap_since = loop.last_data_s();
    bool reopened = false;
    std::string last_failure;
    while (!reopened && failures < config_.retry_max && !stop_.load(std::memory_order_acquire)) {
      ++failures;
      log_->warn("alsa source: " + pcm_name + " lost (" + why + ") at stream frame " + std::to_string(produced_total) +
                 "; reopening in " + num(backoff) + " s (attempt " + std::to_string(failures) + " of " +
                 std::to_string(config_.retry_max) + ")");
      if (!sleep_unless_stopped(backoff)) break;
      backoff = std::min(backoff * 2.0, config_.retry_backoff_max_s);
      try {
        pcm_ = Pcm::open(config_.request);
        reopened = true;
      } catch (const std::exception& e) {
        last_failure = e.what();
        log_->warn(std::string("alsa source: reopen attempt ") + std::to_string(failures) + " failed: " + e.what());
      }
    }
    if (stop_.load(std::memory_order_acquire)) break;
    if (!reopened) {
      error_ = "alsa source: " + pcm_name + " lost (" + why + ") at stream frame " + std::to_string(produced_total) +
               (config_.retry_max == 0 ? " (retry_max is 0: no reopen attempt)"
                                       : " and not reopened after " + std::to_string(failures) +
                                             " attempt(s); last attempt: " + last_failure);
      has_error_.store(true, std::memory_order_release);
      log_->error(error_);
      break;
    }
    setup_ = pcm_.setup();
    counters_->reconnects.fetch_add(1, std::memory_order_relaxed);
    log_->info("alsa source: " + pcm_name + " reopened after " + std::to_string(failures) +
               " attempt(s); the gap is reported as lost frames");
  }
  finished_.store(true, std::memory_order_release);
}

}  // namespace locus::hal::alsa
