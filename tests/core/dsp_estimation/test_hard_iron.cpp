// dsp::HardIronCalibrator: the hard iron of a turning device is learnt (flat on a turntable: the
// horizontal components; tumbling: all three), a still device keeps a zero estimate whatever its
// reading, a gyro bias does not drag the estimate towards the reading, and update() never allocates
// (Eigen's malloc guard).
#define EIGEN_RUNTIME_NO_MALLOC
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "locus/dsp/ahrs.hpp"

namespace locus::dsp {
namespace {

const Eigen::Vector3d kField(19.0, 0.0, -44.0);  // world field, uT (x north, z up)
const Eigen::Vector3d kHardIron(2.5, -3.0, 1.5);

/// Feeds `seconds` of 100 Hz samples of a device whose attitude is rot(t) (body -> world) and whose
/// body rate is rate(t); readings m = R^T F + h + noise, gyro = rate + bias + noise.
template <class Rot, class Rate>
void feed(HardIronCalibrator& c, double seconds, Rot rot, Rate rate, const Eigen::Vector3d& gyro_bias, unsigned seed,
          double mag_noise = 0.4) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 1.0);
  const double dt = 0.01;
  for (int i = 0; i <= static_cast<int>(seconds / dt); ++i) {
    const double t = i * dt;
    const Eigen::Matrix3d r = rot(t);
    const Eigen::Vector3d m = r.transpose() * kField + kHardIron + mag_noise * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Vector3d g = rate(t) + gyro_bias + 0.002 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    c.update(g, m, i == 0 ? -1.0 : dt);
  }
}

TEST(HardIronCalibrator, FlatTurningDeviceLearnsTheHorizontalComponents) {
  // A device lying flat on a train turning at 1.06 rad/s (tum's ellipse: one turn per 5.9 s).
  HardIronCalibrator c;
  const double w = 2.0 * M_PI / 5.9;
  feed(c, 60.0, [&](double t) { return Eigen::AngleAxisd(w * t, Eigen::Vector3d::UnitZ()).toRotationMatrix(); },
       [&](double) { return Eigen::Vector3d(0, 0, w); }, Eigen::Vector3d(0.001, -0.002, 0.003), 1);
  EXPECT_NEAR(c.hard_iron().x(), kHardIron.x(), 0.2);
  EXPECT_NEAR(c.hard_iron().y(), kHardIron.y(), 0.2);
  EXPECT_NEAR(c.hard_iron().z(), 0.0, 0.2) << "never turned about a horizontal axis: z stays near the prior's 0";
  EXPECT_GT(c.turns(), 50u);
}

TEST(HardIronCalibrator, TumblingDeviceLearnsAllThree) {
  HardIronCalibrator c;
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, 2.0, 3.0).normalized();
  const Eigen::Vector3d axis2 = Eigen::Vector3d(-2.0, 1.0, 0.5).normalized();
  // alternating rotations about two axes: rotation rate piecewise constant in the body frame
  auto rate = [&](double t) { return (static_cast<int>(t / 3.0) % 2 ? axis2 : axis) * 1.2; };
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  double last = 0.0;
  auto rot = [&](double t) {
    if (t > last) {
      r = r * Eigen::AngleAxisd(1.2 * (t - last), static_cast<int>(last / 3.0) % 2 ? axis2 : axis).toRotationMatrix();
      last = t;
    }
    return r;
  };
  feed(c, 60.0, rot, rate, Eigen::Vector3d::Zero(), 2);
  EXPECT_LT((c.hard_iron() - kHardIron).norm(), 0.3) << c.hard_iron().transpose();
  EXPECT_LT(c.max_std(), 0.2);
}

TEST(HardIronCalibrator, StillDeviceKeepsZeroWhateverItsReadingAndGyroBias) {
  // The failure of a sphere fit: a still device's readings are a noise blob around R^T F + h, which a
  // fit explains with a tiny sphere centred on the reading. Here nothing turns: no equation at all.
  HardIronCalibrator c;
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  feed(c, 120.0, [&](double) { return r; }, [](double) { return Eigen::Vector3d::Zero(); },
       Eigen::Vector3d(0.004, -0.004, 0.004), 3, 1.0);
  EXPECT_EQ(c.hard_iron().norm(), 0.0);
  EXPECT_EQ(c.turns(), 0u);
}

TEST(HardIronCalibrator, HandWiggleBelowTheTurnGateAddsNothing) {
  // +-3 deg of yaw wiggle at 1 Hz: each 0.5 s interval turns less than min_turn_rad.
  HardIronCalibrator c;
  const double amp = 3.0 * M_PI / 180.0;
  feed(c, 60.0,
       [&](double t) { return Eigen::AngleAxisd(amp * std::sin(2 * M_PI * t), Eigen::Vector3d::UnitZ()).toRotationMatrix(); },
       [&](double t) { return Eigen::Vector3d(0, 0, amp * 2 * M_PI * std::cos(2 * M_PI * t)); }, Eigen::Vector3d::Zero(), 4);
  EXPECT_EQ(c.turns(), 0u);
  EXPECT_EQ(c.hard_iron().norm(), 0.0);
}

TEST(HardIronCalibrator, UpdateNeverAllocates) {
  HardIronCalibrator c;
  Eigen::internal::set_is_malloc_allowed(false);
  for (int i = 0; i < 1000; ++i)
    c.update(Eigen::Vector3d(0, 0, 1.0), Eigen::Vector3d(20.0 * std::cos(0.01 * i), -20.0 * std::sin(0.01 * i), -44.0), 0.01);
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_GT(c.turns(), 0u);
}

}  // namespace
}  // namespace locus::dsp
