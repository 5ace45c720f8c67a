// Phone-grade IMU synthesis (see imu.hpp).
#include "locus/sim/motion/imu.hpp"

#include <cmath>
#include <stdexcept>

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

PhoneImu::PhoneImu(PhoneImuConfig cfg) : cfg_(std::move(cfg)) {
  if (!(cfg_.rate_hz >= 1.0 && cfg_.rate_hz <= 2000.0))
    throw std::invalid_argument("imu: rate_hz must be in 1..2000 Hz");
  const double nonneg[] = {cfg_.accel_noise_density, cfg_.gyro_noise_density, cfg_.mag_noise_ut,
                           cfg_.accel_bias_std_mps2, cfg_.gyro_bias_std_radps, cfg_.mag_bias_std_ut,
                           cfg_.accel_scale_std, cfg_.gyro_scale_std, cfg_.jitter_std_s};
  for (double v : nonneg)
    if (!(v >= 0.0)) throw std::invalid_argument("imu: noise, bias, scale and jitter sigmas must be >= 0");
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
  drawn_ = true;
}

ImuReading PhoneImu::sample(const Simulation& sim, const DeviceModel& device, double t_true_s, Rng& rng) {
  if (!device.trajectory) throw std::invalid_argument("imu: device '" + device.id + "' has no trajectory");
  if (cfg_.magnetometer && !sim.magnetic_field_world_ut)
    throw std::invalid_argument("imu: device '" + device.id +
                                "' has a magnetometer but the simulation has no magnetic_field_world_ut");
  return sample(*device.trajectory, cfg_.magnetometer ? sim.magnetic_field_world_ut : std::nullopt, t_true_s, rng);
}

ImuReading PhoneImu::sample(const Trajectory& traj, const std::optional<Vector3d>& mag_world_ut, double t_true_s,
                            Rng& rng) {
  if (!drawn_) draw_errors(rng);
  const double t = cfg_.jitter_std_s > 0.0 ? t_true_s + cfg_.jitter_std_s * rng.normal() : t_true_s;
  ImuReading r = ideal_imu_reading(traj, t, cfg_.gravity_mps2, cfg_.magnetometer ? mag_world_ut : std::nullopt);
  const double sq = std::sqrt(cfg_.rate_hz);
  const double sa = cfg_.accel_noise_density * sq, sg = cfg_.gyro_noise_density * sq;
  for (int i = 0; i < 3; ++i) {
    r.accel_mps2[i] = (1.0 + err_.accel_scale[i]) * r.accel_mps2[i] + err_.accel_bias_mps2[i] + sa * rng.normal();
    r.gyro_radps[i] = (1.0 + err_.gyro_scale[i]) * r.gyro_radps[i] + err_.gyro_bias_radps[i] + sg * rng.normal();
  }
  if (r.mag_ut) {
    for (int i = 0; i < 3; ++i) (*r.mag_ut)[i] += err_.mag_bias_ut[i] + cfg_.mag_noise_ut * rng.normal();
  }
  return r;
}

}  // namespace locus::sim::motion
