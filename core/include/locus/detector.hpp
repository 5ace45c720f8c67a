// Detector plugins: turn blocks of audio, IMU samples or BLE advertisements into events.
//
// A detector is a plain object: the host calls configure() once on the main thread, then the
// [RT] process_* methods from one detector thread, block by block. process_* must not allocate,
// lock, log, throw or make a syscall; everything it needs is prepared in configure(). A detector is
// testable on one thread with no host running (see tests/).
#pragma once

#include <cstddef>
#include <cstdint>

#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"

namespace locus {

/// Describes the audio stream a detector will see.
struct StreamInfo {
  DeviceId device;
  std::uint32_t stream = 0;
  std::uint32_t channels = 1;
  double sample_rate_hz = 44100.0;
  std::uint32_t max_block_frames = 1024;  ///< process_audio never gets more frames than this
};

/// One block of audio, planar (one pointer per channel), on the stream's own frame counter.
struct AudioBlock {
  const float* const* channel_data = nullptr;  ///< channels pointers, each `frames` floats
  std::uint32_t channels = 0;
  std::uint32_t frames = 0;
  std::uint64_t first_frame = 0;    ///< stream frame number of sample 0 of this block
  std::uint64_t lost_before = 0;    ///< frames lost (overrun) right before this block; reset state
};

/// [RT] Where a detector emits events. emit() never blocks or allocates; it returns false (and the
/// host counts the drop) when the event queue is full.
class EventSink {
 public:
  virtual ~EventSink() = default;
  virtual bool emit(const Event& event) noexcept = 0;
};

/// Which inputs a detector consumes (bit mask in the descriptor).
enum DetectorInput : std::uint32_t {
  kInputAudio = 1u << 0,
  kInputImu = 1u << 1,
  kInputBle = 1u << 2,
};

class Detector {
 public:
  virtual ~Detector() = default;

  /// [main] Validated params and the stream it will see. Allocate everything here (FFT plans via
  /// ctx.fft, buffers sized by info.max_block_frames). Throw std::runtime_error on a bad setup.
  virtual void configure(const StreamInfo& info, const Params& params, HostContext& ctx) = 0;

  /// [RT] One audio block.
  virtual void process_audio(const AudioBlock& /*block*/, EventSink& /*out*/) noexcept {}
  /// [RT] IMU samples in time order.
  virtual void process_imu(const ImuSample* /*samples*/, std::size_t /*count*/, EventSink& /*out*/) noexcept {}
  /// [RT] BLE advertisements in time order.
  virtual void process_ble(const BleAdvertisement* /*adverts*/, std::size_t /*count*/, EventSink& /*out*/) noexcept {}

  /// [main] The stream ended (replay finished, daemon stopping): emit what is still pending.
  virtual void finish(EventSink& /*out*/) {}
};

}  // namespace locus
