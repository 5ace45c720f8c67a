// Opening and configuring an ALSA PCM for the `alsa` source and sink, with errors a user can act on.
//
// Why a helper of its own: capture and playback open PCMs the same way (by name, optionally from an
// extra config file loaded on top of the system configuration, non-blocking, interleaved, exact rate,
// negotiated format), and the device-loss retry reopens them from a supervisor thread. Every failure
// throws std::runtime_error naming the PCM and what it offers (rates, formats, channel range) so a
// config mistake is obvious without aplay.
//
// The extra config (`config_file`) is loaded the documented way: snd_config_update_ref() for the
// system tree, snd_config_copy(), snd_config_load() of the file into the copy, snd_pcm_open_lconf().
// The tree is kept alive with the PCM (plugins may refer to it) and freed on close.
//
// libasound reports details through SNDERR on stderr; install_error_capture() replaces that handler
// (once per process) with one that keeps the last message of the calling thread in a fixed buffer
// (no allocation, so it is safe if a plugin reports from the capture thread) and errors built here
// append it ("ALSA: Unknown PCM foo").
#pragma once

#include <alsa/asoundlib.h>

#include <cstdint>
#include <memory>
#include <string>

#include "alsa/alsa_format.hpp"

namespace locus::hal::alsa {

/// What to open.
struct PcmRequest {
  std::string pcm = "default";   ///< PCM name: hw:1,0, plughw:1,0, default, a name from config_file
  std::string config_file;       ///< "" = the system configuration only
  snd_pcm_stream_t stream = SND_PCM_STREAM_CAPTURE;
  std::uint32_t channels = 1;
  std::string format = "auto";   ///< a format_choices() name
  std::uint32_t rate_hz = 44100;
  std::uint32_t period_frames = 256;
  std::uint32_t periods = 4;
  std::string role = "alsa";     ///< prefix of error messages ("alsa source", "alsa sink")
};

/// What the PCM was configured to.
struct PcmSetup {
  SampleFormat format = SampleFormat::S16;
  std::uint32_t channels = 1;
  std::uint32_t rate_hz = 44100;
  snd_pcm_uframes_t period_frames = 0;
  snd_pcm_uframes_t buffer_frames = 0;
  std::size_t frame_bytes() const noexcept { return bytes_per_sample(format) * channels; }
};

/// An open, configured (prepared, not started) PCM. Closing frees the private config tree too.
class Pcm {
 public:
  Pcm() = default;
  ~Pcm() { close(); }
  Pcm(const Pcm&) = delete;
  Pcm& operator=(const Pcm&) = delete;
  Pcm(Pcm&& o) noexcept { *this = std::move(o); }
  Pcm& operator=(Pcm&& o) noexcept;

  /// [main or supervisor] Opens and configures; throws std::runtime_error naming the PCM and the cause.
  static Pcm open(const PcmRequest& request);

  snd_pcm_t* get() const noexcept { return pcm_; }
  explicit operator bool() const noexcept { return pcm_ != nullptr; }
  const PcmSetup& setup() const noexcept { return setup_; }
  const std::string& name() const noexcept { return name_; }
  void close() noexcept;

 private:
  snd_pcm_t* pcm_ = nullptr;
  snd_config_t* config_ = nullptr;
  PcmSetup setup_;
  std::string name_;
};

/// Replaces libasound's stderr error handler by the capturing one (idempotent, thread-safe).
void install_error_capture();
/// The last libasound message reported on this thread ("" if none), and clears it.
std::string take_alsa_message();

/// Errno text of a negative libasound return ("No such device" for -ENODEV).
std::string alsa_error_text(long err);

/// [main] Makes the calling thread SCHED_FIFO at `priority` (1..99); returns false (and changes
/// nothing) when not permitted. 0 does nothing and returns true.
bool set_rt_priority(int priority) noexcept;

/// [RT] Monotonic time in seconds (CLOCK_MONOTONIC, the clock the PCM timestamps are taken on).
double monotonic_s() noexcept;
/// snd_htimestamp_t to seconds; 0 for a zero timestamp.
inline double to_seconds(const snd_htimestamp_t& t) noexcept {
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}

}  // namespace locus::hal::alsa
