// PhoneImu: gravity on the right axis at rest, bias and noise statistics, gyro integrates back to
// the attitude change of a moving trajectory, determinism for a seed.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "locus/sim/motion/imu.hpp"
#include "locus/sim/motion/pedestrian.hpp"

using namespace locus::sim;
using namespace locus::sim::motion;
using Eigen::Vector3d;

namespace {

struct Stats {
  Vector3d mean = Vector3d::Zero(), std = Vector3d::Zero();
};
template <class F>
Stats stats(int n, F&& f) {
  Vector3d s = Vector3d::Zero(), s2 = Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Vector3d v = f(i);
    s += v;
    s2 += v.cwiseProduct(v);
  }
  Stats out;
  out.mean = s / n;
  out.std = (s2 / n - out.mean.cwiseProduct(out.mean)).cwiseMax(0.0).cwiseSqrt();
  return out;
}

PhoneImuConfig rest_config() {
  PhoneImuConfig c;
  c.rate_hz = 200.0;
  c.accel_bias_mps2 = Vector3d(0.05, -0.02, 0.03);
  c.gyro_bias_radps = Vector3d(0.004, -0.001, 0.002);
  c.mag_bias_ut = Vector3d(1.0, 2.0, -1.5);
  c.accel_scale = Vector3d::Zero();
  c.gyro_scale = Vector3d::Zero();
  return c;
}

}  // namespace

TEST(PhoneImu, AtRestFlatReadsGravityUpOnZWithSetBiasAndNoise) {
  const StaticTrajectory flat(Vector3d(1, 2, 0.8));
  PhoneImu imu(rest_config());
  Rng rng(7);
  const Vector3d field(12.1, 14.6, -44.0);
  const int n = 40000;
  std::vector<ImuReading> r;
  for (int i = 0; i < n; ++i) r.push_back(imu.sample(flat, field, i / 200.0, rng));
  const Stats a = stats(n, [&](int i) { return r[i].accel_mps2; });
  const Stats g = stats(n, [&](int i) { return r[i].gyro_radps; });
  const Stats m = stats(n, [&](int i) { return *r[i].mag_ut; });
  const double sa = 1.5e-3 * std::sqrt(200.0), sg = 1.2e-4 * std::sqrt(200.0);
  const double tol_a = 5.0 * sa / std::sqrt(n), tol_g = 5.0 * sg / std::sqrt(n);
  EXPECT_NEAR(a.mean.x(), 0.05, tol_a);
  EXPECT_NEAR(a.mean.y(), -0.02, tol_a);
  EXPECT_NEAR(a.mean.z(), 9.81 + 0.03, tol_a);
  EXPECT_NEAR(g.mean.x(), 0.004, tol_g);
  EXPECT_NEAR(g.mean.y(), -0.001, tol_g);
  EXPECT_NEAR(g.mean.z(), 0.002, tol_g);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(a.std[i], sa, 0.03 * sa) << "axis " << i;
    EXPECT_NEAR(g.std[i], sg, 0.03 * sg) << "axis " << i;
    EXPECT_NEAR(m.std[i], 0.3, 0.03 * 0.3) << "axis " << i;
  }
  EXPECT_NEAR(m.mean.x(), 12.1 + 1.0, 0.02);
  EXPECT_NEAR(m.mean.y(), 14.6 + 2.0, 0.02);
  EXPECT_NEAR(m.mean.z(), -44.0 - 1.5, 0.02);
}

TEST(PhoneImu, GravityFollowsTheAttitude) {
  // Phone standing on its bottom edge (body y up): +g on y. Lying screen down: −g on z.
  const Eigen::Quaterniond upright(Eigen::AngleAxisd(std::numbers::pi / 2, Vector3d::UnitX()));
  const Eigen::Quaterniond face_down(Eigen::AngleAxisd(std::numbers::pi, Vector3d::UnitY()));
  PhoneImuConfig c = rest_config();
  c.accel_noise_density = 0.0;
  c.accel_bias_mps2 = Vector3d::Zero();
  PhoneImu imu(c);
  Rng rng(1);
  const Vector3d a1 = imu.sample(StaticTrajectory(Vector3d::Zero(), upright), std::nullopt, 0.0, rng).accel_mps2;
  const Vector3d a2 = imu.sample(StaticTrajectory(Vector3d::Zero(), face_down), std::nullopt, 0.0, rng).accel_mps2;
  EXPECT_NEAR(a1.y(), 9.81, 1e-9);
  EXPECT_NEAR(a1.norm(), 9.81, 1e-9);
  EXPECT_NEAR(a2.z(), -9.81, 1e-9);
  EXPECT_NEAR(a2.norm(), 9.81, 1e-9);
}

TEST(PhoneImu, ScaleErrorMultipliesTheReading) {
  PhoneImuConfig c = rest_config();
  c.accel_noise_density = 0.0;
  c.accel_bias_mps2 = Vector3d::Zero();
  c.accel_scale = Vector3d(0.0, 0.0, 0.01);
  PhoneImu imu(c);
  Rng rng(1);
  EXPECT_NEAR(imu.sample(StaticTrajectory(Vector3d::Zero()), std::nullopt, 0.0, rng).accel_mps2.z(), 9.81 * 1.01, 1e-9);
}

TEST(PhoneImu, GyroIntegratesBackToTheAttitudeChange) {
  PedestrianParams pp;
  pp.path_m = {{0, 0}, {6, 0}, {6, 4}};
  pp.wobble_rad = 0.05;
  const PedestrianTrajectory walk(pp, 0.0, 3);
  PhoneImuConfig c;
  c.rate_hz = 400.0;
  c.gyro_noise_density = 0.0;
  c.gyro_bias_radps = Vector3d::Zero();
  c.gyro_scale = Vector3d::Zero();
  c.magnetometer = false;
  PhoneImu imu(c);
  Rng rng(2);
  const double t0 = walk.walk_start_s(), t1 = walk.walk_end_s();
  Eigen::Quaterniond q = walk.pose(t0).attitude;
  const double dt = 1.0 / c.rate_hz;
  Vector3d w_prev = imu.sample(walk, std::nullopt, t0, rng).gyro_radps;
  for (double t = t0 + dt; t <= t1 + 1e-12; t += dt) {
    const Vector3d w = imu.sample(walk, std::nullopt, t, rng).gyro_radps;
    const Vector3d w_mid = 0.5 * (w + w_prev);  // trapezoid
    const double angle = w_mid.norm() * dt;
    if (angle > 0) q = q * Eigen::Quaterniond(Eigen::AngleAxisd(angle, w_mid.normalized()));
    q.normalize();
    w_prev = w;
  }
  const Eigen::Quaterniond truth = walk.pose(std::floor((t1 - t0) / dt) * dt + t0).attitude;
  const double err = truth.angularDistance(q);
  const double total_turn = walk.pose(t0).attitude.angularDistance(truth);
  EXPECT_GT(total_turn, 1.3);  // the L turns ~90°
  EXPECT_LT(err, 5e-3) << "integrated gyro drifted " << err << " rad";
}

TEST(PhoneImu, DeterministicForASeed) {
  PedestrianParams pp;
  pp.path_m = {{0, 0}, {3, 0}};
  const PedestrianTrajectory walk(pp, 0.0, 3);
  auto run = [&](std::uint64_t seed) {
    PhoneImu imu;  // drawn biases, noise, scale
    Rng rng(seed);
    std::vector<double> out;
    for (int i = 0; i < 100; ++i) {
      const auto r = imu.sample(walk, Vector3d(20, 0, -40), i * 0.01, rng);
      out.insert(out.end(), {r.accel_mps2.x(), r.gyro_radps.y(), r.mag_ut->z()});
    }
    return out;
  };
  EXPECT_EQ(run(5), run(5));
  EXPECT_NE(run(5), run(6));
}

TEST(PhoneImu, RejectsBadConfigAndMissingField) {
  PhoneImuConfig c;
  c.rate_hz = 0.0;
  EXPECT_THROW(PhoneImu{c}, std::invalid_argument);
  c = {};
  c.accel_noise_density = -1.0;
  EXPECT_THROW(PhoneImu{c}, std::invalid_argument);
  Simulation sim;  // no magnetic field
  DeviceModel dev;
  dev.id = "A";
  dev.trajectory = std::make_shared<StaticTrajectory>(Vector3d::Zero());
  PhoneImu imu;  // magnetometer on
  Rng rng(1);
  try {
    imu.sample(sim, dev, 0.0, rng);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("magnetic_field_world_ut"), std::string::npos) << e.what();
  }
}
