// Frames: names, placement from truth (start / origin / north / body), the heading axes, and the
// rigid best fit used for relative frames.
#include <gtest/gtest.h>

#include "eval_test_support.hpp"
#include "locus/eval/frames.hpp"

namespace locus::eval {
namespace {

using test::deg;
using test::yaw;

TEST(EvalFrames, ParsesEveryFrameName) {
  EXPECT_EQ(parse_frame("world").kind, FrameKind::World);
  EXPECT_EQ(parse_frame("body").kind, FrameKind::Body);
  EXPECT_EQ(parse_frame("relative").kind, FrameKind::Relative);
  EXPECT_EQ(parse_frame("relative_trace").kind, FrameKind::RelativeTrace);
  const FrameSpec p = parse_frame("player_start");
  EXPECT_EQ(p.kind, FrameKind::Start);
  EXPECT_FALSE(p.t0_local_s.has_value());
  const FrameSpec t = parse_frame("player_start@12.5");
  EXPECT_EQ(t.kind, FrameKind::Start);
  ASSERT_TRUE(t.t0_local_s.has_value());
  EXPECT_DOUBLE_EQ(*t.t0_local_s, 12.5);
  EXPECT_EQ(parse_frame("W1_origin").kind, FrameKind::Origin);
  EXPECT_EQ(parse_frame("O_north@-1e-3").kind, FrameKind::North);
  EXPECT_TRUE(parse_frame("A_start").needs_reference());
  EXPECT_FALSE(parse_frame("world").needs_reference());
  EXPECT_TRUE(parse_frame("relative").aligned());
}

TEST(EvalFrames, RejectsUnknownFramesWithWhatWasExpected) {
  try {
    parse_frame("map");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frame 'map' is unknown: expected world, body, relative"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_frame("_start"), std::invalid_argument);        // no device name
  EXPECT_THROW(parse_frame("world@3"), std::invalid_argument);       // world takes no time
  try {
    parse_frame("player_start@soon");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'@soon' is not a time"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_frame("player_start@1.5x"), std::invalid_argument);
}

TEST(EvalFrames, HeadingAxesFollowTheHorizontalBodyYAxis) {
  // Identity attitude: body axes are world axes.
  EXPECT_TRUE(heading_axes(Eigen::Quaterniond::Identity()).isApprox(Eigen::Matrix3d::Identity(), 1e-12));
  // Yaw by 30°: the frame's axes are the body's x and y.
  const Eigen::Matrix3d a = heading_axes(yaw(deg(30)));
  EXPECT_TRUE(a.col(1).isApprox(Vec3(-std::sin(deg(30)), std::cos(deg(30)), 0), 1e-12));
  EXPECT_TRUE(a.col(0).isApprox(Vec3(std::cos(deg(30)), std::sin(deg(30)), 0), 1e-12));
  // Tilted 40° about body x (screen pitched up): the heading is unchanged.
  const Eigen::Quaterniond tilted = yaw(deg(30)) * Eigen::Quaterniond(Eigen::AngleAxisd(deg(40), Vec3::UnitX()));
  EXPECT_TRUE(heading_axes(tilted).isApprox(a, 1e-12));
  // Upright in portrait (body y vertical, screen towards the user): forward is body −z.
  const Eigen::Quaterniond upright = yaw(deg(30)) * Eigen::Quaterniond(Eigen::AngleAxisd(deg(90), Vec3::UnitX()));
  EXPECT_TRUE(heading_axes(upright).isApprox(a, 1e-9));
}

TEST(EvalFrames, StartFrameUsesTheReferencePoseAtTheGivenLocalTime) {
  TruthData truth;
  truth.objects = {test::device("P"), test::device("L1")};
  // The player sits at (1,1) facing world +y, turns to yaw 90° at t = 10 s and moves to (2,1).
  truth.tracks["P"].add(TruthPose{0.0, Vec3(1, 1, 0), yaw(0)});
  truth.tracks["P"].add(TruthPose{5.0, Vec3(1, 1, 0), yaw(0)});
  truth.tracks["P"].add(TruthPose{10.0, Vec3(2, 1, 0), yaw(deg(90))});
  truth.clocks["P"] = ClockModel{2.0, 0.0};  // local = true + 2

  const Vec3 listener(0, 2, 0);
  // No @T: the first truth sample (position (1,1), yaw 0).
  FramePlacement f = place_frame(parse_frame("player_start"), "P", 7.0, truth);
  EXPECT_TRUE(f.to_frame(listener).isApprox(Vec3(-1, 1, 0), 1e-12));
  // @12 on P's clock = true 10 s: position (2,1), yaw 90°: d = (-2, 1) → frame (1, 2).
  f = place_frame(parse_frame("player_start@12"), "P", 0.0, truth);
  EXPECT_TRUE(f.to_frame(listener).isApprox(Vec3(1, 2, 0), 1e-12));
  // origin: same position, world axes.
  f = place_frame(parse_frame("P_origin@12"), "P", 0.0, truth);
  EXPECT_TRUE(f.to_frame(listener).isApprox(Vec3(-2, 1, 0), 1e-12));
  // body at the estimate's own true time 10 s: same as the start frame at 10 s here.
  f = place_frame(parse_frame("body"), "P", 10.0, truth);
  EXPECT_TRUE(f.to_frame(listener).isApprox(Vec3(1, 2, 0), 1e-12));
  // world: identity.
  f = place_frame(parse_frame("world"), "", 3.0, truth);
  EXPECT_TRUE(f.to_frame(listener).isApprox(listener, 1e-12));
}

TEST(EvalFrames, NorthFrameUsesTheHorizontalMagneticField) {
  TruthData truth;
  truth.objects = {test::device("O")};
  test::place(truth, "O", Vec3(1, 0, 0));
  // Field pointing along world +x (with a large downward part): north = +x, east = −y.
  truth.magnetic_field_world_ut = Vec3(20, 0, -40);
  const FramePlacement f = place_frame(parse_frame("O_north"), "O", 0.0, truth);
  EXPECT_TRUE(f.to_frame(Vec3(1, -3, 0)).isApprox(Vec3(3, 0, 0), 1e-12));   // 3 m east
  EXPECT_TRUE(f.to_frame(Vec3(3, 0, 0)).isApprox(Vec3(0, 2, 0), 1e-12));    // 2 m north
  truth.magnetic_field_world_ut.reset();
  EXPECT_THROW(place_frame(parse_frame("O_north"), "O", 0.0, truth), std::runtime_error);
  EXPECT_THROW(place_frame(parse_frame("X_start"), "X", 0.0, truth), std::runtime_error);  // no truth for X
}

TEST(EvalFrames, RigidFitRecoversARotationAndTranslation2D) {
  const std::vector<Vec3> truth_pts = {{0, 0, 0}, {3, 0, 0}, {0, 4, 0}, {2, 5, 0}};
  const Eigen::Matrix3d r = Eigen::AngleAxisd(deg(-70), Vec3::UnitZ()).toRotationMatrix();
  const Vec3 t(10, -4, 0);
  std::vector<Vec3> est;
  for (const Vec3& p : truth_pts) est.push_back(r * p + t);  // estimate frame = truth moved
  const RigidFit fit = fit_rigid(est, truth_pts, 2);
  for (std::size_t i = 0; i < est.size(); ++i) EXPECT_LT((fit.apply(est[i]) - truth_pts[i]).norm(), 1e-9);
  EXPECT_NEAR(fit.rotation.determinant(), 1.0, 1e-12);
}

TEST(EvalFrames, RigidFitRecoversA3DRotationAndNeverReflects) {
  const std::vector<Vec3> truth_pts = {{0, 0, 0}, {1, 0, 0.3}, {0, 2, -0.5}, {1.5, 1, 1}};
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized())).toRotationMatrix();
  std::vector<Vec3> est;
  for (const Vec3& p : truth_pts) est.push_back(r * p + Vec3(1, 2, 3));
  const RigidFit fit = fit_rigid(est, truth_pts, 3);
  for (std::size_t i = 0; i < est.size(); ++i) EXPECT_LT((fit.apply(est[i]) - truth_pts[i]).norm(), 1e-9);
  // A mirrored formation cannot be aligned exactly by a proper rotation: residuals stay > 0.
  std::vector<Vec3> mirrored;
  for (const Vec3& p : truth_pts) mirrored.push_back(Vec3(-p.x(), p.y(), p.z()));
  const RigidFit m = fit_rigid(mirrored, truth_pts, 3);
  EXPECT_NEAR(m.rotation.determinant(), 1.0, 1e-9);
  double residual = 0;
  for (std::size_t i = 0; i < mirrored.size(); ++i) residual += (m.apply(mirrored[i]) - truth_pts[i]).norm();
  EXPECT_GT(residual, 0.1);
}

}  // namespace
}  // namespace locus::eval
