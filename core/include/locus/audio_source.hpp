// Audio sources: the HAL side that produces frames into a device's AudioRing (ALSA, JACK, scene
// replay, the synthetic generator). The pipeline owns the ring and the consumer side.
#pragma once

#include <cstdint>
#include <limits>
#include <string>

#include "locus/audio_ring.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"

namespace locus {

class AudioSource {
 public:
  virtual ~AudioSource() = default;

  /// [main] Validated params; decide channels and rate. Throw std::runtime_error naming what failed.
  virtual void open(const Params& params, HostContext& ctx) = 0;
  virtual std::uint32_t channels() const = 0;
  virtual double sample_rate_hz() const = 0;

  /// True for hardware-paced sources (a full ring means frames are lost and reported); false for
  /// sources that can wait for the consumer (replay at max speed, the generator).
  virtual bool live() const = 0;

  /// [main] Starts producing into `ring` (the source owns its thread or callback). Must return quickly.
  virtual void start(AudioRing& ring) = 0;
  /// [main] Stops producing; idempotent. After it returns nothing writes to the ring.
  virtual void stop() = 0;
  /// [any] True once a finite source has produced its last frame (the stream ended).
  virtual bool finished() const noexcept = 0;
  /// [main] Error that ended the stream early ("" if none).
  virtual std::string error() const { return {}; }

  /// [any, RT-safe] CLOCK_MONOTONIC seconds at which stream frame 0 was (or would have been) captured,
  /// so that stream frame F was captured at frame_zero_monotonic_s() + F / sample_rate_hz() (frames
  /// reported lost count: they advance the frame counter like captured ones). NaN when unknown:
  /// non-live sources (replay: their device-local time already has frame 0 at t = 0), or a live
  /// source that has not produced frames yet. Valid once frames have been produced; a source may
  /// refine it while running (clock drift, a server reconnect) by small amounts. The pipeline uses it
  /// to put live sensor events (stamped on CLOCK_MONOTONIC) on the audio timeline (pipeline.hpp).
  virtual double frame_zero_monotonic_s() const noexcept { return std::numeric_limits<double>::quiet_NaN(); }
};

}  // namespace locus
