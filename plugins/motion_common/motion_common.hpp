// Pieces shared by the IMU detector plugins (attitude, steps, turns): the
// AHRS choice as parameters, and the per-sample attitude tracker that turns ImuSample timestamps
// into filter updates (dt from the device's own clock; gaps reset the filter from gravity).
#pragma once

#include <Eigen/Geometry>
#include <string>

#include "locus/dsp/ahrs.hpp"
#include "locus/events.hpp"
#include "locus/params.hpp"

namespace locus::plugins::motion_common {

/// The AHRS parameters every IMU plugin declares: `ahrs` (madgwick|mahony), `ahrs_gain` (Madgwick
/// beta in rad/s or Mahony kp in 1/s), `ahrs_ki` (Mahony bias gain), `use_mag`, `max_gap_s`,
/// `mag_calibration` (learn the magnetometer's hard iron from the device's turns,
/// dsp::HardIronCalibrator; off unless a config turns it on) and `mag_calibration_tau_s`.
void append_ahrs_params(ParamSchema& schema, double default_gain = 0.5);

/// Tracks the attitude of one device from its IMU samples.
class AttitudeTracker {
 public:
  /// [main] From the validated AHRS parameters (see append_ahrs_params).
  void configure(const Params& params);
  /// [RT] Feeds one sample. The first sample (and the first after a gap longer than max_gap_s, or a
  /// timestamp going backwards) initialises the attitude from gravity (and the field when used)
  /// instead of integrating. Returns false for a sample with non-finite values (ignored).
  bool update(const ImuSample& s) noexcept;
  /// True once a sample has been seen.
  bool valid() const noexcept { return valid_; }
  /// True when the last update() (re)initialised the attitude (a gap or the first sample).
  bool restarted() const noexcept { return restarted_; }
  const Eigen::Quaterniond& q() const noexcept { return ahrs_.q(); }
  /// Seconds since the previous sample (0 after a restart).
  double dt_s() const noexcept { return dt_; }
  double t_s() const noexcept { return t_; }
  void reset() noexcept { valid_ = false; }
  /// Samples ignored (non-finite values) since configure.
  std::uint64_t rejected() const noexcept { return rejected_; }
  std::uint64_t gaps() const noexcept { return gaps_; }

 private:
  dsp::Ahrs ahrs_;
  dsp::HardIronCalibrator calib_;
  bool use_mag_ = true;
  bool calibrate_ = false;
  double max_gap_s_ = 0.5;
  bool valid_ = false, restarted_ = false;
  double t_ = 0.0, dt_ = 0.0;
  std::uint64_t rejected_ = 0, gaps_ = 0;
};

}  // namespace locus::plugins::motion_common
