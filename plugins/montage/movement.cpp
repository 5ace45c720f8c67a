#include "movement.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace locus::plugins::montage {

void WalkDirection::add_sample(double t_s, const Eigen::Vector3d& accel_ref_mps2) {
  if (!samples_.empty() && t_s <= samples_.back().t_s) return;
  if (!accel_ref_mps2.allFinite()) return;
  samples_.push_back(Sample{t_s, accel_ref_mps2});
  while (samples_.size() > 2 && samples_.back().t_s - samples_.front().t_s > 5.0) samples_.pop_front();
}

std::optional<double> WalkDirection::add_step(double t0_s, double t1_s, double phone_heading_rad) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  std::size_t n = 0;
  for (const Sample& s : samples_)
    if (s.t_s >= t0_s && s.t_s <= t1_s) {
      mean += s.a;
      ++n;
    }
  if (n < 8 || !std::isfinite(phone_heading_rad)) return std::nullopt;
  mean /= static_cast<double>(n);
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (const Sample& s : samples_)
    if (s.t_s >= t0_s && s.t_s <= t1_s) {
      const Eigen::Vector2d h = (s.a - mean).head<2>();
      c += h * h.transpose();
    }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(c);
  const double l0 = es.eigenvalues()(0), l1 = es.eigenvalues()(1);
  if (!(l1 > 0.0)) return std::nullopt;
  Eigen::Vector2d axis = es.eigenvectors().col(1);
  // Sign: the forward acceleration comes with the rising edge of the vertical acceleration.
  double corr = 0.0;
  const Sample* prev = nullptr;
  for (const Sample& s : samples_) {
    if (s.t_s < t0_s || s.t_s > t1_s) continue;
    if (prev != nullptr && s.t_s > prev->t_s) {
      const double dv = (s.a.z() - prev->a.z()) / (s.t_s - prev->t_s);
      const double fwd = 0.5 * ((s.a - mean).head<2>() + (prev->a - mean).head<2>()).dot(axis);
      corr += fwd * dv;
    }
    prev = &s;
  }
  if (corr < 0.0) axis = -axis;
  const double dir = std::atan2(axis.y(), axis.x());
  // Weight: how much the swing is along one axis (1 for a line, 0 for a circle).
  const double w = 1.0 - l0 / l1;
  sum_c_ += w * std::cos(dir - phone_heading_rad);
  sum_s_ += w * std::sin(dir - phone_heading_rad);
  ++steps_;
  return dir;
}

std::optional<double> WalkDirection::offset_rad(std::size_t min_steps) const {
  if (steps_ < min_steps || std::hypot(sum_c_, sum_s_) <= 0.0) return std::nullopt;
  return std::atan2(sum_s_, sum_c_);
}

}  // namespace locus::plugins::montage
