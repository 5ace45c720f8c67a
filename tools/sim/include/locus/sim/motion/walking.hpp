// Helpers shared by the walking families (montage, spyloc, locble): formation paths, step truth,
// difficulty-scaled phone IMU.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "locus/sim/motion/imu.hpp"
#include "locus/sim/motion/pedestrian.hpp"

namespace locus::sim::motion {

/// The polyline shifted sideways by `lateral_m` (positive = to the left of the walking direction),
/// mitred at the corners. Throws std::invalid_argument for < 2 points or a zero-length segment.
std::vector<Eigen::Vector2d> offset_polyline(const std::vector<Eigen::Vector2d>& path, double lateral_m);

/// truth_steps.csv text: header `t_true,id,stride_m,frequency_hz`, one row per heel strike of every
/// walker up to `until_s` (the recording's duration: a walk cut short by `--duration` has no steps
/// after it), sorted by t_true (true time, s). See docs/simulator.md.
std::string truth_steps_csv(const std::vector<std::pair<std::string, const PedestrianTrajectory*>>& walkers,
                            double until_s);

/// A phone IMU (PhoneImuConfig defaults) whose error sigmas are multiplied by `noise_scale`
/// (difficulty; PhoneImuConfig::scale_errors).
PhoneImuConfig phone_imu_config(double rate_hz, double noise_scale, bool magnetometer);

}  // namespace locus::sim::motion
