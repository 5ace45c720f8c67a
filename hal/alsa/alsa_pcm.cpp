// See alsa_pcm.hpp: opening a PCM by name (optionally from a private config file), negotiating the
// format, exact rate, channels and buffer, with errors that say what the PCM offers.
#include "alsa/alsa_pcm.hpp"

#include <pthread.h>
#include <sched.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <utility>
#include <vector>

namespace locus::hal::alsa {

namespace {

thread_local char t_alsa_message[512];

void capture_handler(const char* /*file*/, int /*line*/, const char* /*function*/, int err, const char* fmt, ...) {
  // No allocation: format into this thread's fixed buffer (truncated if long).
  va_list ap;
  va_start(ap, fmt);
  int n = std::vsnprintf(t_alsa_message, sizeof t_alsa_message, fmt, ap);
  va_end(ap);
  if (n < 0) n = 0;
  auto used = static_cast<std::size_t>(n);
  if (err != 0 && used + 4 < sizeof t_alsa_message) {
    char buf[128];
    const char* text = ::strerror_r(err, buf, sizeof buf);
    std::snprintf(t_alsa_message + used, sizeof t_alsa_message - used, ": %s", text);
  }
}

/// Builds "<role>: <what> (ALSA: <last libasound message>)".
[[noreturn]] void fail(const PcmRequest& r, const std::string& what) {
  std::string msg = r.role + ": " + what;
  const std::string detail = take_alsa_message();
  if (!detail.empty()) msg += " (ALSA: " + detail + ")";
  throw std::runtime_error(msg);
}

const char* direction(const PcmRequest& r) {
  return r.stream == SND_PCM_STREAM_CAPTURE ? "capture" : "playback";
}

std::string rates_offered(snd_pcm_t* pcm, const snd_pcm_hw_params_t* base) {
  unsigned int lo = 0, hi = 0;
  int dir = 0;
  snd_pcm_hw_params_get_rate_min(base, &lo, &dir);
  snd_pcm_hw_params_get_rate_max(base, &hi, &dir);
  static constexpr unsigned int kCommon[] = {8000,  11025, 16000, 22050,  24000,  32000, 44100,
                                             48000, 88200, 96000, 176400, 192000, 384000};
  std::string list;
  snd_pcm_hw_params_t* probe = nullptr;
  snd_pcm_hw_params_malloc(&probe);
  for (unsigned int rate : kCommon) {
    snd_pcm_hw_params_copy(probe, base);
    if (snd_pcm_hw_params_test_rate(pcm, probe, rate, 0) == 0) list += (list.empty() ? "" : ", ") + std::to_string(rate);
  }
  snd_pcm_hw_params_free(probe);
  std::string out = "it offers " + std::to_string(lo) + ".." + std::to_string(hi) + " Hz";
  if (!list.empty()) out += " (common rates: " + list + ")";
  return out;
}

std::string formats_offered(snd_pcm_t* pcm, const snd_pcm_hw_params_t* base) {
  std::string list;
  snd_pcm_hw_params_t* probe = nullptr;
  snd_pcm_hw_params_malloc(&probe);
  for (int f = 0; f <= static_cast<int>(SND_PCM_FORMAT_LAST); ++f) {
    const auto fmt = static_cast<snd_pcm_format_t>(f);
    const char* name = snd_pcm_format_name(fmt);
    if (name == nullptr) continue;
    snd_pcm_hw_params_copy(probe, base);
    if (snd_pcm_hw_params_test_format(pcm, probe, fmt) == 0) list += (list.empty() ? "" : ", ") + std::string(name);
  }
  snd_pcm_hw_params_free(probe);
  return list.empty() ? "none" : list;
}

struct HwParams {
  snd_pcm_hw_params_t* p = nullptr;
  HwParams() { snd_pcm_hw_params_malloc(&p); }
  ~HwParams() { snd_pcm_hw_params_free(p); }
};
struct SwParams {
  snd_pcm_sw_params_t* p = nullptr;
  SwParams() { snd_pcm_sw_params_malloc(&p); }
  ~SwParams() { snd_pcm_sw_params_free(p); }
};

}  // namespace

void install_error_capture() {
  static std::once_flag once;
  std::call_once(once, [] { snd_lib_error_set_handler(&capture_handler); });
}

std::string take_alsa_message() {
  std::string s(t_alsa_message);
  t_alsa_message[0] = '\0';
  return s;
}

std::string alsa_error_text(long err) {
  const char* t = snd_strerror(static_cast<int>(err));
  return t ? std::string(t) : "error " + std::to_string(err);
}

bool set_rt_priority(int priority) noexcept {
  if (priority <= 0) return true;
  sched_param sp{};
  sp.sched_priority = priority;
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
}

double monotonic_s() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

Pcm& Pcm::operator=(Pcm&& o) noexcept {
  if (this != &o) {
    close();
    pcm_ = std::exchange(o.pcm_, nullptr);
    config_ = std::exchange(o.config_, nullptr);
    setup_ = o.setup_;
    name_ = std::move(o.name_);
  }
  return *this;
}

void Pcm::close() noexcept {
  if (pcm_) {
    snd_pcm_drop(pcm_);  // also flushes what a `type file` PCM still buffers to its file
    snd_pcm_close(pcm_);
  }
  pcm_ = nullptr;
  if (config_) snd_config_delete(config_);
  config_ = nullptr;
}

Pcm Pcm::open(const PcmRequest& r) {
  install_error_capture();
  take_alsa_message();
  const std::string quoted = "PCM '" + r.pcm + "'";
  if (r.pcm.empty()) fail(r, "pcm is empty (expected a PCM name such as default, hw:1,0, plughw:1,0)");
  std::vector<SampleFormat> candidates;
  try {
    candidates = formats_for_name(r.format);
  } catch (const std::invalid_argument& e) {
    fail(r, e.what());
  }

  Pcm out;
  out.name_ = r.pcm;
  // ---- configuration tree
  if (!r.config_file.empty()) {
    if (::access(r.config_file.c_str(), R_OK) != 0)
      fail(r, "config_file '" + r.config_file + "' cannot be read: " + std::strerror(errno));
    snd_config_t* global = nullptr;
    int err = snd_config_update_ref(&global);
    if (err < 0) fail(r, "cannot load the system ALSA configuration: " + alsa_error_text(err));
    err = snd_config_copy(&out.config_, global);
    snd_config_unref(global);
    if (err < 0) fail(r, "cannot copy the system ALSA configuration: " + alsa_error_text(err));
    snd_input_t* in = nullptr;
    err = snd_input_stdio_open(&in, r.config_file.c_str(), "r");
    if (err < 0) fail(r, "config_file '" + r.config_file + "' cannot be opened: " + alsa_error_text(err));
    err = snd_config_load(out.config_, in);
    snd_input_close(in);
    if (err < 0) fail(r, "config_file '" + r.config_file + "' is not a valid ALSA configuration: " + alsa_error_text(err));
  }
  // ---- open
  int err = out.config_ ? snd_pcm_open_lconf(&out.pcm_, r.pcm.c_str(), r.stream, SND_PCM_NONBLOCK, out.config_)
                        : snd_pcm_open(&out.pcm_, r.pcm.c_str(), r.stream, SND_PCM_NONBLOCK);
  if (err < 0) {
    out.pcm_ = nullptr;
    std::string hint;
    if (err == -ENOENT) hint = " (no such PCM or a file it needs is missing; `locus devices` lists the PCMs)";
    if (err == -EBUSY) hint = " (the device is in use by another program)";
    fail(r, "cannot open " + quoted + " for " + direction(r) + ": " + alsa_error_text(err) + hint +
                (r.config_file.empty() ? "" : " [config_file '" + r.config_file + "']"));
  }
  snd_pcm_t* pcm = out.pcm_;

  // ---- hardware parameters
  HwParams hw;
  if ((err = snd_pcm_hw_params_any(pcm, hw.p)) < 0)
    fail(r, quoted + ": cannot read its hardware parameters: " + alsa_error_text(err));
  if ((err = snd_pcm_hw_params_set_access(pcm, hw.p, SND_PCM_ACCESS_RW_INTERLEAVED)) < 0)
    fail(r, quoted + " does not support interleaved read/write access: " + alsa_error_text(err));
  if ((err = snd_pcm_hw_params_set_channels(pcm, hw.p, r.channels)) < 0) {
    unsigned int lo = 0, hi = 0;
    snd_pcm_hw_params_get_channels_min(hw.p, &lo);
    snd_pcm_hw_params_get_channels_max(hw.p, &hi);
    fail(r, quoted + " cannot " + direction(r) + " " + std::to_string(r.channels) + " channel(s): it offers " +
                std::to_string(lo) + ".." + std::to_string(hi));
  }
  bool have_format = false;
  for (SampleFormat f : candidates) {
    if (snd_pcm_hw_params_test_format(pcm, hw.p, to_alsa(f)) == 0 &&
        snd_pcm_hw_params_set_format(pcm, hw.p, to_alsa(f)) == 0) {
      out.setup_.format = f;
      have_format = true;
      break;
    }
  }
  if (!have_format) {
    std::string asked;
    for (SampleFormat f : candidates) asked += (asked.empty() ? "" : ", ") + std::string(snd_pcm_format_name(to_alsa(f)));
    fail(r, quoted + " supports none of the formats asked (" + asked + "); it offers " + formats_offered(pcm, hw.p) +
                " (format: one of auto, s16, s24, s24_3, s32, float)");
  }
  snd_pcm_hw_params_set_rate_resample(pcm, hw.p, 1);  // plug PCMs may resample; hw PCMs cannot
  if (snd_pcm_hw_params_test_rate(pcm, hw.p, r.rate_hz, 0) != 0 ||
      snd_pcm_hw_params_set_rate(pcm, hw.p, r.rate_hz, 0) < 0) {
    fail(r, quoted + " cannot " + direction(r) + " at exactly " + std::to_string(r.rate_hz) + " Hz: " +
                rates_offered(pcm, hw.p) + " (a plughw:/plug PCM resamples)");
  }
  snd_pcm_uframes_t period = r.period_frames;
  int dir = 0;
  if ((err = snd_pcm_hw_params_set_period_size_near(pcm, hw.p, &period, &dir)) < 0)
    fail(r, quoted + " refuses a period of about " + std::to_string(r.period_frames) + " frames: " + alsa_error_text(err));
  snd_pcm_uframes_t buffer = static_cast<snd_pcm_uframes_t>(period) * r.periods;
  if ((err = snd_pcm_hw_params_set_buffer_size_near(pcm, hw.p, &buffer)) < 0)
    fail(r, quoted + " refuses a buffer of about " + std::to_string(buffer) + " frames: " + alsa_error_text(err));
  if ((err = snd_pcm_hw_params(pcm, hw.p)) < 0)
    fail(r, quoted + ": cannot apply the hardware parameters (" + std::to_string(r.channels) + " ch, " +
                std::string(format_name(out.setup_.format)) + ", " + std::to_string(r.rate_hz) + " Hz): " +
                alsa_error_text(err));
  snd_pcm_hw_params_get_period_size(hw.p, &period, &dir);
  snd_pcm_hw_params_get_buffer_size(hw.p, &buffer);
  out.setup_.channels = r.channels;
  out.setup_.rate_hz = r.rate_hz;
  out.setup_.period_frames = period;
  out.setup_.buffer_frames = buffer;

  // ---- software parameters: timestamps on the monotonic clock, wake per period, explicit start
  SwParams sw;
  if ((err = snd_pcm_sw_params_current(pcm, sw.p)) < 0)
    fail(r, quoted + ": cannot read its software parameters: " + alsa_error_text(err));
  snd_pcm_sw_params_set_tstamp_mode(pcm, sw.p, SND_PCM_TSTAMP_ENABLE);
  snd_pcm_sw_params_set_tstamp_type(pcm, sw.p, SND_PCM_TSTAMP_TYPE_MONOTONIC);
  snd_pcm_sw_params_set_avail_min(pcm, sw.p, period);
  // Capture starts explicitly (or on the first read); playback starts when the buffer is full.
  snd_pcm_sw_params_set_start_threshold(pcm, sw.p, r.stream == SND_PCM_STREAM_CAPTURE ? 1 : buffer);
  snd_pcm_sw_params_set_stop_threshold(pcm, sw.p, buffer);
  if ((err = snd_pcm_sw_params(pcm, sw.p)) < 0)
    fail(r, quoted + ": cannot apply the software parameters: " + alsa_error_text(err));
  if ((err = snd_pcm_prepare(pcm)) < 0) fail(r, quoted + ": cannot prepare: " + alsa_error_text(err));
  take_alsa_message();
  return out;
}

}  // namespace locus::hal::alsa
