// PhoneImu: gravity on the right axis at rest, bias and noise statistics, gyro integrates back to
// the attitude change of a moving trajectory, determinism for a seed.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include <filesystem>
#include <fstream>
#include <string>

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
  // an ideal ADC, no cross-axis, no drift, regular stamps: the tests below isolate one error each
  c.accel_cross_axis = Eigen::Matrix3d::Zero();
  c.gyro_cross_axis = Eigen::Matrix3d::Zero();
  c.accel_bias_rw = 0.0;
  c.gyro_bias_rw = 0.0;
  c.adc_bits = 0;
  c.stamp_jitter_std_s = 0.0;
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
  c.gyro_cross_axis = Eigen::Matrix3d::Zero();
  c.gyro_bias_rw = 0.0;
  c.adc_bits = 0;
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

// ------------------------------------------------------------------------------------------ the
// "as hard as the world" error terms: bias random walk, cross-axis, ADC, row-stamp jitter

TEST(PhoneImu, BiasRandomWalkGrowsWithTheSquareRootOfTime) {
  // Many devices at rest, only the random walk on: the bias change over 9 s has std rw·√9 per axis,
  // and the change over the second half is independent of the first (Brownian increments).
  PhoneImuConfig c = rest_config();
  c.accel_noise_density = 0.0;
  c.gyro_noise_density = 0.0;
  c.accel_bias_rw = 0.01;
  c.gyro_bias_rw = 0.002;
  c.magnetometer = false;
  const StaticTrajectory flat(Vector3d::Zero());
  const int devices = 400;
  double s9a = 0.0, s9g = 0.0, cross = 0.0, s_first = 0.0, s_second = 0.0;
  for (int d = 0; d < devices; ++d) {
    PhoneImu imu(c);
    Rng rng(1000 + d);
    const ImuReading r0 = imu.sample(flat, std::nullopt, 0.0, rng);
    ImuReading r45, r9;
    for (int k = 1; k <= 900; ++k) {  // 100 Hz
      const ImuReading r = imu.sample(flat, std::nullopt, k / 100.0, rng);
      if (k == 450) r45 = r;
      if (k == 900) r9 = r;
    }
    for (int i = 0; i < 3; ++i) {
      const double da = r9.accel_mps2[i] - r0.accel_mps2[i], dg = r9.gyro_radps[i] - r0.gyro_radps[i];
      s9a += da * da;
      s9g += dg * dg;
      const double a1 = r45.accel_mps2[i] - r0.accel_mps2[i], a2 = r9.accel_mps2[i] - r45.accel_mps2[i];
      cross += a1 * a2;
      s_first += a1 * a1;
      s_second += a2 * a2;
    }
  }
  const double n = 3.0 * devices;
  EXPECT_NEAR(std::sqrt(s9a / n), 0.01 * 3.0, 0.1 * 0.01 * 3.0);  // 1200 samples: ±~4 % std error
  EXPECT_NEAR(std::sqrt(s9g / n), 0.002 * 3.0, 0.1 * 0.002 * 3.0);
  EXPECT_NEAR(std::sqrt(s_first / n), std::sqrt(s_second / n), 0.12 * std::sqrt(s_first / n));
  EXPECT_LT(std::abs(cross / std::sqrt(s_first * s_second)), 0.1);  // increments uncorrelated
}

TEST(PhoneImu, CrossAxisLeaksGravityIntoXAndY) {
  PhoneImuConfig c = rest_config();
  c.accel_noise_density = 0.0;
  c.accel_bias_mps2 = Vector3d::Zero();
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  m(0, 2) = 0.002;   // x senses 0.2 % of z
  m(1, 2) = -0.001;
  m(2, 2) = 0.5;     // the diagonal is ignored (scale errors are separate)
  c.accel_cross_axis = m;
  c.magnetometer = false;
  PhoneImu imu(c);
  Rng rng(3);
  const ImuReading r = imu.sample(StaticTrajectory(Vector3d::Zero()), std::nullopt, 0.0, rng);
  EXPECT_NEAR(r.accel_mps2.x(), 0.002 * 9.81, 1e-12);
  EXPECT_NEAR(r.accel_mps2.y(), -0.001 * 9.81, 1e-12);
  EXPECT_NEAR(r.accel_mps2.z(), 9.81, 1e-12);
  EXPECT_EQ(imu.errors().accel_cross_axis(2, 2), 0.0);
  // drawn: zero diagonal, off-diagonal std = the set sigma
  PhoneImuConfig d;
  d.magnetometer = false;
  d.accel_cross_axis_std_rad = 0.01;
  double s2 = 0.0;
  int n = 0;
  for (int k = 0; k < 300; ++k) {
    PhoneImu i2(d);
    Rng r2(50 + k);
    i2.sample(StaticTrajectory(Vector3d::Zero()), std::nullopt, 0.0, r2);
    const auto& x = i2.errors().accel_cross_axis;
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(x(a, a), 0.0);
      for (int b = 0; b < 3; ++b)
        if (a != b) {
          s2 += x(a, b) * x(a, b);
          ++n;
        }
    }
  }
  EXPECT_NEAR(std::sqrt(s2 / n), 0.01, 0.001);
}

TEST(PhoneImu, SixteenBitAdcQuantisesAndClips) {
  PhoneImuConfig c = rest_config();  // ±8 g / ±2000 °/s by default
  c.adc_bits = 16;
  c.magnetometer = false;
  const double qa = 2.0 * 8.0 * 9.80665 / 65536.0, qg = 2.0 * 34.906585 / 65536.0;
  EXPECT_NEAR(c.accel_step_mps2(), qa, 1e-15);
  EXPECT_NEAR(c.gyro_step_radps(), qg, 1e-15);
  EXPECT_NEAR(qa, 2.394e-3, 1e-6);  // what the reference scene amil-101 shows: 2.4e-3 m/s², 1.07e-3 rad/s
  EXPECT_NEAR(qg, 1.065e-3, 1e-6);
  PhoneImu imu(c);
  Rng rng(4);
  const StaticTrajectory flat(Vector3d::Zero());
  double mean_z = 0.0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    const ImuReading r = imu.sample(flat, std::nullopt, k / 200.0, rng);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(r.accel_mps2[i] / qa, std::round(r.accel_mps2[i] / qa), 1e-6);
      EXPECT_NEAR(r.gyro_radps[i] / qg, std::round(r.gyro_radps[i] / qg), 1e-6);
    }
    mean_z += r.accel_mps2.z();
  }
  // the noise (σ 0.021 m/s² ≈ 9 steps) dithers the ADC: the mean is not biased by the rounding
  EXPECT_NEAR(mean_z / n, 9.81 + 0.03, 5.0 * 1.5e-3 * std::sqrt(200.0) / std::sqrt(n));
  // clipping: a ±1 g part reads at most 32767 steps
  PhoneImuConfig small = rest_config();
  small.adc_bits = 16;
  small.accel_full_scale_mps2 = 9.80665;
  small.accel_noise_density = 0.0;
  small.accel_bias_mps2 = Vector3d(0.0, 0.0, 0.5);
  small.magnetometer = false;
  PhoneImu clip(small);
  const double step = small.accel_step_mps2();
  EXPECT_DOUBLE_EQ(clip.sample(flat, std::nullopt, 0.0, rng).accel_mps2.z(), 32767.0 * step);
  small.adc_bits = 2;
  EXPECT_THROW(PhoneImu{small}, std::invalid_argument);
}

TEST(PhoneImu, RowStampJitterHasTheSetStdAndKeepsRowsInOrder) {
  PhoneImuConfig c = rest_config();
  c.stamp_jitter_std_s = 1.2e-4;
  c.magnetometer = false;
  PhoneImu imu(c);
  Rng rng(5);
  const StaticTrajectory flat(Vector3d::Zero());
  double s = 0.0, s2 = 0.0, lag = 0.0, prev = 0.0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    const double o = imu.sample(flat, std::nullopt, k / 200.0, rng).stamp_offset_s;
    EXPECT_LE(std::abs(o), 0.45 / 200.0);
    s += o;
    s2 += o * o;
    lag += o * prev;
    prev = o;
  }
  EXPECT_NEAR(s / n, 0.0, 5.0 * 1.2e-4 / std::sqrt(n));
  EXPECT_NEAR(std::sqrt(s2 / n), 1.2e-4, 0.03 * 1.2e-4);
  EXPECT_LT(std::abs(lag / s2), 0.05);  // white, as in the reference scene (lag-1 correlation 0.02)
}

TEST(PhoneImu, EngineWritesJitteredRowStamps) {
  // Through SceneSimulator: imu.csv rows are k/rate + jitter on the device clock, not a regular grid.
  Simulation sim;
  sim.name = "imu-jitter";
  sim.seed = 8;
  sim.duration_s = 20.0;
  DeviceModel d;
  d.id = "P";
  d.record_audio = false;
  d.trajectory = std::make_shared<StaticTrajectory>(Vector3d(1, 1, 1));
  PhoneImuConfig c;  // the defaults: 0.12 ms row-stamp jitter
  c.magnetometer = false;
  c.rate_hz = 200.0;
  d.imu = std::make_shared<PhoneImu>(c);
  sim.devices.push_back(d);
  const auto dir = std::filesystem::path(LOCUS_BINARY_DIR) / "test_tmp" / "sim_motion" / "imu_jitter";
  std::filesystem::remove_all(dir);
  SceneSimulator(sim).write(dir.string());
  std::ifstream f(dir / "P" / "imu.csv");
  std::string line;
  std::getline(f, line);  // header
  std::vector<double> t;
  while (std::getline(f, line)) t.push_back(std::stod(line.substr(0, line.find(','))));
  ASSERT_GT(t.size(), 3900u);
  double s2 = 0.0, dmin = 1.0, dmax = 0.0;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const double r = t[k] - static_cast<double>(k) / 200.0;
    s2 += r * r;
    dmin = std::min(dmin, t[k] - t[k - 1]);
    dmax = std::max(dmax, t[k] - t[k - 1]);
  }
  EXPECT_NEAR(std::sqrt(s2 / (t.size() - 1)), 1.2e-4, 0.1 * 1.2e-4);
  EXPECT_GT(dmin, 0.0);  // strictly increasing
  EXPECT_GT(dmax - dmin, 4e-4);  // not a regular grid
}

TEST(PhoneImu, ScaleErrorsScalesEveryErrorButTheAdc) {
  PhoneImuConfig c;
  const PhoneImuConfig base = c;
  c.scale_errors(2.0);
  EXPECT_DOUBLE_EQ(c.accel_noise_density, 2.0 * base.accel_noise_density);
  EXPECT_DOUBLE_EQ(c.gyro_bias_rw, 2.0 * base.gyro_bias_rw);
  EXPECT_DOUBLE_EQ(c.accel_cross_axis_std_rad, 2.0 * base.accel_cross_axis_std_rad);
  EXPECT_DOUBLE_EQ(c.stamp_jitter_std_s, 2.0 * base.stamp_jitter_std_s);
  EXPECT_DOUBLE_EQ(c.accel_scale_std, 2.0 * base.accel_scale_std);
  EXPECT_DOUBLE_EQ(c.accel_step_mps2(), base.accel_step_mps2());
  EXPECT_THROW(c.scale_errors(-1.0), std::invalid_argument);
}
