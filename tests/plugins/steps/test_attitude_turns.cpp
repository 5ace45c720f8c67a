// `attitude` on synthetic rotations with known truth (Madgwick and Mahony, with and without the
// magnetometer) and `turns` on synthetic walks with known turns.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

#include "motion_test_util.hpp"
#include "walk_sim.hpp"

namespace locus::test {
namespace {

constexpr double kG = 9.80665;

/// A device rotating with a time-varying angular velocity (body frame), true attitude integrated
/// exactly per sample; the accelerometer reads gravity only (rotation about the sensor), the field
/// is a tilted Earth field.
struct Rotation {
  std::vector<ImuSample> samples;
  std::vector<Eigen::Quaterniond> truth;
};

Rotation simulate_rotation(double duration_s, double rate_hz, bool mag, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  Rotation r;
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d field(18.0, 0.0, -42.0);  // north + down component, reference x = magnetic north
  const double dt = 1.0 / rate_hz;
  for (int i = 0; i * dt < duration_s; ++i) {
    const double t = i * dt;
    // Quiet 5 s (convergence), then rotations about all axes with pauses.
    Eigen::Vector3d w = Eigen::Vector3d::Zero();
    if (t > 5.0) {
      const double u = t - 5.0;
      w = Eigen::Vector3d(0.8 * std::sin(0.7 * u), 0.6 * std::sin(1.1 * u + 1.0), 1.2 * std::sin(0.4 * u)) *
          (std::fmod(u, 10.0) < 7.0 ? 1.0 : 0.0);
    }
    ImuSample s;
    s.t_s = t;
    const Eigen::Vector3d acc = q.conjugate() * Eigen::Vector3d(0, 0, kG);
    const Eigen::Vector3d m = q.conjugate() * field;
    for (int k = 0; k < 3; ++k) {
      s.accel_mps2[k] = static_cast<float>(acc[k] + 0.05 * n01(rng));
      s.gyro_radps[k] = static_cast<float>(w[k] + 0.005 * n01(rng));
      s.mag_ut[k] = static_cast<float>(m[k] + 0.3 * n01(rng));
    }
    s.has_mag = mag;
    r.samples.push_back(s);
    r.truth.push_back(q);
    // Exact integration of a constant body rate over dt.
    const double ang = w.norm() * dt;
    if (ang > 0) q = (q * Eigen::Quaterniond(Eigen::AngleAxisd(ang, w.normalized()))).normalized();
  }
  return r;
}

double tilt_error_deg(const Eigen::Quaterniond& est, const Eigen::Quaterniond& truth) {
  const Eigen::Vector3d up_est = est.conjugate() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_true = truth.conjugate() * Eigen::Vector3d::UnitZ();
  return std::acos(std::clamp(up_est.dot(up_true), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

double angle_deg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b) * 180.0 / std::numbers::pi;
}

TEST(Attitude, TracksSyntheticRotationsWithinBounds) {
  for (const char* kind : {"madgwick", "mahony"}) {
    for (bool mag : {false, true}) {
      TestHost host;
      Params p;
      p.set("ahrs", std::string(kind));
      p.set("output_rate_hz", 0.0);
      p.set("ahrs_gain", std::string(kind) == "madgwick" ? 0.1 : 1.0);
      auto det = make_detector("attitude", host, p);
      const Rotation rot = simulate_rotation(60.0, 100.0, mag, 5);
      CollectingSink sink;
      feed_imu(*det, rot.samples, sink, 16);
      const auto att = events_of<Attitude>(sink);
      ASSERT_EQ(att.size(), rot.samples.size());
      double max_tilt = 0, max_full = 0, max_yaw_rel = 0;
      const Eigen::Quaterniond q0_est(att[400].q_wxyz[0], att[400].q_wxyz[1], att[400].q_wxyz[2], att[400].q_wxyz[3]);
      for (std::size_t i = 500; i < att.size(); ++i) {  // after 5 s of convergence
        const Eigen::Quaterniond e(att[i].q_wxyz[0], att[i].q_wxyz[1], att[i].q_wxyz[2], att[i].q_wxyz[3]);
        max_tilt = std::max(max_tilt, tilt_error_deg(e, rot.truth[i]));
        if (mag) max_full = std::max(max_full, angle_deg(e, rot.truth[i]));
        // Without a field the yaw reference is arbitrary: compare rotations relative to t = 4 s.
        else max_yaw_rel = std::max(max_yaw_rel, angle_deg(q0_est.conjugate() * e, rot.truth[400].conjugate() * rot.truth[i]));
      }
      std::printf("[ measured ] attitude %s mag=%d: max tilt error %.2f deg, max %s error %.2f deg\n", kind, mag, max_tilt,
                  mag ? "full-attitude" : "relative-rotation", mag ? max_full : max_yaw_rel);
      EXPECT_LT(max_tilt, 3.0) << kind << " mag=" << mag;
      if (mag) EXPECT_LT(max_full, 5.0) << kind;
      else EXPECT_LT(max_yaw_rel, 6.0) << kind;
      // heading_rad is the heading of the body y axis of q.
      const auto& last = att.back();
      const Eigen::Quaterniond e(last.q_wxyz[0], last.q_wxyz[1], last.q_wxyz[2], last.q_wxyz[3]);
      const Eigen::Vector3d y = e * Eigen::Vector3d::UnitY();
      EXPECT_NEAR(last.heading_rad, std::atan2(y.y(), y.x()), 1e-4);
    }
  }
}

TEST(Attitude, EmitsAtTheConfiguredRate) {
  TestHost host;
  Params p;
  p.set("output_rate_hz", 10.0);
  auto det = make_detector("attitude", host, p);
  const Rotation rot = simulate_rotation(20.0, 200.0, false, 1);
  CollectingSink sink;
  feed_imu(*det, rot.samples, sink, 50);
  const auto att = events_of<Attitude>(sink);
  EXPECT_NEAR(static_cast<double>(att.size()), 200.0, 2.0);
  for (std::size_t i = 1; i < att.size(); ++i) EXPECT_NEAR(att[i].t_s - att[i - 1].t_s, 0.1, 0.006);
}

TEST(Turns, DetectsEachTurnWithItsAngle) {
  for (bool mag : {false, true}) {
    TestHost host;
    auto det = make_detector("turns", host);
    WalkTruth truth;
    WalkOptions o;
    o.with_mag = mag;
    const auto imu = simulate_walk(mixed_walk(), o, truth);
    CollectingSink sink;
    feed_imu(*det, imu, sink);
    det->finish(sink);
    const auto turns = events_of<Attitude>(sink);
    ASSERT_EQ(turns.size(), truth.turn_rad.size()) << "mag=" << mag;
    for (std::size_t i = 0; i < turns.size(); ++i) {
      const double angle = 2.0 * std::atan2(turns[i].q_wxyz[3], turns[i].q_wxyz[0]);
      const double err = std::remainder(angle - truth.turn_rad[i], 2 * std::numbers::pi);
      std::printf("[ measured ] turn %zu: true %+.1f deg, detected %+.1f deg at t=%.2f (turn ends %.2f)\n", i,
                  truth.turn_rad[i] * 180 / std::numbers::pi, angle * 180 / std::numbers::pi, turns[i].t_s,
                  truth.turn_end_t_s[i]);
      EXPECT_LT(std::abs(err), 10.0 * std::numbers::pi / 180.0);
      EXPECT_NEAR(turns[i].t_s, truth.turn_end_t_s[i], 0.8);
    }
  }
}

TEST(Turns, NoTurnsOnAStraightWalk) {
  TestHost host;
  auto det = make_detector("turns", host);
  WalkTruth truth;
  const auto imu = simulate_walk({{WalkSegment::Stand, 2.0}, {WalkSegment::Walk, 60.0, 1.6, 2.2, 0.7}}, WalkOptions{}, truth);
  CollectingSink sink;
  feed_imu(*det, imu, sink);
  det->finish(sink);
  EXPECT_EQ(events_of<Attitude>(sink).size(), 0u);
}

}  // namespace
}  // namespace locus::test
