// Typed events that flow from detectors (real-time side) to localizers and sinks (main side).
//
// Every event is a trivially copyable value so it can cross a lock-free SPSC queue without
// allocating. Time is always device-local: audio events carry the fractional sample index on their
// stream's own frame counter (never a wall-clock guess); IMU/BLE/sync events carry the local time in
// seconds of the device that sensed them. The JSON shape of each event is documented in docs/events.md.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string_view>
#include <type_traits>
#include <variant>

#include "locus/fixed_string.hpp"
#include "locus/numbers.hpp"

namespace locus {

using DeviceId = FixedString<32>;
using NameTag = FixedString<32>;

/// A detector found a known signal in an audio stream.
struct AudioDetection {
  DeviceId device;              ///< device whose stream this is
  NameTag detector;             ///< detector instance name (from the config)
  std::uint32_t stream = 0;     ///< stream id within the device (0 = its audio input)
  std::uint16_t channel = 0;    ///< channel (microphone) index
  std::uint16_t template_index = 0;  ///< which template/code/signal matched
  double frame = 0.0;           ///< fractional sample index on the stream's frame counter
  double sample_rate_hz = 0.0;  ///< nominal rate of the stream (local time = frame / rate)
  float snr_db = 0.0f;          ///< peak-to-noise ratio of the detection statistic
  float confidence = 0.0f;      ///< 0..1
  float amplitude = 0.0f;       ///< linear peak amplitude of the detection statistic
  /// Detectors that time a passband signal by its carrier phase (chirp, refine: phase): the arrival by
  /// the correlation envelope alone (same frame counter) and the carrier period (samples). `frame` is
  /// a carrier-phase zero near envelope_frame; whole periods apart are equally plausible to the phase.
  /// A consumer holding several arrivals through one channel (same source, same microphone) can choose
  /// their cycles consistently: frame - envelope_frame is the same for all of them up to whole periods.
  /// carrier_period 0: not carrier-timed (envelope_frame is then frame or 0).
  double envelope_frame = 0.0;
  float carrier_period = 0.0f;
};

/// One IMU reading in the device body frame (Android convention), gravity included.
struct ImuSample {
  DeviceId device;
  double t_s = 0.0;                       ///< local time
  std::array<float, 3> accel_mps2{};      ///< m/s^2
  std::array<float, 3> gyro_radps{};      ///< rad/s
  std::array<float, 3> mag_ut{};          ///< µT, valid when has_mag
  bool has_mag = false;
};

/// One received BLE advertisement.
struct BleAdvertisement {
  DeviceId device;                        ///< the scanning device
  double t_s = 0.0;                       ///< local receive time
  std::array<std::uint8_t, 6> address{};  ///< AA:BB:CC:DD:EE:FF, most significant byte first
  float rssi_dbm = 0.0f;
  float tx_power_dbm = 0.0f;              ///< valid when has_tx_power
  bool has_tx_power = false;
  std::uint8_t channel = 0;               ///< 37..39, 0 = unknown
};

/// A radio synchronisation message was received (SpyLoc: the beep follows after a known delay).
struct RadioSync {
  DeviceId device;   ///< the receiving device
  double t_s = 0.0;  ///< local receive time
  NameTag source;    ///< sender id
};

/// A detected step of a walker.
struct Step {
  DeviceId device;
  NameTag detector;
  double t_s = 0.0;          ///< local time of the step (heel strike)
  float stride_m = 0.0f;     ///< estimated stride length, NaN when unknown
  float frequency_hz = 0.0f; ///< current step frequency
};

/// Orientation of a device body frame (rotates body vectors into the reference frame).
struct Attitude {
  DeviceId device;
  NameTag detector;
  double t_s = 0.0;
  std::array<float, 4> q_wxyz{1.0f, 0.0f, 0.0f, 0.0f};
  float heading_rad = 0.0f;  ///< yaw of the body y axis in the reference frame
};

/// A position estimate published by a localizer. Unknown fields are NaN.
/// Flags of an Estimate (bit mask; docs/events.md "estimate" lists them by name).
enum EstimateFlag : std::uint32_t {
  kEstimateDirectionOnly = 1u << 0,   ///< the data give a direction, not a distance (position_m null)
  kEstimateAmbiguous = 1u << 1,       ///< another position fits as well (the preferred one is reported)
  kEstimateInconsistent = 1u << 2,    ///< the measurements disagree with the model beyond their noise
                                      ///< (e.g. an obstructed path or a reflection taken for the first path):
                                      ///< treat the result as unreliable; confidence is lowered accordingly
  kEstimateWeak = 1u << 3,            ///< too few reliable measurements to pin the answer down (it may be a
                                      ///< mirror image or far off); confidence is lowered accordingly
  kEstimateHeightUnobserved = 1u << 4,  ///< the data do not observe the position along the reference's
                                        ///< vertical: position_m's vertical component is the localizer's
                                        ///< prior, and std_m covers the horizontal plane only
};

struct Estimate {
  NameTag plugin;                      ///< localizer instance name
  DeviceId reference;                  ///< device whose frame `position_m` is expressed in ("" = world)
  NameTag frame;                       ///< frame name, see docs/events.md (e.g. "world", "player_start")
  NameTag target;                      ///< what was located (device id, tag address, user)
  double t_s = 0.0;                    ///< time of validity on the reference device's clock
  std::array<double, 3> position_m{kNaN, kNaN, kNaN};
  std::uint8_t dims = 2;               ///< 2 or 3 valid position components
  double direction_rad = kNaN;         ///< bearing of the target in the frame, when meaningful
  double distance_m = kNaN;            ///< range to the target, when meaningful
  double std_m = kNaN;                 ///< 1-sigma position uncertainty
  float confidence = 0.0f;             ///< 0..1
  double direction_std_rad = kNaN;     ///< 1-sigma of direction_rad, when given
  double distance_std_m = kNaN;        ///< 1-sigma of distance_m, when given
  std::uint32_t flags = 0;             ///< EstimateFlag bits
  /// Line-of-sight verdict of the measurement this estimate was updated with (SpyLoc): 1 = LoS,
  /// 0 = NLoS, -1 = none given (JSON key `los`, written only when given). Fits the padding after
  /// `flags`: sizeof(Estimate) is unchanged.
  std::int8_t los = -1;
};

/// Reverberation-decay features of one detected sound (SpyLoc's LoS/NLoS features T5..T30), emitted
/// by a detector right after the AudioDetection it belongs to (same device, detector, stream, channel,
/// template_index and frame). Kept separate so AudioDetection stays small.
struct DecayFeatures {
  DeviceId device;
  NameTag detector;
  std::uint32_t stream = 0;
  std::uint16_t channel = 0;
  std::uint16_t template_index = 0;
  double frame = 0.0;                ///< the detection's frame (links the two events)
  double sample_rate_hz = 0.0;
  /// T5, T10, ..., T30: seconds from the end of the direct sound until the smoothed energy envelope
  /// first falls 5, 10, ..., 30 dB below the direct sound's peak; NaN = not reached in the window.
  std::array<float, 6> decay_s{NAN, NAN, NAN, NAN, NAN, NAN};
  float noise_margin_db = 0.0f;      ///< direct-sound peak energy over the noise floor
};

/// Every event type, in a fixed order (the order is part of the plugin ABI; new types go at the end).
using Event = std::variant<AudioDetection, ImuSample, BleAdvertisement, RadioSync, Step, Attitude, Estimate,
                           DecayFeatures>;
static_assert(std::is_trivially_copyable_v<Event>);

enum class EventType : std::uint8_t {
  AudioDetection = 0,
  ImuSample,
  BleAdvertisement,
  RadioSync,
  Step,
  Attitude,
  Estimate,
  DecayFeatures,
};
inline constexpr std::size_t kEventTypeCount = std::variant_size_v<Event>;

inline EventType type_of(const Event& e) noexcept { return static_cast<EventType>(e.index()); }

/// Stable snake_case name used in configs and JSON ("audio_detection", ...).
std::string_view event_type_name(EventType t) noexcept;
/// Inverse of event_type_name; returns false for an unknown name.
bool event_type_from_name(std::string_view name, EventType& out) noexcept;

}  // namespace locus
