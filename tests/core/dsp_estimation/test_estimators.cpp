// PCA, particle filter, GMM and linear SVM against known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/LU>

#include "locus/dsp/gmm.hpp"
#include "locus/dsp/particle_filter.hpp"
#include "locus/dsp/pca.hpp"
#include "locus/dsp/svm.hpp"

namespace locus::dsp {
namespace {

TEST(Pca, RecoversAxesOfAnisotropicGaussian) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n01;
  const double angle = 0.6;
  Eigen::Matrix2d rot;
  rot << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  Eigen::MatrixXd x(20000, 2);
  for (Eigen::Index i = 0; i < x.rows(); ++i) x.row(i) = (rot * Eigen::Vector2d(3.0 * n01(rng), 0.5 * n01(rng))).transpose() + Eigen::RowVector2d(1, -2);
  Pca pca;
  pca.fit(x);
  EXPECT_NEAR(pca.explained_variance()[0], 9.0, 0.3);
  EXPECT_NEAR(pca.explained_variance()[1], 0.25, 0.01);
  EXPECT_NEAR(std::abs(pca.components().col(0).dot(rot.col(0))), 1.0, 1e-3);
  EXPECT_NEAR(pca.mean()[0], 1.0, 0.05);
  const Eigen::MatrixXd back = pca.inverse_transform(pca.transform(x));
  EXPECT_TRUE(back.isApprox(x, 1e-9));
  EXPECT_NEAR(pca.explained_variance_ratio().sum(), 1.0, 1e-12);
  // The closed-form 2-D axis agrees.
  std::vector<double> xs(x.rows()), ys(x.rows());
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    xs[i] = x(i, 0);
    ys[i] = x(i, 1);
  }
  const PrincipalAxis2d ax = principal_axis_2d(xs.data(), ys.data(), xs.size());
  EXPECT_NEAR(ax.angle_rad, angle, 0.01);
  EXPECT_NEAR(ax.variance_major, pca.explained_variance()[0], 1e-6);
  EXPECT_GT(ax.linearity(), 0.95);
  EXPECT_THROW(pca.fit(Eigen::MatrixXd(1, 2)), std::invalid_argument);
}

TEST(ParticleFilter, SystematicResamplingCopiesFloorOrCeilOfNw) {
  ParticleFilter<int> pf(10, 7);
  for (int i = 0; i < 10; ++i) pf.particles()[i] = i;
  // Weights 0.35, 0.25, 0.4 on particles 0, 1, 2, zero elsewhere (via a log-likelihood).
  const double w[3] = {0.35, 0.25, 0.4};
  pf.update([&](const int& p) { return p < 3 ? std::log(w[p]) : -INFINITY; });
  EXPECT_NEAR(pf.effective_sample_size(), 1.0 / (0.35 * 0.35 + 0.25 * 0.25 + 0.4 * 0.4), 1e-9);
  for (int rep = 0; rep < 50; ++rep) {
    ParticleFilter<int> copy = pf;
    copy.resample();
    int counts[10] = {};
    for (int p : copy.particles()) ++counts[p];
    EXPECT_TRUE(counts[0] == 3 || counts[0] == 4);
    EXPECT_TRUE(counts[1] == 2 || counts[1] == 3);
    EXPECT_EQ(counts[2], 4);
    EXPECT_EQ(counts[0] + counts[1] + counts[2], 10);
    copy.rng().discard(rep);
  }
}

TEST(ParticleFilter, MatchesKalmanPosteriorForGaussianModel) {
  // Prior N(0, 4), measurement z = x + N(0, 1) with z = 2: posterior mean 1.6, variance 0.8.
  ParticleFilter<double> pf(20000, 11);
  std::normal_distribution<double> prior(0.0, 2.0);
  pf.initialize([&](double& x, auto& rng) { x = prior(rng); });
  ASSERT_TRUE(pf.update([](const double& x) { return -0.5 * (2.0 - x) * (2.0 - x); }));
  const double mean = pf.mean([](const double& x) { return x; }, 0.0);
  const double var = pf.mean([&](const double& x) { return (x - mean) * (x - mean); }, 0.0);
  EXPECT_NEAR(mean, 1.6, 0.05);
  EXPECT_NEAR(var, 0.8, 0.05);
  pf.resample();
  const double mean2 = pf.mean([](const double& x) { return x; }, 0.0);
  EXPECT_NEAR(mean2, 1.6, 0.05);
  // An impossible measurement resets to uniform weights and says so.
  EXPECT_FALSE(pf.update([](const double&) { return -INFINITY; }));
  EXPECT_NEAR(pf.effective_sample_size(), 20000.0, 1e-6);
}

TEST(Gmm, RecoversTwoComponentsAndLikelihoodIncreases) {
  std::mt19937 rng(4);
  std::normal_distribution<double> n01;
  Eigen::MatrixXd x(3000, 2);
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    if (i % 3 == 0) x.row(i) << 5 + 0.5 * n01(rng), 5 + 1.0 * n01(rng);
    else x.row(i) << -2 + 1.0 * n01(rng), 0.3 * n01(rng);
  }
  Gmm g;
  g.fit(x, {.components = 2, .seed = 3});
  const int a = g.means()[0][0] > g.means()[1][0] ? 0 : 1;
  EXPECT_NEAR(g.weights()[a], 1.0 / 3, 0.02);
  EXPECT_NEAR(g.means()[a][0], 5, 0.1);
  EXPECT_NEAR(g.means()[1 - a][1], 0, 0.05);
  EXPECT_NEAR(g.covariances()[a](1, 1), 1.0, 0.1);
  EXPECT_NEAR(g.covariances()[1 - a](1, 1), 0.09, 0.01);
  for (std::size_t i = 1; i < g.history().size(); ++i) EXPECT_GE(g.history()[i], g.history()[i - 1] - 1e-9);
  EXPECT_EQ(g.predict(Eigen::Vector2d(5, 5)), a);
  EXPECT_NEAR(g.posterior(Eigen::Vector2d(-2, 0)).sum(), 1.0, 1e-12);
  EXPECT_THROW(g.fit(Eigen::MatrixXd(1, 2), {.components = 2}), std::invalid_argument);
}

TEST(Gmm, SingleComponentLogLikelihoodIsTheNormalDensity) {
  Gmm g;
  Eigen::Matrix2d cov;
  cov << 2.0, 0.3, 0.3, 1.0;
  g.set({1.0}, {Eigen::Vector2d(1, 2)}, {cov});
  const Eigen::Vector2d x(0.5, 3.0);
  const Eigen::Vector2d d = x - Eigen::Vector2d(1, 2);
  const double expect = -std::log(2 * std::numbers::pi) - 0.5 * std::log(cov.determinant()) - 0.5 * d.dot(cov.inverse() * d);
  EXPECT_NEAR(g.log_likelihood(x), expect, 1e-12);
  EXPECT_THROW(g.set({0.5}, {Eigen::Vector2d(0, 0)}, {cov}), std::invalid_argument);
}

TEST(LinearSvm, KnownWeightsAndOneVsRest) {
  LinearSvm bin(Eigen::RowVector2d(1.0, -2.0), Eigen::VectorXd::Constant(1, 0.5));
  EXPECT_EQ(bin.predict(Eigen::Vector2d(1, 0)), 1);   // 1.5 > 0
  EXPECT_EQ(bin.predict(Eigen::Vector2d(0, 1)), 0);   // -1.5
  bin.set_standardization(Eigen::Vector2d(1, 0), Eigen::Vector2d(2, 1));
  Eigen::VectorXd dv(1);
  bin.decision(Eigen::Vector2d(3, 0), dv);            // ((3-1)/2)*1 + 0.5
  EXPECT_DOUBLE_EQ(dv[0], 1.5);
  Eigen::MatrixXd w(3, 2);
  w << 1, 0, 0, 1, -1, -1;
  LinearSvm multi(w, Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(multi.predict(Eigen::Vector2d(2, 1)), 0);
  EXPECT_EQ(multi.predict(Eigen::Vector2d(1, 2)), 1);
  EXPECT_EQ(multi.predict(Eigen::Vector2d(-1, -1)), 2);
  EXPECT_THROW(LinearSvm(w, Eigen::Vector2d(0, 0)), std::invalid_argument);
}

TEST(LinearSvm, PegasosSeparatesSeparableClasses) {
  std::mt19937 rng(9);
  std::normal_distribution<double> n01;
  const Eigen::Vector2d centers[3] = {{4, 0}, {-2, 3.5}, {-2, -3.5}};
  Eigen::MatrixXd x(600, 2);
  Eigen::VectorXi y(600);
  for (int i = 0; i < 600; ++i) {
    y[i] = i % 3;
    x.row(i) = (centers[i % 3] + 0.6 * Eigen::Vector2d(n01(rng), n01(rng))).transpose();
  }
  const LinearSvm m = train_linear_svm(x, y, 3, {.lambda = 1e-3, .epochs = 30});
  int correct = 0;
  for (int i = 0; i < 600; ++i) correct += m.predict(x.row(i).transpose()) == y[i];
  EXPECT_GE(correct, 594);
  EXPECT_THROW(train_linear_svm(x, Eigen::VectorXi::Constant(600, 5), 3), std::invalid_argument);
}

}  // namespace
}  // namespace locus::dsp
