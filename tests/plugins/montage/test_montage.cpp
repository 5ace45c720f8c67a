// Montage maths (plugins/montage): messages, ETOA known answers, rounds, the walking direction from a
// synthetic acceleration, and the formation recovered from exact and noisy ranges + movement vectors
// of four synthetic walkers (up to the rigid transform the `relative_trace` frame leaves free), with
// pairs missing.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>

#include "montage/messages.hpp"
#include "montage/movement.hpp"
#include "montage/solver.hpp"

namespace {

namespace mt = locus::plugins::montage;
constexpr double kPi = std::numbers::pi;

TEST(MontageMessages, RoundTrip) {
  mt::RoundMessage r{"U0", 3.25, 0.018, {{"U1", 0.0123}, {"U2", -0.004}}};
  const auto r2 = mt::decode_round(mt::encode(r));
  ASSERT_TRUE(r2);
  EXPECT_EQ(r2->device, "U0");
  EXPECT_DOUBLE_EQ(r2->tau_own_s, 3.25);
  EXPECT_DOUBLE_EQ(r2->self_m, 0.018);
  ASSERT_EQ(r2->arrivals.size(), 2u);
  EXPECT_EQ(r2->arrivals[1].first, "U2");
  EXPECT_DOUBLE_EQ(r2->arrivals[1].second, -0.004);
  mt::StepMessage s{"U1", 4.5, 6.1, 0.7, 1.2, -0.3, true};
  const auto s2 = mt::decode_step(mt::encode(s));
  ASSERT_TRUE(s2);
  EXPECT_DOUBLE_EQ(s2->t_s, 6.1);
  EXPECT_DOUBLE_EQ(s2->offset_rad, -0.3);
  EXPECT_TRUE(s2->offset_valid);
  const auto p2 = mt::decode_progress(mt::encode(mt::ProgressMessage{"U2", 9.5}));
  ASSERT_TRUE(p2);
  EXPECT_DOUBLE_EQ(p2->tau_s, 9.5);
  EXPECT_EQ(mt::topic_round("montage", "U0"), "montage/round/U0");
}

TEST(MontageMessages, MalformedAreRefusedWithAReason) {
  for (const char* bad : {"", "U0", "U0 1.0 0.01", "U0 1.0 0.01 2 U1 0.1", "U0 1.0 0.01 1 U1 0.1 extra",
                          "U0 nan 0.01 0", "U0 1.0 -0.5 0", "U0 1.0 20 0", "U0 1.0 0.01 -1", "U0 1.0 0.01 65",
                          "U0 1.0 0.01 1 U0 0.1", "U0 1e7 0.01 0", "U0 1.0 0.01 1 U1 inf"}) {
    std::string why;
    EXPECT_FALSE(mt::decode_round(bad, &why)) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
  for (const char* bad : {"", "U1 1 2 0.7 0 0", "U1 1 2 0.7 0 0 2", "U1 1 2 -0.7 0 0 1", "U1 1 2 9 0 0 1",
                          "U1 1 2 0.7 nan 0 1", "U1 1 2 0.7 0 0 1 x", "U1 x 2 0.7 0 0 1"}) {
    std::string why;
    EXPECT_FALSE(mt::decode_step(bad, &why)) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
  for (const char* bad : {"", "U2", "U2 x", "U2 1 2", "U2 -inf"}) EXPECT_FALSE(mt::decode_progress(bad)) << bad;
}

TEST(MontageEtoa, KnownAnswerWithoutClockSync) {
  // True geometry: distance 7.3 m, own speaker-to-mic 0.02 / 0.01 m, emissions 31 ms apart, clocks
  // offset by 1.7 s (cancels: only differences on one clock enter).
  const double c = 343.0, d = 7.3, si = 0.02, sj = 0.01;
  const double Ti = 10.000, Tj = 10.031, off_i = 0.0, off_j = 1.7;
  const double tii = Ti + si / c + off_i, tji = Tj + d / c + off_i;  // on i's clock
  const double tjj = Tj + sj / c + off_j, tij = Ti + d / c + off_j;  // on j's clock
  EXPECT_NEAR(mt::etoa_distance_m(tji - tii, tij - tjj, si, sj, c), d, 1e-9);
}

TEST(MontageRounds, GroupedByTimeSinceTheStartSignal) {
  mt::RoundBook book(0.3);
  book.add({"U0", 0.02, 0.0, {{"U1", 0.01}}});
  book.add({"U1", 0.05, 0.0, {{"U0", 0.005}}});
  book.add({"U0", 1.03, 0.0, {}});
  book.add({"U1", 0.9, 0.0, {}});   // U1's next round (its own emission ~1 s later)
  book.add({"U0", 0.04, 0.0, {}});  // a second report of U0 near round 0: not merged into it
  ASSERT_EQ(book.rounds().size(), 3u);
  EXPECT_EQ(book.rounds()[0].reports.size(), 2u);
  EXPECT_NEAR(book.rounds()[0].tau_s, 0.035, 1e-12);
  EXPECT_EQ(book.rounds()[2].reports.size(), 2u);
  // Ranges: both directions needed; a one-sided pair is not ranged.
  const auto r = mt::round_ranges(book.rounds()[0], {"U0", "U1", "U2"}, 343.0, 40.0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_NEAR(r[0].distance_m, 0.5 * 343.0 * 0.015, 1e-9);
  EXPECT_TRUE(mt::round_ranges(book.rounds()[2], {"U0", "U1"}, 343.0, 40.0).empty());
}

TEST(MontageMovement, WalkingDirectionFromTheHorizontalAcceleration) {
  // Forward surge in phase with the rising edge of the vertical bounce, a lateral sway at half the
  // step rate, walking towards 120° while the phone points to 30°: offset +90°.
  mt::WalkDirection w;
  const double dir = 120.0 * kPi / 180.0, f = 2.0;
  const Eigen::Vector2d fwd(std::cos(dir), std::sin(dir)), lat(-fwd.y(), fwd.x());
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.0, 0.05);
  for (int i = 0; i < 1000; ++i) {
    const double t = i * 0.01, ph = 2 * kPi * f * t;
    const double av = 1.5 * std::sin(ph), af = 1.0 * std::cos(ph), al = 0.4 * std::sin(ph / 2);
    const Eigen::Vector2d h = af * fwd + al * lat;
    w.add_sample(t, Eigen::Vector3d(h.x() + n(rng), h.y() + n(rng), 9.81 + av + n(rng)));
  }
  for (int k = 1; k < 19; ++k) w.add_step((k - 1) / f, k / f, 30.0 * kPi / 180.0);
  const auto off = w.offset_rad();
  ASSERT_TRUE(off);
  EXPECT_NEAR(*off, 90.0 * kPi / 180.0, 10.0 * kPi / 180.0);
}

/// Four walkers on straight legs with turns; steps every 0.5 s; phones' headings offset from the
/// walking direction by known constants; rounds every second with every pair (or some missing).
struct Scenario {
  std::vector<std::vector<Eigen::Vector2d>> pos;  ///< [round][user] truth
  mt::Formation f;
  explicit Scenario(double range_noise, bool drop_pairs, unsigned seed = 3)
      : f({"A", "B", "C", "D"}, mt::FormationConfig{}) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    const std::array<Eigen::Vector2d, 4> start{Eigen::Vector2d(0, 0), {4, 1}, {1, 6}, {-3, 3}};
    const std::array<double, 4> head0{0.3, 2.0, -1.0, 4.0}, turn{0.08, -0.06, 0.1, 0.05}, offs{0.5, -1.2, 2.0, 0.0};
    const std::array<double, 4> stride{0.65, 0.7, 0.6, 0.75};
    std::array<Eigen::Vector2d, 4> p = start;
    std::array<double, 4> h = head0;
    const int rounds = 16;
    for (int k = 0; k < rounds; ++k) {
      const double tau = k * 1.0;
      pos.push_back({p.begin(), p.end()});
      std::vector<mt::RangeObs> ranges;
      for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = i + 1; j < 4; ++j) {
          if (drop_pairs && (i + j + static_cast<std::size_t>(k)) % 3 == 0) continue;  // a third of the pairs missing
          ranges.push_back(mt::RangeObs{i, j, (p[j] - p[i]).norm() + range_noise * n(rng)});
        }
      f.add_round(tau, ranges);
      // Two steps to the next round (the first after the round at tau + 0.5).
      for (int s = 1; s <= 2; ++s)
        for (std::size_t u = 0; u < 4; ++u) {
          h[u] += turn[u];
          p[u] += stride[u] * Eigen::Vector2d(std::cos(h[u]), std::sin(h[u]));
          const double noisy_stride = stride[u] * 0.9 * (1.0 + 0.02 * range_noise / 0.05 * n(rng));
          f.add_step(u, tau + 0.5 * s, noisy_stride, h[u] - offs[u] + 0.02 * n(rng), offs[u] + 0.1 * n(rng));
        }
    }
  }
};

/// Error after the best rigid alignment of every solved position to truth (what relative_trace scores).
double aligned_max_error(const std::vector<Eigen::Vector2d>& est, const std::vector<Eigen::Vector2d>& tru) {
  Eigen::Vector2d pm = Eigen::Vector2d::Zero(), qm = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < est.size(); ++i) {
    pm += est[i];
    qm += tru[i];
  }
  pm /= est.size();
  qm /= tru.size();
  Eigen::Matrix2d H = Eigen::Matrix2d::Zero();
  for (std::size_t i = 0; i < est.size(); ++i) H += (est[i] - pm) * (tru[i] - qm).transpose();
  Eigen::JacobiSVD<Eigen::Matrix2d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix2d D = Eigen::Matrix2d::Identity();
  D(1, 1) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1 : 1;
  const Eigen::Matrix2d R = svd.matrixV() * D * svd.matrixU().transpose();
  double mx = 0.0;
  for (std::size_t i = 0; i < est.size(); ++i) mx = std::max(mx, (R * (est[i] - pm) + qm - tru[i]).norm());
  return mx;
}

/// max_error_m: over every causal fix after the first `settle` rounds with all four placed (the first
/// placement uses uncalibrated strides and offsets; the adjustment corrects them as rounds come).
void expect_formation(Scenario& s, double max_error_m, std::size_t min_localized_rounds, std::size_t settle = 3) {
  std::vector<Eigen::Vector2d> est, tru;
  std::size_t full = 0;
  for (std::size_t k = 0; k < s.f.rounds(); ++k) {
    const auto fixes = s.f.solve(k);
    std::size_t n = 0;
    for (std::size_t u = 0; u < 4; ++u)
      if (fixes[u].localized) {
        ++n;
        est.push_back(fixes[u].position_m);
        tru.push_back(s.pos[k][u]);
        EXPECT_GT(fixes[u].std_m, 0.0);
      }
    full += n == 4;
    if (n == 4 && full <= settle) {  // not yet settled: not scored
      est.resize(est.size() - 4);
      tru.resize(tru.size() - 4);
    }
  }
  EXPECT_GE(full, min_localized_rounds);
  ASSERT_GE(est.size(), 8u);
  EXPECT_LT(aligned_max_error(est, tru), max_error_m);
  // The stride scale was calibrated by ranging (strides were reported 10 % short).
  for (std::size_t u = 0; u < 4; ++u) EXPECT_NEAR(s.f.stride_scale(u), 1.0 / 0.9, 0.08) << u;
}

TEST(MontageFormation, ExactRangesRecoverTheFormation) {
  Scenario s(0.0, false);
  expect_formation(s, 0.8, 10);  // measured 0.68 m (guard; see docs/montage.md "Limits")
}

TEST(MontageFormation, NoisyRangesAndMissingPairs) {
  Scenario s(0.05, true);
  expect_formation(s, 1.1, 8);  // measured 0.89 m
  EXPECT_TRUE(s.f.origin_user().has_value());
}

TEST(MontageFormation, NoMovementNoOrientation) {
  // Users standing still: every orientation fits (the paper's "infinite solutions"): nobody is placed.
  mt::Formation f({"A", "B", "C"});
  for (int k = 0; k < 5; ++k) f.add_round(k, {{0, 1, 3.0}, {0, 2, 4.0}, {1, 2, 5.0}});
  for (std::size_t k = 0; k < 5; ++k)
    for (const auto& fix : f.solve(k)) EXPECT_FALSE(fix.localized);
}

}  // namespace
