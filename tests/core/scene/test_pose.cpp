// scene/pose.hpp: where a time falls among samples, and the interpolation every truth track uses.
#include "locus/scene/pose.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace locus::scene {
namespace {

TimeBracket at(const std::vector<double>& times, double t) {
  return bracket(times.size(), t, [&](std::size_t i) { return times[i]; });
}

TEST(ScenePose, BracketHoldsTheEndsAndFindsTheInterval) {
  const std::vector<double> t{0.0, 1.0, 1.0, 3.0};
  EXPECT_EQ(at(t, -1.0).lo, 0u);
  EXPECT_EQ(at(t, -1.0).hi, 0u);
  EXPECT_EQ(at(t, 0.0).hi, 0u);  // at the first time: hold
  EXPECT_EQ(at(t, std::numeric_limits<double>::quiet_NaN()).hi, 0u);
  EXPECT_EQ(at(t, 3.0).lo, 3u);
  EXPECT_EQ(at(t, 3.0).hi, 3u);
  const TimeBracket mid = at(t, 0.25);
  EXPECT_EQ(mid.lo, 0u);
  EXPECT_EQ(mid.hi, 1u);
  EXPECT_DOUBLE_EQ(mid.u, 0.25);
  const TimeBracket after_repeat = at(t, 1.0);  // the last sample at or before t
  EXPECT_EQ(after_repeat.lo, 2u);
  EXPECT_EQ(after_repeat.hi, 3u);
  EXPECT_DOUBLE_EQ(after_repeat.u, 0.0);
  EXPECT_DOUBLE_EQ(at(t, 2.5).u, 0.75);
  EXPECT_EQ(at({5.0}, 7.0).hi, 0u);  // one sample: static
}

TEST(ScenePose, PositionIsLinearAttitudeTakesTheShortArc) {
  EXPECT_TRUE(interpolate_position({0, 0, 1}, {2, 4, 3}, 0.5).isApprox(Eigen::Vector3d(1, 2, 2)));
  const Eigen::Quaterniond a = Eigen::Quaterniond::Identity();
  const Eigen::Quaterniond b(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond half = interpolate_attitude(a, b, 0.5);
  EXPECT_NEAR(half.angularDistance(Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitZ()))), 0.0,
              1e-12);
  // -b is the same rotation: the result must not spin the long way round
  const Eigen::Quaterniond minus_b(-b.w(), -b.x(), -b.y(), -b.z());
  EXPECT_NEAR(interpolate_attitude(a, minus_b, 0.5).angularDistance(half), 0.0, 1e-12);
}

}  // namespace
}  // namespace locus::scene
