// Phone-grade IMU synthesis from any Trajectory: what a phone's accelerometer, gyroscope and
// magnetometer read, as an engine ImuModel (engine.hpp) that any family can attach to a device.
//
//   accel = (I + diag(scale))·R^T·(a_world − g_world) + bias + noise   g_world = (0, 0, −gravity): flat,
//                                                        screen up, at rest: az = +9.81 (specific force)
//   gyro  = (I + diag(scale))·ω_body + bias + noise     ω_body from the attitude derivative
//   mag   = R^T·B_world + hard-iron bias + noise         µT; B_world = Simulation::magnetic_field_world_ut
//
// The engine samples at regular LOCAL times (k/rate on the device clock) and converts to true time.
// Sample-time jitter: the stamp stays regular but the sensor actually samples at true time + jitter
// (Gaussian, jitter_std_s), which is how a jittery sensor FIFO looks to the reader.
// Discrete white noise per sample: σ = density·sqrt(rate_hz) (continuous density, Kalibr convention).
// The per-device errors (biases, scales) are drawn once, at the first sample, from the device's
// private IMU stream, unless fixed in the config.
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
  double jitter_std_s = 0.0;                    ///< sampling-instant jitter (0 = none)
  bool magnetometer = true;                     ///< needs Simulation::magnetic_field_world_ut
  /// Fixed values instead of drawn ones (tests, calibrated devices).
  std::optional<Eigen::Vector3d> accel_bias_mps2, gyro_bias_radps, mag_bias_ut, accel_scale, gyro_scale;
};

/// The per-device error terms in use (evaluation / tests).
struct ImuErrors {
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag_bias_ut = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_scale = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_scale = Eigen::Vector3d::Zero();
};

/// Error-free reading of `traj` at true time t: specific force R^T·(a + g·ẑ), body rate, R^T·B.
ImuReading ideal_imu_reading(const Trajectory& traj, double t_true_s, double gravity_mps2,
                             const std::optional<Eigen::Vector3d>& mag_world_ut);

class PhoneImu final : public ImuModel {
 public:
  /// Throws std::invalid_argument for a rate outside 1..2000 Hz or a negative noise/bias/jitter.
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
};

}  // namespace locus::sim::motion
