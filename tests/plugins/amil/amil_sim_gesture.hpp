// Test helper (amil-plugin tests): the simulator's AMIL gesture (tools/sim motion::GestureTrajectory,
// motion::PhoneImu) sampled like the `amil` family does, with the truth the tracker must reproduce:
// the speaker's position at every pause in the player's start frame (docs/eval.md `player_start`).
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "locus/sim/motion/gesture.hpp"
#include "locus/sim/motion/imu.hpp"
#include "locus/sim/rng.hpp"

namespace amil_test {

struct SimGesture {
  std::shared_ptr<locus::sim::motion::GestureTrajectory> traj;
  std::vector<double> t_s;                         // IMU sample times (true = local)
  std::vector<Eigen::Vector3d> accel, gyro;
  Eigen::Vector3d speaker_body{0.02, -0.072, 0.0};
  double t_start_s = 0.0;                          // start of the first stroke (true)

  /// World -> start frame (origin: body at t_start, y: body y projected, z up).
  Eigen::Vector3d to_start(const Eigen::Vector3d& world) const {
    const auto pose = traj->pose(t_start_s);
    Eigen::Vector3d y = pose.attitude * Eigen::Vector3d::UnitY();
    y.z() = 0.0;
    y.normalize();
    const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d x = y.cross(z);
    const Eigen::Vector3d d = world - pose.position_m;
    return {x.dot(d), y.dot(d), z.dot(d)};
  }
  /// True speaker position (start frame) at true time t.
  Eigen::Vector3d speaker_at(double t) const { return to_start(traj->pose(t).to_world(speaker_body)); }
};

/// The `amil` family's gesture: triangle of side `side_m`, `gestures` times, on a table; IMU noise
/// scaled by `imu_scale` (normal 1, hard 2). Heading: random (the tracker must not care).
/// `pause_s`: the shortest and longest pause at a corner (the paper's 0.4-0.7 s by default).
inline SimGesture make_gesture(std::uint64_t seed, int gestures = 1, double imu_scale = 1.0, double side_m = 0.305,
                               std::pair<double, double> pause_s = {0.4, 0.7}) {
  using namespace locus::sim;
  motion::GestureParams g;
  g.waypoints_m = {{0.0, 0.0}};
  for (int k = 0; k < gestures; ++k) {
    g.waypoints_m.push_back({-side_m, 0.0});
    g.waypoints_m.push_back({0.0, side_m});
    g.waypoints_m.push_back({side_m, 0.0});
    g.waypoints_m.push_back({0.0, 0.0});
  }
  g.origin_m = Eigen::Vector3d(1.5, 0.25, 0.75);
  Rng layout(seed * 7 + 3);
  g.device_heading_rad = layout.uniform(0.0, 2.0 * M_PI);
  g.plane_yaw_rad = g.device_heading_rad - M_PI / 2;  // the triangle drawn in the phone's own axes
  g.pause_min_s = pause_s.first;
  g.pause_max_s = pause_s.second;
  SimGesture out;
  out.traj = std::make_shared<motion::GestureTrajectory>(g, 1.0, seed ^ 0xA311u);
  motion::PhoneImuConfig ic;
  ic.magnetometer = false;
  ic.accel_noise_density *= imu_scale;
  ic.gyro_noise_density *= imu_scale;
  ic.accel_bias_std_mps2 *= imu_scale;
  ic.gyro_bias_std_radps *= imu_scale;
  motion::PhoneImu imu(ic);
  Rng rng(seed * 13 + 1);
  const double end = out.traj->end_s() + 1.0;
  for (int k = 0; k / 100.0 < end; ++k) {
    const double t = k / 100.0;
    const auto r = imu.sample(*out.traj, std::nullopt, t, rng);
    out.t_s.push_back(t);
    out.accel.push_back(r.accel_mps2);
    out.gyro.push_back(r.gyro_radps);
  }
  out.t_start_s = out.traj->pauses().front().end_s;
  return out;
}

}  // namespace amil_test
