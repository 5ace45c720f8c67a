// DTW against a brute-force reference, LB_Keogh as a true lower bound, early abandoning, open end.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "locus/dsp/dtw.hpp"

namespace locus::dsp {
namespace {

// Full-matrix reference with the same band rule as Dtw::distance.
double reference_dtw(const std::vector<float>& a, const std::vector<float>& b, std::size_t w) {
  const std::size_t n = a.size(), m = b.size();
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<std::vector<double>> d(n + 1, std::vector<double>(m + 1, inf));
  d[0][0] = 0;
  const double ratio = static_cast<double>(m) / n;
  for (std::size_t i = 1; i <= n; ++i)
    for (std::size_t j = 1; j <= m; ++j) {
      if (j < std::max(1.0, std::floor((double(i) - double(w)) * ratio)) || j > std::ceil((double(i) + double(w)) * ratio))
        continue;
      const double c = (double(a[i - 1]) - double(b[j - 1])) * (double(a[i - 1]) - double(b[j - 1]));
      d[i][j] = c + std::min({d[i - 1][j], d[i][j - 1], d[i - 1][j - 1]});
    }
  return d[n][m];
}

TEST(Dtw, KnownSmallExamples) {
  Dtw dtw(16);
  const std::vector<float> a{1, 2, 3}, b{1, 2, 2, 3}, c{0, 0, 0};
  EXPECT_DOUBLE_EQ(dtw.distance(a, b, 16), 0.0);  // warping absorbs the repeated 2
  EXPECT_DOUBLE_EQ(dtw.distance(a, a, 0), 0.0);
  EXPECT_DOUBLE_EQ(dtw.distance(a, c, 16), 1 + 4 + 9);  // each a[i] must meet some 0
  // [0,1] vs [1,0] unconstrained: best path (0-1)^2... costs: (0,1)=1,(1,0)=1 -> min path 1 + 0 + 1? compute:
  const std::vector<float> p{0, 1}, q{1, 0};
  EXPECT_DOUBLE_EQ(dtw.distance(p, q, 16), 2.0);
  Dtw abs_dtw(16, DtwCost::Absolute);
  EXPECT_DOUBLE_EQ(abs_dtw.distance(a, c, 16), 1 + 2 + 3);
}

TEST(Dtw, MatchesBruteForceWithAndWithoutBand) {
  std::mt19937 rng(3);
  std::normal_distribution<float> n01;
  Dtw dtw(64);
  for (int trial = 0; trial < 200; ++trial) {
    const std::size_t n = 5 + rng() % 40, m = 5 + rng() % 40, w = rng() % 12;
    std::vector<float> a(n), b(m);
    for (auto& x : a) x = n01(rng);
    for (auto& x : b) x = n01(rng);
    const double ref = reference_dtw(a, b, w);
    const double got = dtw.distance(a, b, w);
    if (std::isinf(ref)) EXPECT_TRUE(std::isinf(got));
    else EXPECT_NEAR(got, ref, 1e-9 * (1 + ref)) << "n=" << n << " m=" << m << " w=" << w;
  }
}

TEST(Dtw, LbKeoghIsALowerBoundAndEarlyAbandonIsExact) {
  std::mt19937 rng(5);
  std::normal_distribution<float> n01;
  Dtw dtw(128);
  const std::size_t n = 64;
  std::vector<float> q(n), c(n), up(n), lo(n);
  int pruned = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const std::size_t w = 1 + rng() % 10;
    for (std::size_t i = 0; i < n; ++i) {
      q[i] = std::sin(0.2f * i) + 0.3f * n01(rng);
      c[i] = std::sin(0.2f * i + 0.5f * n01(rng)) + 0.3f * n01(rng);
    }
    lb_keogh_envelope(q, w, up, lo);
    const double lb = lb_keogh(c, up, lo);
    const double d = dtw.distance(c, q, w);  // LB_Keogh(c; env(q)) bounds DTW(c, q) in the band
    EXPECT_LE(lb, d + 1e-9);
    // Early abandoning with a bound below the true distance gives +inf, above it the exact value.
    const double bound = 0.5 * d;
    const double ab = dtw.distance(c, q, w, bound);
    EXPECT_TRUE(std::isinf(ab) || std::abs(ab - d) < 1e-9);
    if (std::isinf(ab)) ++pruned;
    EXPECT_NEAR(dtw.distance(c, q, w, 2 * d + 1), d, 1e-9);
    // LB_Keogh's own abandoning returns a value above the bound whenever the full bound is.
    if (lb > 0.1) {
      EXPECT_GT(lb_keogh(c, up, lo, DtwCost::Squared, 0.5 * lb), 0.5 * lb);
    }
  }
  EXPECT_GT(pruned, 0);
}

TEST(Dtw, OpenEndFindsTheStepLength) {
  // A template of one cosine cycle (45 samples) against a signal whose first cycle lasts 58 samples.
  const std::size_t n = 45, period = 58;
  std::vector<float> templ(n), x(100);
  for (std::size_t i = 0; i < n; ++i) templ[i] = std::cos(2 * std::numbers::pi * i / n);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::cos(2 * std::numbers::pi * i / period);
  Dtw dtw(128);
  const auto m = dtw.open_end(templ, x, 25, 90, 5);
  // cost/(n+m) slightly favours running on along the flat top of the next cycle: a known bias of the
  // normalisation, a few percent of the length.
  EXPECT_NEAR(static_cast<double>(m.length), static_cast<double>(period), 0.06 * period);
  EXPECT_LT(m.normalized_cost, 0.02);
  // Lengths outside the allowed range are not returned.
  const auto m2 = dtw.open_end(templ, x, 25, 40, 0);
  EXPECT_LE(m2.length, 40u);
  EXPECT_GT(m2.normalized_cost, m.normalized_cost);
  // Degenerate input.
  EXPECT_EQ(dtw.open_end({}, x, 1, 10, 0).length, 0u);
  EXPECT_TRUE(std::isinf(dtw.distance({}, x, 3)));
  EXPECT_THROW(Dtw(0), std::invalid_argument);
}

}  // namespace
}  // namespace locus::dsp
