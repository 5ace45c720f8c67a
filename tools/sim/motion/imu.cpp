// Phone-grade IMU synthesis (see imu.hpp).
#include "locus/sim/motion/imu.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace locus::sim::motion {

using Eigen::Vector3d;

ImuReading ideal_imu_reading(const Trajectory& traj, double t, double gravity_mps2,
                             const std::optional<Vector3d>& mag_world_ut) {
  const Pose p = traj.pose(t);
  const Eigen::Matrix3d Rt = p.attitude.toRotationMatrix().transpose();
  ImuReading r;
  r.accel_mps2 = Rt * (traj.acceleration(t) + Vector3d(0.0, 0.0, gravity_mps2));
  r.gyro_radps = traj.angular_velocity_body(t);
  if (mag_world_ut) r.mag_ut = Rt * *mag_world_ut;
  return r;
}

PhoneImuConfig& PhoneImuConfig::scale_errors(double k) {
  if (!(k >= 0.0)) throw std::invalid_argument("imu: scale_errors factor must be >= 0");
  for (double* v : {&accel_noise_density, &gyro_noise_density, &mag_noise_ut, &accel_bias_std_mps2,
                    &gyro_bias_std_radps, &mag_bias_std_ut, &accel_scale_std, &gyro_scale_std, &accel_bias_rw,
                    &gyro_bias_rw, &accel_cross_axis_std_rad, &gyro_cross_axis_std_rad, &jitter_std_s,
                    &stamp_jitter_std_s})
    *v *= k;
  return *this;
}

double PhoneImuConfig::accel_step_mps2() const noexcept {
  return adc_bits > 0 ? 2.0 * accel_full_scale_mps2 / std::ldexp(1.0, adc_bits) : 0.0;
}
double PhoneImuConfig::gyro_step_radps() const noexcept {
  return adc_bits > 0 ? 2.0 * gyro_full_scale_radps / std::ldexp(1.0, adc_bits) : 0.0;
}

PhoneImu::PhoneImu(PhoneImuConfig cfg) : cfg_(std::move(cfg)) {
  if (!(cfg_.rate_hz >= 1.0 && cfg_.rate_hz <= 2000.0))
    throw std::invalid_argument("imu: rate_hz must be in 1..2000 Hz");
  const double nonneg[] = {cfg_.accel_noise_density, cfg_.gyro_noise_density, cfg_.mag_noise_ut,
                           cfg_.accel_bias_std_mps2, cfg_.gyro_bias_std_radps, cfg_.mag_bias_std_ut,
                           cfg_.accel_scale_std, cfg_.gyro_scale_std, cfg_.jitter_std_s,
                           cfg_.accel_bias_rw, cfg_.gyro_bias_rw, cfg_.accel_cross_axis_std_rad,
                           cfg_.gyro_cross_axis_std_rad, cfg_.stamp_jitter_std_s};
  for (double v : nonneg)
    if (!(v >= 0.0))
      throw std::invalid_argument("imu: noise, bias, random walk, scale, cross-axis and jitter sigmas must be >= 0");
  if (cfg_.adc_bits != 0 && (cfg_.adc_bits < 4 || cfg_.adc_bits > 32))
    throw std::invalid_argument("imu: adc_bits must be 0 (no quantisation) or 4..32, got " +
                                std::to_string(cfg_.adc_bits));
  if (cfg_.adc_bits != 0 && !(cfg_.accel_full_scale_mps2 > 0.0 && cfg_.gyro_full_scale_radps > 0.0))
    throw std::invalid_argument("imu: accel_full_scale_mps2 and gyro_full_scale_radps must be > 0 with adc_bits > 0");
}

void PhoneImu::draw_errors(Rng& rng) {
  auto draw = [&rng](const std::optional<Vector3d>& fixed, double sigma) {
    if (fixed) return *fixed;
    return Vector3d(sigma * rng.normal(), sigma * rng.normal(), sigma * rng.normal());
  };
  err_.accel_bias_mps2 = draw(cfg_.accel_bias_mps2, cfg_.accel_bias_std_mps2);
  err_.gyro_bias_radps = draw(cfg_.gyro_bias_radps, cfg_.gyro_bias_std_radps);
  err_.mag_bias_ut = draw(cfg_.mag_bias_ut, cfg_.mag_bias_std_ut);
  err_.accel_scale = draw(cfg_.accel_scale, cfg_.accel_scale_std);
  err_.gyro_scale = draw(cfg_.gyro_scale, cfg_.gyro_scale_std);
  auto cross = [&rng](const std::optional<Eigen::Matrix3d>& fixed, double sigma) {
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (i != j) c(i, j) = fixed ? (*fixed)(i, j) : sigma * rng.normal();
    return c;
  };
  err_.accel_cross_axis = cross(cfg_.accel_cross_axis, cfg_.accel_cross_axis_std_rad);
  err_.gyro_cross_axis = cross(cfg_.gyro_cross_axis, cfg_.gyro_cross_axis_std_rad);
  drawn_ = true;
}

namespace {
// ADC: round to the step, clip to the signed range of `bits`.
double quantise(double v, double step, int bits) {
  if (bits <= 0 || !(step > 0.0)) return v;
  const double hi = std::ldexp(1.0, bits - 1);
  return step * std::clamp(std::nearbyint(v / step), -hi, hi - 1.0);
}
}  // namespace

ImuReading PhoneImu::sample(const Simulation& sim, const DeviceModel& device, double t_true_s, Rng& rng) {
  if (!device.trajectory) throw std::invalid_argument("imu: device '" + device.id + "' has no trajectory");
  if (cfg_.magnetometer && !sim.magnetic_field_world_ut)
    throw std::invalid_argument("imu: device '" + device.id +
                                "' has a magnetometer but the simulation has no magnetic_field_world_ut");
  return sample(*device.trajectory, cfg_.magnetometer ? sim.magnetic_field_world_ut : std::nullopt, t_true_s, rng);
}

ImuReading PhoneImu::sample(const Trajectory& traj, const std::optional<Vector3d>& mag_world_ut, double t_true_s,
                            Rng& rng) {
  if (!drawn_) {
    draw_errors(rng);
    t_last_s_ = t_true_s;
  }
  // bias random walk over the time since the previous sample
  const double dt = std::abs(t_true_s - t_last_s_);
  t_last_s_ = t_true_s;
  if (dt > 0.0 && (cfg_.accel_bias_rw > 0.0 || cfg_.gyro_bias_rw > 0.0)) {
    const double sdt = std::sqrt(dt);
    for (int i = 0; i < 3; ++i) err_.accel_bias_drift_mps2[i] += cfg_.accel_bias_rw * sdt * rng.normal();
    for (int i = 0; i < 3; ++i) err_.gyro_bias_drift_radps[i] += cfg_.gyro_bias_rw * sdt * rng.normal();
  }
  const double t = cfg_.jitter_std_s > 0.0 ? t_true_s + cfg_.jitter_std_s * rng.normal() : t_true_s;
  ImuReading r = ideal_imu_reading(traj, t, cfg_.gravity_mps2, cfg_.magnetometer ? mag_world_ut : std::nullopt);
  const double sq = std::sqrt(cfg_.rate_hz);
  const double sa = cfg_.accel_noise_density * sq, sg = cfg_.gyro_noise_density * sq;
  const Vector3d a_true = r.accel_mps2, g_true = r.gyro_radps;
  const Vector3d a_cross = err_.accel_cross_axis * a_true, g_cross = err_.gyro_cross_axis * g_true;
  const double qa = cfg_.accel_step_mps2(), qg = cfg_.gyro_step_radps();
  for (int i = 0; i < 3; ++i) {
    const double a = (1.0 + err_.accel_scale[i]) * a_true[i] + a_cross[i] + err_.accel_bias_mps2[i] +
                     err_.accel_bias_drift_mps2[i] + sa * rng.normal();
    const double g = (1.0 + err_.gyro_scale[i]) * g_true[i] + g_cross[i] + err_.gyro_bias_radps[i] +
                     err_.gyro_bias_drift_radps[i] + sg * rng.normal();
    r.accel_mps2[i] = quantise(a, qa, cfg_.adc_bits);
    r.gyro_radps[i] = quantise(g, qg, cfg_.adc_bits);
  }
  if (cfg_.stamp_jitter_std_s > 0.0) {
    const double lim = 0.45 / cfg_.rate_hz;
    r.stamp_offset_s = std::clamp(cfg_.stamp_jitter_std_s * rng.normal(), -lim, lim);
  }
  if (r.mag_ut) {
    for (int i = 0; i < 3; ++i) (*r.mag_ut)[i] += err_.mag_bias_ut[i] + cfg_.mag_noise_ut * rng.normal();
  }
  return r;
}

}  // namespace locus::sim::motion
