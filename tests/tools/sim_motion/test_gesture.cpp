// GestureTrajectory: min-jerk strokes start and end at rest, pauses at the waypoints, AMIL timing.
#include <gtest/gtest.h>

#include <cmath>

#include "locus/sim/motion/gesture.hpp"

using namespace locus::sim;
using namespace locus::sim::motion;
using Eigen::Vector3d;

namespace {
GestureParams no_tremor() {
  GestureParams p;
  p.tremor_m = 0.0;
  p.tremor_rad = 0.0;
  p.origin_m = Vector3d(2.0, 1.5, 0.75);
  return p;
}
}  // namespace

TEST(Gesture, StrokesHaveZeroVelocityAndAccelerationAtTheirEnds) {
  const GestureTrajectory g(no_tremor(), 1.0, 11);
  const auto& pauses = g.pauses();
  ASSERT_EQ(pauses.size(), 5u);
  for (std::size_t k = 0; k + 1 < pauses.size(); ++k) {
    for (double t : {pauses[k].end_s, pauses[k + 1].start_s}) {
      EXPECT_LT(g.velocity(t).norm(), 1e-12) << "stroke " << k << " t=" << t;
      EXPECT_LT(g.acceleration(t).norm(), 1e-9) << "stroke " << k << " t=" << t;
      // The numeric derivative of pose() agrees (the closed forms are not just zeros).
      EXPECT_LT(g.Trajectory::velocity(t).norm(), 1e-5);
    }
    // Mid-stroke: peak speed of a min-jerk move = 1.875·d/T, matching the numeric derivative.
    const double t0 = pauses[k].end_s, t1 = pauses[k + 1].start_s, tm = 0.5 * (t0 + t1);
    const double d = (pauses[k + 1].position_m - pauses[k].position_m).norm();
    EXPECT_NEAR(g.velocity(tm).norm(), 1.875 * d / (t1 - t0), 1e-9);
    EXPECT_NEAR((g.velocity(tm) - g.Trajectory::velocity(tm)).norm(), 0.0, 1e-5);
    EXPECT_NEAR((g.acceleration(t0 + 0.2 * (t1 - t0)) - g.Trajectory::acceleration(t0 + 0.2 * (t1 - t0))).norm(), 0.0,
                1e-4);
    EXPECT_LE(g.velocity(tm).norm(), g.max_speed_mps());
  }
}

TEST(Gesture, PausesSitAtTheWaypointsWithTheSetDurations) {
  const GestureParams p = no_tremor();
  const GestureTrajectory g(p, 0.0, 3);
  const auto& pauses = g.pauses();
  for (std::size_t k = 0; k < pauses.size(); ++k) {
    const Vector3d expect = p.origin_m + Vector3d(p.waypoints_m[k].x(), p.waypoints_m[k].y(), 0.0);
    EXPECT_NEAR((pauses[k].position_m - expect).norm(), 0.0, 1e-12);
    EXPECT_NEAR((g.pose(pauses[k].mid_s()).position_m - expect).norm(), 0.0, 1e-12);
    double dur = pauses[k].end_s - pauses[k].start_s;
    if (k == 0) dur -= p.lead_in_s;
    if (k + 1 == pauses.size()) dur -= p.lead_out_s;
    EXPECT_GE(dur, p.pause_min_s - 1e-12);
    EXPECT_LE(dur, p.pause_max_s + 1e-12);
  }
  // AMIL: a 30.5 cm triangle with five beeps takes a few seconds (paper: within ~5 s of motion).
  const double motion_s = pauses.back().start_s - pauses.front().end_s;
  EXPECT_GT(motion_s, 2.5);
  EXPECT_LT(motion_s, 6.0);
  // On a table: flat (body z up), heading near the set one.
  for (double t = 0.0; t < g.end_s(); t += 0.05) {
    const Pose pose = g.pose(t);
    EXPECT_NEAR(pose.position_m.z(), 0.75, 1e-12);
    EXPECT_NEAR((pose.attitude * Vector3d::UnitZ() - Vector3d::UnitZ()).norm(), 0.0, 1e-9);
  }
}

TEST(Gesture, TremorIsSmallAndPresent) {
  GestureParams p;  // default tremor
  const GestureTrajectory g(p, 0.0, 5);
  const auto& pause = g.pauses()[2];
  double s2 = 0.0;
  int n = 0;
  for (double t = pause.start_s; t < pause.end_s; t += 0.002, ++n) s2 += (g.pose(t).position_m - pause.position_m).squaredNorm();
  const double rms = std::sqrt(s2 / n);
  EXPECT_GT(rms, 1e-5);
  EXPECT_LT(rms, 5e-4);
}

TEST(Gesture, DeterministicAndValidated) {
  const GestureTrajectory a(GestureParams{}, 0.0, 9), b(GestureParams{}, 0.0, 9), c(GestureParams{}, 0.0, 10);
  EXPECT_EQ(a.pauses().back().end_s, b.pauses().back().end_s);
  EXPECT_EQ(a.pose(2.0).position_m, b.pose(2.0).position_m);
  EXPECT_NE(a.pauses().back().end_s, c.pauses().back().end_s);
  GestureParams bad;
  bad.waypoints_m = {{0, 0}};
  EXPECT_THROW(GestureTrajectory(bad, 0.0, 1), std::invalid_argument);
  bad = {};
  bad.mean_speed_mps = 0.0;
  EXPECT_THROW(GestureTrajectory(bad, 0.0, 1), std::invalid_argument);
}

// The hand of "as hard as the world": strokes bow off the chord (wiggle), the phone yaws at
// mid-stroke and comes back, corners miss their waypoints, the phone lies tilted; the closed-form
// velocity and acceleration still match the numeric derivatives and strokes still end at rest.
TEST(Gesture, WiggleYawDuringStrokesCornerMissAndTilt) {
  GestureParams p = no_tremor();
  p.wiggle_m = 0.004;
  p.yaw_stroke_rad = 0.03;
  p.waypoint_jitter_m = 0.01;
  p.tilt_pitch_rad = 0.01;
  p.tilt_roll_rad = -0.02;
  const GestureParams plain = no_tremor();
  double worst_lateral = 0.0, worst_yaw = 0.0, worst_corner = 0.0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const GestureTrajectory g(p, 1.0, seed);
    const GestureTrajectory ref(plain, 1.0, seed);  // the hand terms are a separate stream: same pause lengths
    const auto& pauses = g.pauses();
    ASSERT_EQ(pauses.size(), ref.pauses().size());
    for (std::size_t k = 0; k < pauses.size(); ++k)
      EXPECT_NEAR(pauses[k].end_s - pauses[k].start_s, ref.pauses()[k].end_s - ref.pauses()[k].start_s, 1e-12);
    for (std::size_t k = 1; k < pauses.size(); ++k) {
      const Vector3d nominal = p.origin_m + Vector3d(p.waypoints_m[k].x(), p.waypoints_m[k].y(), 0.0);
      worst_corner = std::max(worst_corner, (pauses[k].position_m - nominal).norm());
      EXPECT_NEAR((g.pose(pauses[k].mid_s()).position_m - pauses[k].position_m).norm(), 0.0, 1e-12);
    }
    for (std::size_t k = 0; k + 1 < pauses.size(); ++k) {
      const double t0 = pauses[k].end_s, t1 = pauses[k + 1].start_s;
      for (double t : {t0, t1}) {
        EXPECT_LT(g.velocity(t).norm(), 1e-12);
        EXPECT_LT(g.acceleration(t).norm(), 1e-9);
      }
      const Vector3d a = pauses[k].position_m, b = pauses[k + 1].position_m;
      const Vector3d dir = (b - a).normalized();
      const double yaw0 = std::atan2((g.pose(t0).attitude * Vector3d::UnitY()).y(), (g.pose(t0).attitude * Vector3d::UnitY()).x());
      for (double u = 0.05; u < 1.0; u += 0.05) {
        const double t = t0 + u * (t1 - t0);
        const Vector3d rel = g.pose(t).position_m - a;
        worst_lateral = std::max(worst_lateral, (rel - rel.dot(dir) * dir).norm());
        const Vector3d y = g.pose(t).attitude * Vector3d::UnitY();
        worst_yaw = std::max(worst_yaw, std::abs(std::remainder(std::atan2(y.y(), y.x()) - yaw0, 2 * M_PI)));
        EXPECT_NEAR((g.velocity(t) - g.Trajectory::velocity(t)).norm(), 0.0, 1e-5);
        EXPECT_NEAR((g.acceleration(t) - g.Trajectory::acceleration(t)).norm(), 0.0, 2e-4);
        EXPECT_LE(g.velocity(t).norm(), g.max_speed_mps());
      }
    }
    // tilted: gravity leaks into body x/y
    const Vector3d up_body = g.pose(0.5).attitude.conjugate() * Vector3d::UnitZ();
    EXPECT_NEAR(std::hypot(up_body.x(), up_body.y()), std::sin(std::hypot(0.01, 0.02)), 2e-4);
  }
  EXPECT_GT(worst_lateral, 0.004);   // 20 seeds × 4 strokes of N(0, 4 mm): some bow > 1σ
  EXPECT_LT(worst_lateral, 0.025);
  EXPECT_GT(worst_corner, 0.01);
  EXPECT_LT(worst_corner, 0.06);
  EXPECT_GT(worst_yaw, 0.03);        // mid-stroke yaw + waypoint heading changes (std 0.035)
  GestureParams bad = no_tremor();
  bad.wiggle_m = -1.0;
  EXPECT_THROW(GestureTrajectory(bad, 0.0, 1), std::invalid_argument);
}
