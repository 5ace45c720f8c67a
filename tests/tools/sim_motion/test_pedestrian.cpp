// PedestrianTrajectory: step count, frequency and stride follow the model (s = a·f + b), bounce
// follows the inverted pendulum, turns are smooth, the phone is held screen up.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "locus/sim/motion/imu.hpp"
#include "locus/sim/motion/pedestrian.hpp"

using namespace locus::sim;
using namespace locus::sim::motion;
using Eigen::Vector3d;

TEST(Pedestrian, StepsMatchFrequencyAndStrideModel) {
  PedestrianParams p;
  p.path_m = {{0, 0}, {40, 0}};
  p.step_freq_hz = 1.8;
  p.stride_a_m_s = 0.3;
  p.stride_b_m = 0.2;
  const PedestrianTrajectory w(p, 0.0, 42);
  const auto& steps = w.true_steps();
  ASSERT_GT(steps.size(), 40u);
  double sum_len = 0.0, sum_f = 0.0;
  for (const auto& s : steps) sum_len += s.stride_m;
  EXPECT_NEAR(sum_len, w.path_length_m(), 1e-9);
  EXPECT_NEAR(w.path_length_m(), 40.0, 1e-9);
  // Middle steps (the last one holds the remainder of the path).
  const std::size_t n = steps.size() - 1;
  double mean_err = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    sum_f += steps[k].frequency_hz;
    mean_err += steps[k].stride_m - (0.3 * steps[k].frequency_hz + 0.2);
  }
  EXPECT_NEAR(sum_f / n, 1.8, 0.02);
  EXPECT_NEAR(mean_err / n, 0.0, 0.01);
  // Step times: consecutive heel strikes 1/f apart; the walk is (steps) long.
  for (std::size_t k = 1; k < steps.size(); ++k)
    EXPECT_NEAR(steps[k].t_s - steps[k - 1].t_s, 1.0 / steps[k].frequency_hz, 1e-9);
  EXPECT_NEAR(steps.back().t_s, w.walk_end_s(), 1e-9);
  // Expected count: 40 m / (0.3·1.8 + 0.2) = 54 steps.
  EXPECT_NEAR(static_cast<double>(steps.size()), 40.0 / 0.74, 3.0);
}

TEST(Pedestrian, BounceIsLowestAtHeelStrikeWithThePendulumAmplitude) {
  PedestrianParams p;
  p.path_m = {{0, 0}, {20, 0}};
  p.step_freq_cv = 0.0;
  p.stride_noise_m = 0.0;
  p.wobble_rad = 0.0;
  const PedestrianTrajectory w(p, 0.0, 1);
  const auto& steps = w.true_steps();
  const double b = w.bounce_for_stride_m(steps[5].stride_m);
  EXPECT_GT(b, 0.03);
  EXPECT_LT(b, 0.08);
  // Pendulum: L(1 − cos φ), sin φ = s/(2L), times the gain.
  const double L = w.leg_length_m(), s = steps[5].stride_m;
  EXPECT_NEAR(b, p.bounce_gain * L * (1 - std::sqrt(1 - s * s / (4 * L * L))), 1e-12);
  for (std::size_t k = 3; k + 3 < steps.size(); ++k) {
    const double t_strike = steps[k].t_s, t_mid = t_strike + 0.5 / steps[k + 1].frequency_hz;
    const double dz = w.pose(t_mid).position_m.z() - w.pose(t_strike).position_m.z();
    EXPECT_NEAR(dz, b, 0.002) << "step " << k;
  }
}

TEST(Pedestrian, VerticalAccelerationPeaksCountTheSteps) {
  PedestrianParams p;
  p.path_m = {{0, 0}, {15, 0}, {15, 10}};
  const PedestrianTrajectory w(p, 0.0, 9);
  PhoneImuConfig c;
  c.rate_hz = 100.0;
  c.magnetometer = false;
  PhoneImu imu(c);
  Rng rng(3);
  // Vertical specific force in the world frame, lightly smoothed; count upward crossings of g + 1.
  int crossings = 0;
  bool above = false;
  double smooth = 9.81;
  for (double t = 0.0; t < w.end_s(); t += 0.01) {
    const auto r = imu.sample(w, std::nullopt, t, rng);
    const double vert = (w.pose(t).attitude * r.accel_mps2).z();
    smooth += 0.5 * (vert - smooth);
    if (!above && smooth > 9.81 + 1.0) {
      above = true;
      ++crossings;
    } else if (above && smooth < 9.81) {
      above = false;
    }
  }
  const int n = static_cast<int>(w.true_steps().size());
  EXPECT_NEAR(crossings, n, 2) << "steps " << n;
}

TEST(Pedestrian, FollowsThePathTurnsSmoothlyAndHoldsThePhoneUp) {
  PedestrianParams p;
  p.path_m = {{0, 0}, {5, 0}, {5, 5}};
  const PedestrianTrajectory w(p, 2.0, 4);
  EXPECT_EQ(w.start_s(), 2.0);
  EXPECT_NEAR(w.pose(0.0).position_m.x(), 0.0, 1e-9);  // held before the start
  const Vector3d end = w.pose(w.end_s() + 5).position_m;
  EXPECT_NEAR(end.x(), 5.0, 0.3);  // corners are rounded: the end is near, not on, the polyline end
  EXPECT_NEAR(end.y(), 5.0, 0.3);
  double max_yaw_rate = 0.0;
  for (double t = w.walk_start_s(); t < w.walk_end_s(); t += 0.01) {
    const Pose pose = w.pose(t);
    // Screen up and towards the face: body z has a positive world-up component.
    EXPECT_GT((pose.attitude * Vector3d::UnitZ()).z(), 0.8);
    max_yaw_rate = std::max(max_yaw_rate, std::abs(w.angular_velocity_body(t).norm()));
    // Near the path: within sway + corner rounding of the L.
    const Vector3d x = pose.position_m;
    const double off = std::min(std::abs(x.y()) + (x.x() > 5.0 ? x.x() - 5.0 : 0.0), std::abs(x.x() - 5.0));
    EXPECT_LT(off, 0.35) << "t=" << t;
  }
  // A 90° quintic turn over turn_length_m at walking speed peaks at 1.875·(π/2)·v/turn_length; plus wobble.
  const double v = w.path_length_m() / (w.walk_end_s() - w.walk_start_s());
  EXPECT_LT(max_yaw_rate, 1.875 * (std::numbers::pi / 2) * v * 1.2 / p.turn_length_m + 0.3);
  EXPECT_GT(max_yaw_rate, 0.5 * (std::numbers::pi / 2) * v / p.turn_length_m);
  // Phone attitude at rest after the walk: heading along +y (body y points along the last segment).
  const Vector3d y_axis = w.pose(w.end_s() + 1).attitude * Vector3d::UnitY();
  EXPECT_GT(y_axis.y(), 0.85);
}

TEST(Pedestrian, RejectsBadParameters) {
  PedestrianParams p;
  p.path_m = {{0, 0}};
  EXPECT_THROW(PedestrianTrajectory(p, 0, 1), std::invalid_argument);
  p.path_m = {{0, 0}, {0, 0}};
  EXPECT_THROW(PedestrianTrajectory(p, 0, 1), std::invalid_argument);
  p.path_m = {{0, 0}, {1, 0}};
  p.step_freq_hz = 9.0;
  EXPECT_THROW(PedestrianTrajectory(p, 0, 1), std::invalid_argument);
}
