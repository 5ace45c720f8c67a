// Trajectories (see trajectory.hpp): numeric derivatives, sampled poses, helpers.
#include "locus/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "locus/scene/pose.hpp"

namespace locus::sim {

Eigen::Vector3d Trajectory::velocity(double t) const {
  const double h = kDiffStep_s;
  return (pose(t + h).position_m - pose(t - h).position_m) / (2.0 * h);
}

Eigen::Vector3d Trajectory::acceleration(double t) const {
  const double h = kDiffStep_s;
  return (pose(t + h).position_m - 2.0 * pose(t).position_m + pose(t - h).position_m) / (h * h);
}

Eigen::Vector3d Trajectory::angular_velocity_body(double t) const {
  const double h = kDiffStep_s;
  // q(t+h) = q(t-h) · exp(ω_body · 2h / 2)  =>  ω_body = log(q(t-h)^-1 q(t+h)) / (2h)
  Eigen::Quaterniond dq = pose(t - h).attitude.conjugate() * pose(t + h).attitude;
  if (dq.w() < 0.0) dq.coeffs() = -dq.coeffs();
  const Eigen::AngleAxisd aa(dq.normalized());
  return aa.axis() * aa.angle() / (2.0 * h);
}

SampledTrajectory::SampledTrajectory(std::vector<double> t_s, std::vector<Pose> poses)
    : t_(std::move(t_s)), poses_(std::move(poses)) {
  if (t_.empty() || t_.size() != poses_.size()) {
    throw std::invalid_argument("SampledTrajectory: need as many times as poses, at least one (got " +
                                std::to_string(t_.size()) + " times, " + std::to_string(poses_.size()) + " poses)");
  }
  for (std::size_t i = 1; i < t_.size(); ++i) {
    if (!(t_[i] > t_[i - 1])) {
      throw std::invalid_argument("SampledTrajectory: times must increase strictly (index " + std::to_string(i) + ")");
    }
    // Catmull-Rom can overshoot the chord speed a little; 1.5x covers it.
    max_speed_ = std::max(max_speed_, 1.5 * (poses_[i].position_m - poses_[i - 1].position_m).norm() / (t_[i] - t_[i - 1]));
  }
  for (auto& p : poses_) p.attitude.normalize();
}

Pose SampledTrajectory::pose(double t) const {
  if (t_.size() == 1 || t <= t_.front()) return poses_.front();
  if (t >= t_.back()) return poses_.back();
  const std::size_t i = static_cast<std::size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin()) - 1;
  const double t0 = t_[i], t1 = t_[i + 1], h = t1 - t0;
  const double u = (t - t0) / h;
  const Eigen::Vector3d& p0 = poses_[i].position_m;
  const Eigen::Vector3d& p1 = poses_[i + 1].position_m;
  // Catmull-Rom tangents (non-uniform: finite differences over the neighbouring intervals).
  auto tangent = [&](std::size_t k) -> Eigen::Vector3d {
    if (k == 0) return (poses_[1].position_m - poses_[0].position_m) / (t_[1] - t_[0]);
    if (k + 1 == t_.size()) return (poses_[k].position_m - poses_[k - 1].position_m) / (t_[k] - t_[k - 1]);
    return (poses_[k + 1].position_m - poses_[k - 1].position_m) / (t_[k + 1] - t_[k - 1]);
  };
  const Eigen::Vector3d m0 = tangent(i) * h, m1 = tangent(i + 1) * h;
  const double u2 = u * u, u3 = u2 * u;
  Pose out;
  out.position_m = (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1;
  out.attitude = scene::interpolate_attitude(poses_[i].attitude, poses_[i + 1].attitude, u);
  return out;
}

Eigen::Quaterniond flat_attitude(const Eigen::Vector2d& heading_xy) {
  if (heading_xy.norm() <= 0.0) throw std::invalid_argument("flat_attitude: heading must be non-zero");
  // Body y -> heading; rotation about world z by the angle from +y to the heading.
  const double yaw = std::atan2(heading_xy.y(), heading_xy.x()) - std::atan2(1.0, 0.0);
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()));
}

double min_jerk(double u) noexcept {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
}
double min_jerk_d1(double u) noexcept {
  if (u <= 0.0 || u >= 1.0) return 0.0;
  return 30.0 * u * u * (1.0 - u) * (1.0 - u);
}
double min_jerk_d2(double u) noexcept {
  if (u <= 0.0 || u >= 1.0) return 0.0;
  return 60.0 * u * (1.0 - u) * (1.0 - 2.0 * u);
}

}  // namespace locus::sim
