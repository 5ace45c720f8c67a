// Movement vectors of one walker (paper 002, Sec. 4): the direction of each step in a world-aligned
// frame (gravity + magnetometer: the `attitude` detector's reference frame) from the horizontal
// acceleration, and the walker's constant offset between that direction and the phone's heading.
//
// Sec. 4.3: within a step, the horizontal acceleration (reference frame, its mean over the step
// removed) swings along the walking direction: its principal axis (PCA of the samples; the paper
// takes the largest sample, which is one sample's noise) gives the axis; "the forward acceleration
// accompanies the rising edge of the vertical acceleration" gives the sign (the axis is taken forward
// when Σ a_fwd · da_v/dt > 0 over the step). Per step this is ±20° (the paper's figure) and zigzags, so
// the paper smooths it with a Kalman filter; here the phone is held at a fixed attitude relative to
// the body (the Montage scenes: "phone held at a fixed but unknown attitude"), so the walking direction
// is the phone's heading plus a constant offset, and the offset is the circular mean of (step
// direction − phone heading) over every step so far, each step weighted by how clearly its
// acceleration has one axis. Turns then come from the phone's heading at once and the offset only
// has to be learnt once (the formation solver refines it further from ranging).
//
// Everything [main] (the localizer's dispatcher thread).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <deque>
#include <optional>

namespace locus::plugins::montage {

class WalkDirection {
 public:
  /// [main] One IMU sample rotated into the reference frame (z up), gravity included; times increasing.
  void add_sample(double t_s, const Eigen::Vector3d& accel_ref_mps2);
  /// [main] A step from t0_s to t1_s with the phone's mean heading over it (rad, CCW from reference x):
  /// returns the step's direction (rad, same convention) when the step holds enough samples, and
  /// adds (direction − heading) to the offset estimate.
  std::optional<double> add_step(double t0_s, double t1_s, double phone_heading_rad);
  /// The offset (walking direction − phone heading, rad in (−π, π]) once min_steps steps gave one.
  std::optional<double> offset_rad(std::size_t min_steps = 4) const;
  std::size_t steps() const noexcept { return steps_; }

 private:
  struct Sample {
    double t_s;
    Eigen::Vector3d a;
  };
  std::deque<Sample> samples_;
  double sum_c_ = 0.0, sum_s_ = 0.0;
  std::size_t steps_ = 0;
};

}  // namespace locus::plugins::montage
