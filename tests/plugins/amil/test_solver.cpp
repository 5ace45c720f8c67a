// AMIL solver (plugins/amil/solver.hpp): the paper's 3-beep closed form, the direction-majority
// filter, the given-skew (calibration) drift fix, the joint position + skew least squares, its robust
// variant, weak-geometry fallbacks, the Cramér-Rao bound, and that the reported std matches the
// Monte-Carlo spread of the estimates (a solver that claims a wrong confidence fails here), and the
// network solver (all listeners at once, beep positions refined).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "amil/solver.hpp"

namespace amil = locus::plugins::amil;

namespace {

constexpr double kC = 343.2;
constexpr double kSide = 0.305;

/// The paper's triangle (Sec. III): (0,0) → (−s,0) → (0,s) → (s,0) → (0,0), `gestures` times,
/// a beep at every pause, 1.3 s apart.
std::vector<amil::Beep> triangle(int gestures = 1, double t0 = 12.0) {
  std::vector<Eigen::Vector2d> p{{0, 0}};
  for (int g = 0; g < gestures; ++g) {
    p.emplace_back(-kSide, 0.0);
    p.emplace_back(0.0, kSide);
    p.emplace_back(kSide, 0.0);
    p.emplace_back(0.0, 0.0);
  }
  std::vector<amil::Beep> beeps;
  for (std::size_t k = 0; k < p.size(); ++k) {
    amil::Beep b;
    b.position_m = p[k];
    b.player_time_s = t0 + 1.3 * static_cast<double>(k) + 0.01 * std::sin(static_cast<double>(k));
    beeps.push_back(b);
  }
  return beeps;
}

amil::ListenerArrivals arrivals(const std::vector<amil::Beep>& beeps, Eigen::Vector2d x, double skew) {
  amil::ListenerArrivals a;
  a.arrival_s = amil::exact_arrivals(beeps, x, skew, 2.345, kC);
  return a;
}

amil::SolverConfig config(amil::Method m) {
  amil::SolverConfig c;
  c.method = m;
  c.speed_of_sound_mps = kC;
  c.timing_std_s = 1e-6;
  c.position_std_m = 1e-4;
  return c;
}

double angle_error_deg(double a, double b) {
  double d = std::remainder(a - b, 2.0 * std::numbers::pi);
  return std::abs(d) * 180.0 / std::numbers::pi;
}

const std::vector<Eigen::Vector2d>& grid() {
  static const std::vector<Eigen::Vector2d> g = [] {
    std::vector<Eigen::Vector2d> v;
    for (int row = 1; row <= 4; ++row)
      for (int col = -1; col <= 1; ++col) v.emplace_back(1.22 * col, 1.22 * row);
    return v;
  }();
  return g;
}

}  // namespace

TEST(AmilSolveThree, ExactSubsetGivesTheListener) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-6.0, 6.0);
  const Eigen::Vector2d pi(0, 0), pj(-0.3, 0.02), pk(0.01, 0.3);
  int found = 0;
  for (int t = 0; t < 200; ++t) {
    const Eigen::Vector2d x(U(rng), U(rng));
    if (x.norm() < 0.5) continue;
    const double ddj = (x - pj).norm() - (x - pi).norm(), ddk = (x - pk).norm() - (x - pi).norm();
    const auto pts = amil::solve_three(pi, pj, pk, ddj, ddk);
    ASSERT_GE(pts.size(), 1u);
    ASSERT_LE(pts.size(), 2u);
    double best = 1e9;
    for (const auto& p : pts) {
      best = std::min(best, (p - x).norm());
      // every returned point satisfies both equations
      EXPECT_NEAR((p - pj).norm() - (p - pi).norm(), ddj, 1e-6);
      EXPECT_NEAR((p - pk).norm() - (p - pi).norm(), ddk, 1e-6);
    }
    EXPECT_LT(best, 1e-6 * std::max(1.0, x.norm())) << x.transpose();
    ++found;
  }
  EXPECT_GT(found, 150);
}

TEST(AmilSolveThree, TriangleInequalityBrokenHasNoSolution) {
  // |dd| larger than the beep spacing cannot be a distance difference
  EXPECT_TRUE(amil::solve_three({0, 0}, {0.3, 0}, {0, 0.3}, 0.35, 0.1).empty());
  EXPECT_TRUE(amil::solve_three({0, 0}, {0.3, 0}, {0, 0.3}, 0.1, -0.31).empty());
  // collinear beeps: the linear system is singular
  EXPECT_TRUE(amil::solve_three({0, 0}, {0.3, 0}, {0.6, 0}, 0.1, 0.2).empty());
}

TEST(AmilPaper, ExactArrivalsWithoutSkewLocateEveryGridListener) {
  const auto beeps = triangle();
  for (const auto& x : grid()) {
    const auto s = amil::solve(beeps, arrivals(beeps, x, 0.0), config(amil::Method::Paper));
    ASSERT_EQ(s.status, amil::Status::Located) << x.transpose() << " " << s.note;
    // (a listener on the gesture's symmetry axis is a double root of some subsets: sqrt(eps) precision)
    EXPECT_LT((s.position_m - x).norm(), 1e-3) << x.transpose();
    EXPECT_FALSE(s.candidates.empty());
  }
}

TEST(AmilPaper, SkewBreaksTheDistanceUnlessCalibrated) {
  const auto beeps = triangle();
  const Eigen::Vector2d x(1.22, 2.44);
  const double skew = 60e-6;  // 60 ppm: 0.3 samples per second of gesture
  auto cfg = config(amil::Method::Paper);
  const auto raw = amil::solve(beeps, arrivals(beeps, x, skew), cfg);
  const double raw_err = raw.located() ? (raw.position_m - x).norm() : 1e9;
  EXPECT_GT(raw_err, 0.3) << "an uncalibrated 60 ppm skew should visibly break the paper's distance";
  cfg.known_skew = skew;  // the paper's per-model calibration table, exact
  const auto cal = amil::solve(beeps, arrivals(beeps, x, skew), cfg);
  ASSERT_EQ(cal.status, amil::Status::Located) << cal.note;
  EXPECT_LT((cal.position_m - x).norm(), 1e-4);
  EXPECT_DOUBLE_EQ(cal.skew, skew);
  // the per-listener calibration wins over the config's
  auto arr = arrivals(beeps, x, skew);
  arr.known_skew = skew;
  cfg.known_skew = 0.0;
  EXPECT_LT((amil::solve(beeps, arr, cfg).position_m - x).norm(), 1e-4);
}

TEST(AmilJoint, RecoversPositionAndSkewExactly) {
  for (int gestures : {1, 3}) {
    auto cfg_of = [](amil::Method m) {
      auto c = config(m);
      c.timing_std_s = 1e-8;  // exact data: keep the reported distance std small (no direction-only)
      return c;
    };
    const auto beeps = triangle(gestures);
    for (double skew : {-80e-6, 0.0, 35e-6, 150e-6}) {
      for (const auto& x : grid()) {
        for (auto m : {amil::Method::Joint, amil::Method::Robust, amil::Method::PaperJointSkew}) {
          const auto s = amil::solve(beeps, arrivals(beeps, x, skew), cfg_of(m));
          ASSERT_EQ(s.status, amil::Status::Located) << amil::to_string(m) << " " << x.transpose() << " " << s.note;
          EXPECT_LT((s.position_m - x).norm(), 1e-3) << amil::to_string(m) << " " << x.transpose();
          EXPECT_NEAR(s.skew, skew, 1e-8) << amil::to_string(m);
          EXPECT_LT(angle_error_deg(s.direction_rad, std::atan2(x.y(), x.x())), 0.01);
          EXPECT_NEAR(s.distance_m, x.norm(), 1e-3);
          EXPECT_EQ(s.beeps_heard, static_cast<int>(beeps.size()));
        }
      }
    }
  }
}

TEST(AmilJoint, MissedBeepStillLocates) {
  const auto beeps = triangle(3);
  const Eigen::Vector2d x(-1.22, 3.66);
  auto arr = arrivals(beeps, x, 20e-6);
  arr.arrival_s[0] = std::nan("");  // the first beep (the usual reference) missed
  arr.arrival_s[6] = std::nan("");
  auto b2 = beeps;
  b2[9].player_time_s = std::nan("");  // the player did not find its own beep 9
  const auto s = amil::solve(b2, arr, config(amil::Method::Robust));
  ASSERT_EQ(s.status, amil::Status::Located) << s.note;
  EXPECT_EQ(s.beeps_heard, 10);
  EXPECT_LT((s.position_m - x).norm(), 1e-3);
}

TEST(AmilJoint, TooFewBeeps) {
  const auto beeps = triangle();
  const Eigen::Vector2d x(0.0, 1.22);
  auto arr = arrivals(beeps, x, 0.0);
  arr.arrival_s[1] = arr.arrival_s[2] = arr.arrival_s[3] = std::nan("");
  const auto s = amil::solve(beeps, arr, config(amil::Method::Robust));
  EXPECT_EQ(s.status, amil::Status::Failed);
  EXPECT_NE(s.note.find("2 beeps"), std::string::npos) << s.note;
  // three beeps: the skew cannot be estimated; the paper's closed form with the given skew is used
  auto arr3 = arrivals(beeps, x, 0.0);
  arr3.arrival_s[4] = arr3.arrival_s[3] = std::nan("");
  const auto s3 = amil::solve(beeps, arr3, config(amil::Method::Robust));
  EXPECT_TRUE(s3.status == amil::Status::Located || s3.status == amil::Status::Ambiguous) << s3.note;
  EXPECT_NE(s3.note.find("paper method"), std::string::npos) << s3.note;
  EXPECT_LT(angle_error_deg(s3.direction_rad, std::atan2(x.y(), x.x())), 1.0);
}

TEST(AmilRobust, OneCycleSlipIsDroppedWithThreeGestures) {
  const auto beeps = triangle(3);
  const Eigen::Vector2d x(1.22, 2.44);
  auto arr = arrivals(beeps, x, -30e-6);
  std::mt19937 rng(7);
  std::normal_distribution<double> N(0.0, 1e-6);
  for (auto& a : arr.arrival_s) a += N(rng);
  arr.arrival_s[5] += 1.0 / 20000.0;  // one carrier cycle late at 20 kHz (1.7 cm of path)
  auto cfg = config(amil::Method::Robust);
  cfg.position_std_m = 0.0;
  const auto robust = amil::solve(beeps, arr, cfg);
  ASSERT_EQ(robust.status, amil::Status::Located) << robust.note;
  EXPECT_NE(robust.note.find("beep 5 dropped"), std::string::npos) << robust.note;
  EXPECT_EQ(robust.beeps_used, 12);
  cfg.method = amil::Method::Joint;
  const auto plain = amil::solve(beeps, arr, cfg);
  ASSERT_EQ(plain.status, amil::Status::Located) << plain.note;
  const double e_robust = (robust.position_m - x).norm(), e_plain = (plain.position_m - x).norm();
  EXPECT_LT(e_robust, 0.05);
  EXPECT_LT(e_robust * 3.0, e_plain) << "robust " << e_robust << " plain " << e_plain;
}

TEST(AmilWeakGeometry, FarListenerIsDirectionOnly) {
  const auto beeps = triangle();
  const Eigen::Vector2d x(-6.0, 25.0);
  auto arr = arrivals(beeps, x, 10e-6);
  std::mt19937 rng(11);
  std::normal_distribution<double> N(0.0, 2e-6);
  for (auto& a : arr.arrival_s) a += N(rng);
  auto cfg = config(amil::Method::Robust);
  cfg.timing_std_s = 2e-6;
  cfg.position_std_m = 0.0;
  const auto s = amil::solve(beeps, arr, cfg);
  ASSERT_EQ(s.status, amil::Status::DirectionOnly) << s.note << " " << s.position_m.transpose();
  EXPECT_FALSE(std::isfinite(s.position_m.x()));
  EXPECT_FALSE(std::isfinite(s.distance_m));
  EXPECT_LT(angle_error_deg(s.direction_rad, std::atan2(x.y(), x.x())), 3.0);
  EXPECT_FALSE(s.located());
}

TEST(AmilWeakGeometry, LineGestureIsAmbiguous) {
  // beeps on a line cannot tell a listener from its mirror image across the line
  std::vector<amil::Beep> beeps;
  const std::vector<double> xs{0.0, -0.2, 0.2, 0.0, -0.2, 0.2};
  for (std::size_t k = 0; k < xs.size(); ++k) {
    amil::Beep b;
    b.position_m = {xs[k], 0.0};
    b.player_time_s = 5.0 + 1.1 * static_cast<double>(k);
    beeps.push_back(b);
  }
  const Eigen::Vector2d x(0.8, 1.5);
  const auto s = amil::solve(beeps, arrivals(beeps, x, 0.0), config(amil::Method::Joint));
  ASSERT_EQ(s.status, amil::Status::Ambiguous) << s.note;
  ASSERT_FALSE(s.alternatives.empty());
  const Eigen::Vector2d mirror(0.8, -1.5);
  const bool first_is_truth = (s.position_m - x).norm() < 1e-2 && (s.alternatives[0] - mirror).norm() < 1e-2;
  const bool first_is_mirror = (s.position_m - mirror).norm() < 1e-2 && (s.alternatives[0] - x).norm() < 1e-2;
  EXPECT_TRUE(first_is_truth || first_is_mirror) << s.position_m.transpose() << " / " << s.alternatives[0].transpose();
  EXPECT_TRUE(s.located());
}

TEST(AmilBound, MonteCarloSpreadMatchesCramerRaoAndReportedStd) {
  // With Gaussian timing noise only, the joint estimator is efficient near the listener: the spread
  // of its estimates matches the CRB, and its own reported std matches both.
  const auto beeps = triangle(3);
  std::vector<Eigen::Vector2d> pos;
  std::vector<double> times;
  for (const auto& b : beeps) {
    pos.push_back(b.position_m);
    times.push_back(b.player_time_s);
  }
  const double sigma_t = 2e-6;
  std::mt19937 rng(5);
  std::normal_distribution<double> N(0.0, sigma_t);
  auto cfg = config(amil::Method::Joint);
  cfg.timing_std_s = sigma_t;
  cfg.position_std_m = 0.0;
  for (const Eigen::Vector2d& x : {Eigen::Vector2d(0.0, 1.22), Eigen::Vector2d(-1.22, 2.44)}) {
    const auto bound = amil::cramer_rao(pos, times, x, 25e-6, sigma_t, 0.0, kC);
    ASSERT_TRUE(std::isfinite(bound.std_m));
    double sum2 = 0, reported = 0;
    const int trials = 400;
    for (int t = 0; t < trials; ++t) {
      auto arr = arrivals(beeps, x, 25e-6);
      for (auto& a : arr.arrival_s) a += N(rng);
      const auto s = amil::solve(beeps, arr, cfg);
      ASSERT_EQ(s.status, amil::Status::Located) << s.note;
      sum2 += (s.position_m - x).squaredNorm();
      reported += s.std_m;
    }
    const double mc = std::sqrt(sum2 / trials);
    EXPECT_NEAR(mc / bound.std_m, 1.0, 0.2) << "MC " << mc << " CRB " << bound.std_m << " at " << x.transpose();
    EXPECT_NEAR(reported / trials / bound.std_m, 1.0, 0.2);
    EXPECT_GT(bound.distance_std_m, 3.0 * bound.direction_std_rad * x.norm())
        << "distance (curvature) must be far weaker than direction";
  }
  // farther is worse, and timing noise scales the bound linearly
  const auto b1 = amil::cramer_rao(pos, times, {0.0, 1.22}, 0.0, sigma_t, 0.0, kC);
  const auto b4 = amil::cramer_rao(pos, times, {0.0, 4.88}, 0.0, sigma_t, 0.0, kC);
  const auto b4x2 = amil::cramer_rao(pos, times, {0.0, 4.88}, 0.0, 2.0 * sigma_t, 0.0, kC);
  EXPECT_GT(b4.distance_std_m, 4.0 * b1.distance_std_m);
  EXPECT_NEAR(b4x2.std_m / b4.std_m, 2.0, 1e-6);
}

TEST(AmilConfig, MethodNamesRoundTrip) {
  for (auto m : {amil::Method::Paper, amil::Method::PaperJointSkew, amil::Method::Joint, amil::Method::Robust,
                 amil::Method::Network})
    EXPECT_EQ(amil::parse_method(amil::to_string(m)), m);
  EXPECT_FALSE(amil::parse_method("least_squares").has_value());
  EXPECT_NEAR(amil::speed_of_sound_mps(20.0), 343.42, 1e-9);
}

TEST(AmilConfig, BadInputThrowsWithAReason) {
  const auto beeps = triangle();
  auto arr = arrivals(beeps, {0, 2}, 0.0);
  arr.arrival_s.pop_back();
  try {
    amil::solve(beeps, arr, config(amil::Method::Robust));
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("one per beep"), std::string::npos) << e.what();
  }
  const auto ok = arrivals(beeps, {0, 2}, 0.0);
  auto cfg = config(amil::Method::Robust);
  cfg.speed_of_sound_mps = -1;
  EXPECT_THROW(amil::solve(beeps, ok, cfg), std::invalid_argument);
  cfg = config(amil::Method::Paper);
  cfg.direction_window_rad = 0.0;
  EXPECT_THROW(amil::solve(beeps, ok, cfg), std::invalid_argument);
  cfg = config(amil::Method::Joint);
  cfg.max_range_m = cfg.min_range_m;
  EXPECT_THROW(amil::solve(beeps, ok, cfg), std::invalid_argument);
  // garbage measurements are not exceptions: NaN positions make beeps unusable
  auto nb = beeps;
  for (auto& b : nb) b.position_m = {std::nan(""), 0.0};
  EXPECT_EQ(amil::solve(nb, ok, config(amil::Method::Robust)).status, amil::Status::Failed);
}

TEST(AmilNetwork, SharedBeepPositionErrorsAreEstimatedFromAllListeners) {
  // One IMU track for everyone: the same beep-position errors (5 mm per axis) in every listener's
  // data. Per listener they look like timing noise; across 12 listeners in different directions they
  // are observable, so the network solver's distances are better and it recovers the errors.
  const auto truth_beeps = triangle(3);
  std::mt19937 rng(21);
  std::normal_distribution<double> N(0.0, 1.0);
  double err_robust = 0, err_network = 0, corr_err_before = 0, corr_err_after = 0;
  int n = 0;
  for (int trial = 0; trial < 8; ++trial) {
    auto beeps = truth_beeps;
    for (std::size_t k = 1; k < beeps.size(); ++k) beeps[k].position_m += 0.005 * Eigen::Vector2d(N(rng), N(rng));
    std::vector<amil::ListenerArrivals> arr;
    for (const auto& x : grid()) {
      auto a = arrivals(truth_beeps, x, 40e-6 * N(rng));  // sound from the TRUE positions
      for (auto& t : a.arrival_s) t += 1e-6 * N(rng);
      arr.push_back(a);
    }
    auto cfg = config(amil::Method::Robust);
    cfg.position_std_m = 0.005;
    cfg.timing_std_s = 1.5e-6;
    const auto net = amil::solve_network(beeps, arr, cfg);
    ASSERT_EQ(net.listeners.size(), grid().size());
    EXPECT_GE(net.listeners_in_network, 11) << net.note;
    int in_network = 0;
    for (std::size_t l = 0; l < grid().size(); ++l) {
      const auto single = amil::solve(beeps, arr[l], cfg);
      const auto& s = net.listeners[l];
      ASSERT_TRUE(std::isfinite(s.direction_rad)) << s.note;
      in_network += s.note.find("network") != std::string::npos ? 1 : 0;
      if (!single.located() || !s.located()) continue;
      err_robust += std::abs(single.distance_m - grid()[l].norm());
      err_network += std::abs(s.distance_m - grid()[l].norm());
      ++n;
    }
    EXPECT_EQ(in_network, net.listeners_in_network);
    for (std::size_t k = 0; k < beeps.size(); ++k) {
      corr_err_before += (beeps[k].position_m - truth_beeps[k].position_m).squaredNorm();
      corr_err_after += (beeps[k].position_m + net.beep_correction_m[k] - truth_beeps[k].position_m).squaredNorm();
    }
  }
  ASSERT_GT(n, 60);
  EXPECT_LT(err_network, 0.7 * err_robust) << "network " << err_network / n << " m, robust " << err_robust / n << " m";
  EXPECT_LT(corr_err_after, 0.7 * corr_err_before) << "beep positions: before " << std::sqrt(corr_err_before)
                                                    << ", after " << std::sqrt(corr_err_after);
}

TEST(AmilNetwork, TooFewListenersKeepTheirOwnSolutions) {
  const auto beeps = triangle();
  std::vector<amil::ListenerArrivals> arr{arrivals(beeps, {0.0, 1.22}, 0.0), arrivals(beeps, {1.22, 2.44}, 0.0)};
  auto cfg = config(amil::Method::Network);
  cfg.timing_std_s = 1e-8;
  const auto net = amil::solve_network(beeps, arr, cfg);
  ASSERT_EQ(net.listeners.size(), 2u);
  EXPECT_NE(net.note.find("fewer than 3"), std::string::npos);
  EXPECT_LT((net.listeners[1].position_m - Eigen::Vector2d(1.22, 2.44)).norm(), 1e-3);
  // Method::Network through solve() is the robust per-listener solution
  EXPECT_LT((amil::solve(beeps, arr[0], cfg).position_m - Eigen::Vector2d(0.0, 1.22)).norm(), 1e-3);
}

namespace {

/// The beeps of equilateral() with the tracker's error model: the origin exact, every movement adding
/// `step_std_m` per axis to every later pause (a random walk: beep k's std is step_std_m·√k).
std::vector<amil::Beep> equilateral_tracked(double step_std_m = 0.001);

/// One gesture of the ~30 cm equilateral triangle the foreign scenes draw, a beep per pause.
std::vector<amil::Beep> equilateral(double side = 0.30, double position_std_m = 0.002) {
  const double h = side * std::sqrt(3.0) / 2.0;
  const std::vector<Eigen::Vector2d> p{{0, 0}, {-side / 2, 0}, {0, h}, {side / 2, 0}, {0, 0}};
  std::vector<amil::Beep> beeps;
  for (std::size_t k = 0; k < p.size(); ++k) {
    amil::Beep b;
    b.position_m = p[k];
    b.player_time_s = 3.0 + 1.1 * static_cast<double>(k);
    b.position_std_m = position_std_m;
    beeps.push_back(b);
  }
  return beeps;
}

std::vector<amil::Beep> equilateral_tracked(double step_std_m) {
  std::vector<amil::Beep> beeps = equilateral();
  for (std::size_t k = 0; k < beeps.size(); ++k) beeps[k].position_std_m = step_std_m * std::sqrt(static_cast<double>(k));
  return beeps;
}

struct CycleTrial {
  int slipped = 0;  // arrivals whose detector picked another cycle than the truth's
  amil::ListenerArrivals arr;
  std::vector<double> truth;
};

/// Arrivals of a listener at x as the chirp detector reports them: the envelope maximum is off by the
/// channel's skew (`channel` periods, the same for every beep) plus a per-beep jitter (multipath that
/// moves with the player), and the phase zero nearest it is reported, so a beep whose envelope error
/// passes half a period is slipped by a whole one. Beep positions carry 2 mm errors, timing 0.05 samples.
/// `tracked`: the beep errors accumulate as equilateral_tracked() says (1 mm per movement) instead.
CycleTrial cycle_trial(std::mt19937& rng, const Eigen::Vector2d& x, double jitter_periods, bool tracked = false) {
  constexpr double kFs = 44100.0, kPeriod = 2.205 / kFs;
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<amil::Beep> moved = equilateral();
  if (tracked) {
    Eigen::Vector2d walk = Eigen::Vector2d::Zero();
    for (std::size_t k = 1; k < moved.size(); ++k) {
      walk += 0.001 * Eigen::Vector2d(n01(rng), n01(rng));
      moved[k].position_m += walk;
    }
  } else {
    for (auto& b : moved) b.position_m += 0.002 * Eigen::Vector2d(n01(rng), n01(rng));
  }
  CycleTrial t;
  t.truth = amil::exact_arrivals(moved, x, 20e-6, 1.234, kC);
  const double channel = std::uniform_real_distribution<double>(-0.5, 0.5)(rng);
  t.arr.carrier_period_s = kPeriod;
  t.arr.arrival_s.resize(t.truth.size());
  t.arr.cycle_offset_s.resize(t.truth.size());
  for (std::size_t k = 0; k < t.truth.size(); ++k) {
    const double env_err = (channel + jitter_periods * n01(rng)) * kPeriod;
    const double picked = kPeriod * std::round(env_err / kPeriod);  // the phase zero nearest the envelope
    t.slipped += picked != 0.0;
    t.arr.arrival_s[k] = t.truth[k] + picked + 0.05 / kFs * n01(rng);
    t.arr.cycle_offset_s[k] = picked - env_err;
  }
  return t;
}

/// Every arrival within a quarter period of the truth, up to a common whole-period shift (the clock
/// offset absorbs it).
bool cycles_right(const CycleTrial& t) {
  const double p = t.arr.carrier_period_s;
  const double shift = p * std::round((t.arr.arrival_s[0] - t.truth[0]) / p);
  for (std::size_t k = 0; k < t.truth.size(); ++k)
    if (std::fabs(t.arr.arrival_s[k] - t.truth[k] - shift) > 0.25 * p) return false;
  return true;
}

}  // namespace

TEST(AmilCycles, SlipsFromAJitteryEnvelopeAreUndone) {
  std::mt19937 rng(20261125);
  amil::SolverConfig cfg = config(amil::Method::Robust);
  cfg.timing_std_s = 0.05 / 44100.0;
  cfg.position_std_m = 0.002;
  int with_slips = 0, right_before = 0, right_after = 0, wrong_unflagged = 0;
  for (int i = 0; i < 200; ++i) {
    const double dir = std::uniform_real_distribution<double>(0.2, std::numbers::pi - 0.2)(rng);
    const double r = std::uniform_real_distribution<double>(0.8, 3.0)(rng);
    CycleTrial t = cycle_trial(rng, Eigen::Vector2d(r * std::cos(dir), r * std::sin(dir)), 0.3);
    right_before += cycles_right(t);
    with_slips += t.slipped > 0;
    amil::resolve_cycles(equilateral(), t.arr, cfg);
    const bool right = cycles_right(t);
    right_after += right;
    // a wrong choice must be marked: a doubtful arrival's std is raised to half a period
    bool flagged = false;
    for (double sd : t.arr.arrival_std_s) flagged = flagged || sd > 0.25 * t.arr.carrier_period_s;
    wrong_unflagged += !right && !flagged;
  }
  RecordProperty("right_before", right_before);
  RecordProperty("right_after", right_after);
  EXPECT_GT(with_slips, 60) << "the trial must slip often enough to test anything";
  EXPECT_GE(right_after, 2 * right_before) << "of 200 (before: " << right_before << ")";
  EXPECT_LE(wrong_unflagged, 10) << "of 200 wrong without a doubtful arrival (right: " << right_after << ")";
}

TEST(AmilCycles, RunnerUpMixtureKeepsDistancesThatBothHypothesesAgreeOn) {
  // The same jittery-envelope listeners within 2.5 m, solved two ways: doubtful cycles as a half-period
  // Gaussian (resolve_cycles without an alternative), and as the best/runner-up mixture
  // (cycle_mixture). Beep errors accumulate along the gesture as the tracker's do (1 mm per movement).
  // The mixture must keep more distances, and cover the true error at least as often as the Gaussian
  // does (measured: 166 kept, 88 % within 2 sd; mixture 179, 92 %; the misses of both are wrong cycle
  // choices that no runner-up came close to).
  std::mt19937 rng(20261128);
  amil::SolverConfig cfg = config(amil::Method::Robust);
  cfg.timing_std_s = 0.05 / 44100.0;
  const std::vector<amil::Beep> beeps = equilateral_tracked();
  int doubtful = 0, located_gauss = 0, located_mix = 0, within_2sd = 0, within_2sd_gauss = 0;
  for (int i = 0; i < 200; ++i) {
    const double dir = std::uniform_real_distribution<double>(0.2, std::numbers::pi - 0.2)(rng);
    const double r = std::uniform_real_distribution<double>(0.8, 2.5)(rng);
    const Eigen::Vector2d x(r * std::cos(dir), r * std::sin(dir));
    const CycleTrial t = cycle_trial(rng, x, 0.3, true);
    amil::ListenerArrivals gauss = t.arr, mix = t.arr;
    amil::resolve_cycles(beeps, gauss, cfg);
    amil::CycleAlternative alt;
    amil::resolve_cycles(beeps, mix, cfg, {}, &alt);
    doubtful += alt.valid;
    std::vector<amil::Solution> a{amil::solve(beeps, gauss, cfg)};
    std::vector<amil::Solution> b{amil::solve(beeps, mix, cfg)};
    amil::cycle_mixture(beeps, mix, alt, cfg, b[0]);
    amil::calibrate_session(a, cfg);
    amil::calibrate_session(b, cfg);
    if (a[0].located()) {
      ++located_gauss;
      within_2sd_gauss += std::fabs(a[0].distance_m - r) <= 2.0 * a[0].distance_std_m;
    }
    if (b[0].located()) {
      ++located_mix;
      within_2sd += std::fabs(b[0].distance_m - r) <= 2.0 * b[0].distance_std_m;
    }
  }
  RecordProperty("doubtful", doubtful);
  RecordProperty("located_gauss", located_gauss);
  RecordProperty("located_mixture", located_mix);
  EXPECT_GT(doubtful, 20) << "the trial must leave doubtful cycles often enough to test anything";
  EXPECT_GT(located_mix, located_gauss) << "of 200";
  std::printf("[ measured ] doubtful %d of 200; distance kept: half-cycle Gaussian %d (%d within 2 sd), mixture %d (%d within 2 sd)\n",
              doubtful, located_gauss, within_2sd_gauss, located_mix, within_2sd);
  EXPECT_GE(within_2sd * located_gauss, within_2sd_gauss * located_mix);
  EXPECT_GE(within_2sd, 0.88 * located_mix) << within_2sd << " of " << located_mix;
}

TEST(AmilBound, ReportedStdFollowsTheTrackersAccumulatedErrors) {
  // Beep position errors that accumulate along the gesture (a random walk of 1 mm per movement, as
  // the tracker's: tracker.hpp "Uncertainty") mostly move the beeps together, which the wavefront
  // curvature barely sees. The reported distance std (the sandwich covariance) must match the Monte
  // Carlo spread; treating the errors as independent overstated it about twice.
  const auto beeps = equilateral_tracked(0.001);
  auto cfg = config(amil::Method::Joint);
  cfg.timing_std_s = 0.05 / 44100.0;
  std::mt19937 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (const Eigen::Vector2d& x : {Eigen::Vector2d(0.0, 1.22), Eigen::Vector2d(-1.22, 1.22)}) {
    double sum2 = 0, reported2 = 0;
    int n = 0;
    for (int t = 0; t < 300; ++t) {
      std::vector<amil::Beep> truth = beeps;
      Eigen::Vector2d walk = Eigen::Vector2d::Zero();
      for (std::size_t k = 1; k < truth.size(); ++k) {
        walk += 0.001 * Eigen::Vector2d(n01(rng), n01(rng));
        truth[k].position_m += walk;
      }
      auto arr = arrivals(truth, x, 25e-6);
      for (auto& a : arr.arrival_s) a += cfg.timing_std_s * n01(rng);
      const auto s = amil::solve(beeps, arr, cfg);
      if (!std::isfinite(s.fit_position_m.x())) continue;
      const double d = s.fit_position_m.norm() - x.norm();
      const Eigen::Vector2d u = s.fit_position_m.normalized();
      sum2 += d * d;
      reported2 += u.dot(s.fit_covariance_m2 * u);
      ++n;
    }
    ASSERT_GT(n, 280);
    const double mc = std::sqrt(sum2 / n), reported = std::sqrt(reported2 / n);
    std::printf("[ measured ] accumulated beep errors, listener at (%.2f, %.2f): distance MC %.3f m, reported %.3f m\n",
                x.x(), x.y(), mc, reported);
    EXPECT_NEAR(reported / mc, 1.0, 0.3) << "MC " << mc << " reported " << reported;
  }
}

TEST(AmilCycles, ThreeGesturesAreResolvedToo) {
  // 13 beeps (three triangles): 5^12 combinations is beyond the exhaustive search; the coordinate
  // descent from the rounded real-valued minimiser must still undo most slips (it used to leave all
  // of them; measured 83 -> 12, and 83 -> 48 descending from no shift).
  constexpr double kFs = 44100.0, kPeriod = 2.205 / kFs;
  std::vector<amil::Beep> beeps;
  for (int g = 0; g < 3; ++g) {
    auto one = equilateral();
    for (std::size_t k = (g == 0 ? 0 : 1); k < one.size(); ++k) {
      one[k].player_time_s = 3.0 + 1.1 * static_cast<double>(beeps.size());
      beeps.push_back(one[k]);
    }
  }
  ASSERT_EQ(beeps.size(), 13u);
  std::mt19937 rng(20261128);
  std::normal_distribution<double> n01(0.0, 1.0);
  amil::SolverConfig cfg = config(amil::Method::Robust);
  cfg.timing_std_s = 0.05 / kFs;
  int slipped_before = 0, slipped_after = 0;
  for (int i = 0; i < 40; ++i) {
    const double dir = std::uniform_real_distribution<double>(0.3, std::numbers::pi - 0.3)(rng);
    const Eigen::Vector2d x(1.5 * std::cos(dir), 1.5 * std::sin(dir));
    const std::vector<double> truth = amil::exact_arrivals(beeps, x, 20e-6, 1.0, kC);
    amil::ListenerArrivals arr;
    arr.carrier_period_s = kPeriod;
    for (std::size_t k = 0; k < truth.size(); ++k) {
      const double env_err = 0.3 * n01(rng) * kPeriod;
      const double picked = kPeriod * std::round(env_err / kPeriod);
      arr.arrival_s.push_back(truth[k] + picked + 0.05 / kFs * n01(rng));
      arr.cycle_offset_s.push_back(picked - env_err);
    }
    auto wrong = [&] {
      const double shift = kPeriod * std::round((arr.arrival_s[0] - truth[0]) / kPeriod);
      int w = 0;
      for (std::size_t k = 0; k < truth.size(); ++k) w += std::fabs(arr.arrival_s[k] - truth[k] - shift) > 0.25 * kPeriod;
      return w;
    };
    slipped_before += wrong();
    amil::resolve_cycles(beeps, arr, cfg);
    slipped_after += wrong();
  }
  std::printf("[ measured ] three gestures, 40 listeners: %d slipped arrivals before, %d after\n", slipped_before, slipped_after);
  EXPECT_GT(slipped_before, 20);
  EXPECT_LE(2 * slipped_after, slipped_before);
}

TEST(AmilCycles, NotCarrierTimedIsLeftAlone) {
  amil::SolverConfig cfg = config(amil::Method::Robust);
  std::vector<amil::Beep> beeps = equilateral();
  amil::ListenerArrivals a;
  a.arrival_s = amil::exact_arrivals(beeps, Eigen::Vector2d(0.5, 1.5), 0.0, 1.0, kC);
  a.arrival_s[2] += 2.205 / 44100.0;
  const std::vector<double> before = a.arrival_s;
  EXPECT_EQ(amil::resolve_cycles(beeps, a, cfg), 0);  // no carrier period
  EXPECT_EQ(a.arrival_s, before);
  a.carrier_period_s = 2.205 / 44100.0;
  a.cycle_offset_s.assign(3, 0.0);  // wrong length: not applicable
  EXPECT_EQ(amil::resolve_cycles(beeps, a, cfg), 0);
  EXPECT_EQ(a.arrival_s, before);
}
