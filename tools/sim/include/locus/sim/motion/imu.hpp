// Phone-grade IMU synthesis from any Trajectory: what a phone's accelerometer, gyroscope and
// magnetometer read, as an engine ImuModel (engine.hpp) that any family can attach to a device.
//
//   accel = Q( M_a·R^T·(a_world − g_world) + b_a(t) + noise )   g_world = (0, 0, −gravity): flat, screen
//                                                        up, at rest: az = +9.81 (specific force)
//   gyro  = Q( M_g·ω_body + b_g(t) + noise )             ω_body from the attitude derivative
//   mag   = R^T·B_world + hard-iron bias + noise         µT; B_world = Simulation::magnetic_field_world_ut
//
//   M = I + diag(scale) + C          per-device scale errors and cross-axis sensitivity C (zero
//                                    diagonal, every off-diagonal element N(0, cross_axis_std_rad):
//                                    non-orthogonal, misaligned sensor axes)
//   b(t) = b0 + random walk          turn-on bias b0 per device and axis, plus a Brownian bias drift:
//                                    b(t_k) = b(t_{k−1}) + bias_rw·sqrt(t_k − t_{k−1})·N(0, 1)
//   Q(v)                             ADC: v rounded to the step 2·full_scale / 2^adc_bits, clipped to
//                                    [−2^(bits−1), 2^(bits−1) − 1] steps (off when adc_bits = 0)
//
// Why all of these: a phone IMU is double-integrated by AMIL and the pedestrian trackers, so the
// slowly varying errors (bias, its drift, scale, cross-axis: gravity leaking into x/y when the phone
// is tilted) decide the track error, not the white noise; the defaults are those of a consumer 6-axis
// part (±8 g / ±2000 °/s, 16 bit: steps 2.39e-3 m/s² and 1.07e-3 rad/s) and what the independent
// reference generator models (../shared/scenes/README.md).
//
// The engine samples at regular LOCAL times (k/rate on the device clock) and converts to true time.
// Two timing errors: sampling-instant jitter (jitter_std_s: the row stamp stays regular, the sensor
// samples at true time + N(0, jitter)) and row-stamp jitter (stamp_jitter_std_s: the sensor samples
// on the regular grid, the row is stamped k/rate + N(0, σ), clipped to ±0.45 period, so rows are not
// exactly regular — ImuReading::stamp_offset_s, applied by the engine).
// Discrete white noise per sample: σ = density·sqrt(rate_hz) (continuous density, Kalibr convention).
// The per-device errors (biases, scales, cross-axis) are drawn once, at the first sample, from the
// device's private IMU stream, unless fixed in the config. Samples must come in increasing time (the
// bias random walk advances with the time since the previous sample).
#pragma once

#include <optional>

#include "locus/sim/engine.hpp"

namespace locus::sim::motion {

struct PhoneImuConfig {
  double rate_hz = 100.0;                       ///< 50..400 Hz typical; 1..2000 accepted
  double gravity_mps2 = 9.81;
  double accel_noise_density = 1.5e-3;          ///< m/s²/√Hz (≈150 µg/√Hz)
  double gyro_noise_density = 1.2e-4;           ///< rad/s/√Hz (≈0.007 °/s/√Hz)
  double mag_noise_ut = 0.3;                    ///< µT per sample
  double accel_bias_std_mps2 = 0.03;            ///< per-axis turn-on bias
  double gyro_bias_std_radps = 3e-3;
  double mag_bias_std_ut = 1.0;                 ///< hard iron
  double accel_scale_std = 3e-3;                ///< per-axis relative scale error
  double gyro_scale_std = 3e-3;
  double accel_bias_rw = 1e-3;                  ///< bias random walk, m/s² per √s (bias change std over 1 s)
  double gyro_bias_rw = 1e-4;                   ///< rad/s per √s
  double accel_cross_axis_std_rad = 1.745e-3;   ///< cross-axis sensitivity per off-diagonal element (0.1°)
  double gyro_cross_axis_std_rad = 1.745e-3;
  double accel_full_scale_mps2 = 8.0 * 9.80665; ///< ±8 g: range of the ADC (readings clip there)
  double gyro_full_scale_radps = 34.906585;     ///< ±2000 °/s
  int adc_bits = 16;                            ///< quantisation of accel and gyro (0 = none, no clipping)
  double jitter_std_s = 0.0;                    ///< sampling-instant jitter (0 = none)
  double stamp_jitter_std_s = 1.2e-4;           ///< row-stamp jitter (0 = regular rows)
  bool magnetometer = true;                     ///< needs Simulation::magnetic_field_world_ut
  /// Fixed values instead of drawn ones (tests, calibrated devices).
  std::optional<Eigen::Vector3d> accel_bias_mps2, gyro_bias_radps, mag_bias_ut, accel_scale, gyro_scale;
  /// Fixed cross-axis matrices (the diagonal is ignored: scale errors are separate).
  std::optional<Eigen::Matrix3d> accel_cross_axis, gyro_cross_axis;

  /// Multiplies every error sigma (white noise densities, turn-on biases, bias random walks, scale
  /// and cross-axis errors, both jitters, magnetometer noise and hard iron) by k >= 0; the ADC (full
  /// scale, bits) is hardware and stays. The difficulty knob of every family (imu_noise_scale).
  PhoneImuConfig& scale_errors(double k);
  /// Quantisation step of the accelerometer / gyroscope (0 when adc_bits = 0).
  double accel_step_mps2() const noexcept;
  double gyro_step_radps() const noexcept;
};

/// The per-device error terms in use (evaluation / tests).
struct ImuErrors {
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag_bias_ut = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_scale = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_scale = Eigen::Vector3d::Zero();
  Eigen::Matrix3d accel_cross_axis = Eigen::Matrix3d::Zero();  ///< zero diagonal
  Eigen::Matrix3d gyro_cross_axis = Eigen::Matrix3d::Zero();
  /// Bias random-walk state (the drift added to the turn-on bias so far; changes with every sample).
  Eigen::Vector3d accel_bias_drift_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_drift_radps = Eigen::Vector3d::Zero();
};

/// Error-free reading of `traj` at true time t: specific force R^T·(a + g·ẑ), body rate, R^T·B.
ImuReading ideal_imu_reading(const Trajectory& traj, double t_true_s, double gravity_mps2,
                             const std::optional<Eigen::Vector3d>& mag_world_ut);

class PhoneImu final : public ImuModel {
 public:
  /// Throws std::invalid_argument for a rate outside 1..2000 Hz, a negative noise/bias/jitter/random
  /// walk/cross-axis sigma, adc_bits outside 0 or 4..32, or a non-positive full scale with adc_bits > 0.
  explicit PhoneImu(PhoneImuConfig cfg = {});
  double rate_hz() const override { return cfg_.rate_hz; }
  bool has_magnetometer() const override { return cfg_.magnetometer; }
  /// Throws std::invalid_argument when the magnetometer is on and the simulation has no field.
  ImuReading sample(const Simulation& sim, const DeviceModel& device, double t_true_s, Rng& rng) override;
  /// Same without the engine: reads `traj` (tests, tools).
  ImuReading sample(const Trajectory& traj, const std::optional<Eigen::Vector3d>& mag_world_ut,
                    double t_true_s, Rng& rng);

  /// The errors in use (drawn at the first sample; all zero before it).
  const ImuErrors& errors() const noexcept { return err_; }
  const PhoneImuConfig& config() const noexcept { return cfg_; }

 private:
  void draw_errors(Rng& rng);
  PhoneImuConfig cfg_;
  ImuErrors err_;
  bool drawn_ = false;
  double t_last_s_ = 0.0;  // time of the previous sample (bias random walk)
};

}  // namespace locus::sim::motion
