// The emitter: how a plugin makes its device play a sound (AMIL's player beeps, a TUM device's
// ranging chirp, a SpyLoc beacon). Part of the plugin ABI (HostContext::emitter).
//
// A plugin chooses the signal (a SignalSpec, locus/signal.hpp: typically its device's
// DeviceGeometry::emits entry, or one it built or parsed itself) and the frame of
// the device's playback stream at which it must start; the host renders it on the main thread and
// hands it to the playback backend (ALSA or JACK) through a lock-free queue, so the audio callback only
// mixes ready samples. Where the sound actually left the speaker is NOT known from the schedule
// (speaker latency, driver buffering): measure it in the device's own capture, as AMIL does.
#pragma once

#include <cstdint>
#include <string>

#include "locus/signal.hpp"

namespace locus {

class Emitter {
 public:
  virtual ~Emitter() = default;

  /// [main] Schedules one emission of `signal` (e.g. type "lfm", f0_hz 18000, f1_hz 22000, duration_s
  /// 0.05, fade_s 0.005, amplitude 0.8); it starts at frame `start_frame` of the playback stream (see
  /// playback_frame()), scaled by `gain` (0..1), on every output channel. Returns false and sets
  /// `*error` (when given) if the signal is invalid (check_signal; the message names the field) or not
  /// acoustic, the start frame has already been played, or too many emissions are pending.
  virtual bool schedule(const SignalSpec& signal, std::uint64_t start_frame, double gain, std::string* error) = 0;

  /// [any] The next frame the playback stream will render (its frame counter now). Schedule at least
  /// one period ahead of it.
  virtual std::uint64_t playback_frame() const noexcept = 0;
  /// [any] Nominal sample rate of the playback stream.
  virtual double sample_rate_hz() const noexcept = 0;
  /// [any] Emissions that started late (part of them was cut) or were refused at render time.
  virtual std::uint64_t late_emissions() const noexcept = 0;
};

}  // namespace locus
