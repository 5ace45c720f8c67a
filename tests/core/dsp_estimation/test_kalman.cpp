// Kalman filter against closed forms (running mean, scalar steady-state Riccati), fixed vs dynamic
// sizes, and no heap allocation in predict/update with dynamic sizes (Eigen's malloc guard).
#define EIGEN_RUNTIME_NO_MALLOC
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "locus/dsp/kalman.hpp"

namespace locus::dsp {
namespace {

TEST(Kalman, StaticScalarIsTheRunningMean) {
  // x constant, P0 huge: the estimate is the sample mean and P = R / n.
  KalmanFilter<1, 1> kf;
  kf.P(0, 0) = 1e12;
  kf.H(0, 0) = 1.0;
  kf.R(0, 0) = 4.0;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 2.0);
  double sum = 0.0;
  for (int n = 1; n <= 500; ++n) {
    const double z = 3.0 + noise(rng);
    sum += z;
    kf.predict();
    ASSERT_TRUE(kf.update(Eigen::Matrix<double, 1, 1>(z)));
    EXPECT_NEAR(kf.x(0), sum / n, 1e-6 * (1 + std::abs(sum / n)));
    EXPECT_NEAR(kf.P(0, 0), 4.0 / n, 1e-6);
  }
}

TEST(Kalman, ScalarRandomWalkReachesRiccatiSteadyState) {
  const double q = 0.5, r = 2.0;
  KalmanFilter<1, 1> kf;
  kf.H(0, 0) = 1;
  kf.Q(0, 0) = q;
  kf.R(0, 0) = r;
  for (int i = 0; i < 200; ++i) {
    kf.predict();
    kf.update(Eigen::Matrix<double, 1, 1>(0.0));
  }
  // Predicted covariance solves Pp^2 - q Pp - q r = 0; the posterior is Pp r / (Pp + r).
  const double pp = 0.5 * (q + std::sqrt(q * q + 4 * q * r));
  EXPECT_NEAR(kf.P(0, 0), pp * r / (pp + r), 1e-12);
  EXPECT_NEAR(kf.gain()(0, 0), pp / (pp + r), 1e-12);
}

template <typename KF>
void setup_cv(KF& kf, double dt) {
  kf.F << 1, dt, 0, 1;
  kf.H << 1, 0;
  kf.Q << dt * dt * dt / 3, dt * dt / 2, dt * dt / 2, dt;
  kf.Q *= 0.01;
  kf.R << 0.25;
  kf.B << 0.5 * dt * dt, dt;
  kf.P *= 100.0;
}

TEST(Kalman, FixedAndDynamicAgreeAndTrackConstantVelocity) {
  const double dt = 0.1;
  KalmanFilter<2, 1, 1> fixed;
  DynamicKalmanFilter dyn(2, 1, 1);
  setup_cv(fixed, dt);
  setup_cv(dyn, dt);
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.5);
  double nis_sum = 0;
  int count = 0;
  Eigen::VectorXd ud(1), zd(1);  // dynamic inputs, allocated before the guard
  Eigen::internal::set_is_malloc_allowed(false);
  for (int k = 1; k <= 400; ++k) {
    const double truth = 1.0 + 2.0 * k * dt + 0.5 * 0.3 * (k * dt) * (k * dt);  // accel 0.3 as control
    const double z = truth + noise(rng);
    Eigen::Matrix<double, 1, 1> u(0.3);
    ud(0) = 0.3;
    zd(0) = z;
    fixed.predict(u);
    dyn.predict(ud);
    fixed.update(Eigen::Matrix<double, 1, 1>(z));
    dyn.update(zd);
    if (k > 50) {
      nis_sum += fixed.nis();
      ++count;
    }
  }
  Eigen::internal::set_is_malloc_allowed(true);
  EXPECT_NEAR(fixed.x(0), dyn.x(0), 1e-9);
  EXPECT_NEAR(fixed.x(1), dyn.x(1), 1e-9);
  EXPECT_TRUE(fixed.P.isApprox(dyn.P, 1e-9));
  const double t = 400 * dt;
  EXPECT_NEAR(fixed.x(1), 2.0 + 0.3 * t, 0.3);
  // A consistent filter has mean NIS ~ 1 (one measurement dimension).
  EXPECT_NEAR(nis_sum / count, 1.0, 0.25);
}

TEST(Kalman, RejectsNonPositiveInnovationCovariance) {
  KalmanFilter<1, 1> kf;
  kf.H(0, 0) = 1;
  kf.R(0, 0) = -10;  // S = P + R < 0
  kf.x(0) = 5;
  EXPECT_FALSE(kf.update(Eigen::Matrix<double, 1, 1>(0.0)));
  EXPECT_EQ(kf.x(0), 5);
}

}  // namespace
}  // namespace locus::dsp
