// locus/angles.hpp: wrap_pi, the one angle wrap of core, plugins, simulator and evaluator.
#include "locus/angles.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace locus {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(Angles, WrapPiKeepsAnglesInRangeUnchangedBitForBit) {
  for (double a : {0.0, 0.1, -0.1, 1.0, -3.0, 3.1, kPi, std::nextafter(-kPi, 0.0)}) EXPECT_EQ(wrap_pi(a), a) << a;
}

TEST(Angles, WrapPiMapsIntoTheHalfOpenRange) {
  EXPECT_EQ(wrap_pi(-kPi), kPi);  // (-pi, pi]: -pi is pi
  EXPECT_EQ(wrap_pi(3.0 * kPi), kPi);
  EXPECT_NEAR(wrap_pi(2.0 * kPi + 0.25), 0.25, 1e-15);
  EXPECT_NEAR(wrap_pi(-2.0 * kPi - 0.25), -0.25, 1e-15);
  EXPECT_NEAR(wrap_pi(kPi + 0.5), -kPi + 0.5, 1e-15);
  EXPECT_NEAR(wrap_pi(101.0 * kPi + 0.125), -kPi + 0.125, 1e-12);
  for (double a = -50.0; a < 50.0; a += 0.37) {
    const double w = wrap_pi(a);
    EXPECT_GT(w, -kPi) << a;
    EXPECT_LE(w, kPi) << a;
    EXPECT_NEAR(std::remainder(a - w, 2.0 * kPi), 0.0, 1e-12) << a;
  }
}

TEST(Angles, WrapPiOfTwoHeadingsIsTheirExactDifference) {
  // Differences of headings in (-pi, pi] (the simulator's turns): no rounding beyond the subtraction.
  const double a = 3.0, b = -3.0;
  EXPECT_EQ(wrap_pi(a - b), (a - b) - 2.0 * kPi);
  EXPECT_EQ(wrap_pi(b - a), (b - a) + 2.0 * kPi);
}

TEST(Angles, WrapPiOfNonFiniteIsNaN) {
  EXPECT_TRUE(std::isnan(wrap_pi(std::numeric_limits<double>::quiet_NaN())));
  EXPECT_TRUE(std::isnan(wrap_pi(std::numeric_limits<double>::infinity())));
}

}  // namespace
}  // namespace locus
