// Montage maths (plugins/montage): messages, ETOA known answers, rounds, the walking direction from a
// synthetic acceleration, and the formation recovered from exact and noisy ranges + movement vectors
// of four synthetic walkers (up to the rigid transform the `relative_trace` frame leaves free), with
// pairs missing; the reporter's wait for every user's round reports, whatever order messages come in.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <cstdio>
#include <random>

#include "locus/events.hpp"
#include "locus/params.hpp"
#include "montage/messages.hpp"
#include "montage/montage.hpp"
#include "montage/movement.hpp"
#include "montage/solver.hpp"
#include "support/test_host.hpp"

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

// Two devices with their own clocks (local = true·(1 + skew) + offset), one radio start signal received
// with different latencies, emissions every second at jittered times, walking apart at 1.2 m/s: the
// round reports each device would send (tau since its start signal; dt = arrival − own emission).
struct PairWorld {
  double c = 343.0, skew_i = 35e-6, skew_j = -28e-6, off_i = 0.4, off_j = 1.9, lat_i = 0.0008, lat_j = 0.0003;
  double self_i = 0.018, self_j = 0.012, t0 = 1.0;
  double dist(double t) const { return 3.0 + 1.2 * (t - t0); }
  double li(double t) const { return t * (1.0 + skew_i) + off_i; }
  double lj(double t) const { return t * (1.0 + skew_j) + off_j; }
  /// Round k: both reports; `drop_j_hears_i` leaves j's arrival of i out, `late_i_s` delays i's arrival of j.
  mt::Round round(int k, bool drop_j_hears_i = false, double late_i_s = 0.0) const {
    const double ei = t0 + 0.1 + k + 0.013 * std::sin(k), ej = t0 + 0.1 + k + 0.03 + 0.011 * std::cos(3.0 * k);
    const double own_i = li(ei + self_i / c), own_j = lj(ej + self_j / c);
    mt::RoundMessage ri{"U0", own_i - li(t0 + lat_i), self_i, {{"U1", li(ej + dist(ej) / c) + late_i_s - own_i}}};
    mt::RoundMessage rj{"U1", own_j - lj(t0 + lat_j), self_j, {}};
    if (!drop_j_hears_i) rj.arrivals.push_back({"U0", lj(ei + dist(ei) / c) - own_j});
    mt::Round r;
    r.tau_s = 0.5 * (ri.tau_own_s + rj.tau_own_s);
    r.reports.emplace("U0", ri);
    r.reports.emplace("U1", rj);
    return r;
  }
};

/// Rounds k0..k1−1 of w through round_ranges and learn_clocks; returns how many two-way ranges were
/// kept from round `count_from` on. `late_round` (if >= 0) has U0's arrival 80 ms late.
int learn_rounds(const PairWorld& w, mt::PairClocks& clocks, int k0, int k1, int late_round = -1, int count_from = 0) {
  const std::vector<std::string> users{"U0", "U1"};
  int kept = 0;
  for (int k = k0; k < k1; ++k) {
    const mt::Round r = w.round(k, false, k == late_round ? 0.08 : 0.0);
    std::vector<mt::RangeObs> two = mt::round_ranges(r, users, w.c, 40.0);
    mt::learn_clocks(r, users, w.c, two, clocks);
    if (k >= count_from) kept += static_cast<int>(two.size());
  }
  return kept;
}

TEST(MontagePairClocks, OneWayRangeThroughTheClockLine) {
  const PairWorld w;
  const std::vector<std::string> users{"U0", "U1"};
  mt::PairClocks clocks;
  for (int k = 0; k < 4; ++k) {
    const mt::Round r = w.round(k);
    std::vector<mt::RangeObs> two = mt::round_ranges(r, users, w.c, 40.0);
    ASSERT_EQ(two.size(), 1u);
    mt::learn_clocks(r, users, w.c, two, clocks);
    EXPECT_EQ(two.size(), 1u) << "a good two-way round is kept, round " << k;
    EXPECT_TRUE(mt::one_way_ranges(r, users, w.c, 40.0, clocks).empty()) << "two-way rounds are not ranged one way";
  }
  EXPECT_EQ(clocks.count(0, 1), 4u);
  // Round 5: U1 did not hear U0. ETOA cannot range it; the clock line can (the skews differ by 63 ppm:
  // a line, not a constant, or the range would be off by c·63e-6·Δtau).
  const mt::Round r = w.round(5, true);
  EXPECT_TRUE(mt::round_ranges(r, users, w.c, 40.0).empty());
  const auto one = mt::one_way_ranges(r, users, w.c, 40.0, clocks);
  ASSERT_EQ(one.size(), 1u);
  const double ej = w.t0 + 0.1 + 5 + 0.03 + 0.011 * std::cos(15.0);
  EXPECT_NEAR(one[0].distance_m, w.dist(ej), 0.02);
  EXPECT_GT(one[0].extra_std_m, 0.0);
  EXPECT_LT(one[0].extra_std_m, 0.3);
}

TEST(MontagePairClocks, AWrongArrivalIsDroppedAndNotRangedOneWay) {
  const PairWorld w;
  const std::vector<std::string> users{"U0", "U1"};
  mt::PairClocks clocks;
  EXPECT_EQ(learn_rounds(w, clocks, 0, 3), 3);
  // U0 takes U1's code 80 ms late (montage-103 had such a run): the two-way range is 13.7 m long and
  // its clock difference off the line: dropped, and not learnt.
  const mt::Round bad = w.round(3, false, 0.08);
  std::vector<mt::RangeObs> two = mt::round_ranges(bad, users, w.c, 40.0);
  ASSERT_EQ(two.size(), 1u);
  mt::learn_clocks(bad, users, w.c, two, clocks);
  EXPECT_TRUE(two.empty());
  EXPECT_EQ(clocks.count(0, 1), 4u);  // kept for the line's consensus, which outvotes it
  // The same late arrival one way: 27 m off the pair's last range 1 s before, beyond walking speed.
  EXPECT_TRUE(mt::one_way_ranges(w.round(4, true, 0.08), users, w.c, 40.0, clocks).empty());
  EXPECT_EQ(mt::one_way_ranges(w.round(4, true), users, w.c, 40.0, clocks).size(), 1u);
  // A wrong round among the first two: the later rounds outvote it instead of being dropped for good.
  mt::PairClocks early;
  EXPECT_EQ(learn_rounds(w, early, 0, 7, 1, 3), 4) << "rounds 3-6 agree with round 0 and each other";
  const auto line = early.predict(0, 1, w.round(7).tau_s);
  ASSERT_TRUE(line);
  EXPECT_LT(line->second, 1e-4);
  // A long session keeps only the latest rounds (the line's cost grows with their cube).
  mt::PairClocks bounded(mt::PairClockOptions{.max_rounds = 5});
  for (int k = 0; k < 12; ++k) bounded.add(0, 1, k, 1e-3 + 2e-5 * k);
  EXPECT_EQ(bounded.count(0, 1), 5u);
  EXPECT_NEAR(bounded.predict(0, 1, 12.0)->first, 1e-3 + 2e-5 * 12, 1e-5);
  // Without enough two-way rounds of the pair there is no line to range through.
  mt::PairClocks fresh;
  EXPECT_TRUE(mt::one_way_ranges(w.round(4, true), users, w.c, 40.0, fresh).empty());
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
/// What the walkers report: strides `stride_factor` x the true ones (x (1 + 2 % noise) with range
/// noise), headings with `heading_noise_rad` per step, the offset estimate with a constant per-user
/// bias (+-`offset_bias_rad`, alternating sign: the acceleration estimate's error) and
/// `offset_noise_rad` per step. Draws in a fixed order (one statement each).
struct Walk {
  double range_noise_m = 0.0;
  bool drop_pairs = false;
  double stride_factor = 0.9;
  double heading_noise_rad = 0.02;
  double offset_noise_rad = 0.1;
  double offset_bias_rad = 0.0;
  int rounds = 16;
};

mt::FormationConfig shared_rotation(bool on) {
  mt::FormationConfig c;
  c.shared_frame_rotation = on;
  return c;
}

struct Scenario {
  std::vector<std::vector<Eigen::Vector2d>> pos;  ///< [round][user] truth
  mt::Formation f;
  /// `shared`: FormationConfig::shared_frame_rotation (the frame's rotation from every prior).
  explicit Scenario(const Walk& w, unsigned seed = 3, bool shared = true) : Scenario(w, seed, shared_rotation(shared)) {}
  Scenario(const Walk& w, unsigned seed, const mt::FormationConfig& cfg) : f({"A", "B", "C", "D"}, cfg) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    const std::array<Eigen::Vector2d, 4> start{Eigen::Vector2d(0, 0), {4, 1}, {1, 6}, {-3, 3}};
    const std::array<double, 4> head0{0.3, 2.0, -1.0, 4.0}, turn{0.08, -0.06, 0.1, 0.05}, offs{0.5, -1.2, 2.0, 0.0};
    const std::array<double, 4> stride{0.65, 0.7, 0.6, 0.75};
    std::array<Eigen::Vector2d, 4> p = start;
    std::array<double, 4> h = head0;
    for (int k = 0; k < w.rounds; ++k) {
      const double tau = k * 1.0;
      pos.push_back({p.begin(), p.end()});
      std::vector<mt::RangeObs> ranges;
      for (std::size_t i = 0; i < 4; ++i)
        for (std::size_t j = i + 1; j < 4; ++j) {
          if (w.drop_pairs && (i + j + static_cast<std::size_t>(k)) % 3 == 0) continue;  // a third of the pairs missing
          const double noise = w.range_noise_m * n(rng);
          ranges.push_back(mt::RangeObs{i, j, (p[j] - p[i]).norm() + noise});
        }
      f.add_round(tau, ranges);
      // Two steps to the next round (the first after the round at tau + 0.5).
      for (int s = 1; s <= 2; ++s)
        for (std::size_t u = 0; u < 4; ++u) {
          h[u] += turn[u];
          p[u] += stride[u] * Eigen::Vector2d(std::cos(h[u]), std::sin(h[u]));
          const double stride_noise = 0.02 * w.range_noise_m / 0.05 * n(rng);
          const double heading_noise = w.heading_noise_rad * n(rng);
          const double offset_noise = w.offset_noise_rad * n(rng);
          const double bias = (u % 2 == 0 ? -1.0 : 1.0) * w.offset_bias_rad;
          f.add_step(u, tau + 0.5 * s, stride[u] * w.stride_factor * (1.0 + stride_noise), h[u] - offs[u] + heading_noise,
                     offs[u] + bias + offset_noise);
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

/// The largest error over every causal fix after the first `settle` rounds with all four placed (the
/// first placement uses uncalibrated strides and offsets; the adjustment corrects them as rounds
/// come), after one rigid alignment of all of them (what relative_trace is scored with). Checks that
/// `min_localized_rounds` rounds had every user and every std is positive.
double formation_error(Scenario& s, std::size_t min_localized_rounds, std::size_t settle = 3) {
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
    if (full <= settle) {  // not yet settled (also a round with some users placed before): not scored
      est.resize(est.size() - n);
      tru.resize(tru.size() - n);
    }
  }
  EXPECT_GE(full, min_localized_rounds);
  if (est.size() < 8) {
    ADD_FAILURE() << "fewer than two scored rounds";
    return 1e9;
  }
  return aligned_max_error(est, tru);
}

/// The stride scale was calibrated by ranging (strides reported `factor` x the true ones).
void expect_scales(const Scenario& s, double factor, double tolerance) {
  for (std::size_t u = 0; u < 4; ++u) EXPECT_NEAR(s.f.stride_scale(u), 1.0 / factor, tolerance) << u;
}

TEST(MontageFormation, ExactInputsGiveTheExactFormation) {
  // Exact ranges, strides, headings and offset estimates: the model holds exactly, the adjustment
  // must reach the truth (a wrong Jacobian or gauge shows here first).
  Walk w;
  w.stride_factor = 1.0;
  w.heading_noise_rad = 0.0;
  w.offset_noise_rad = 0.0;
  Scenario s(w);
  EXPECT_LT(formation_error(s, 10), 0.01);
  expect_scales(s, 1.0, 0.005);
}

TEST(MontageFormation, ExactRangesRecoverTheFormation) {
  // 10 %-short strides, 0.02 rad heading noise per step, 0.1 rad noise on every offset report; ten
  // draws of the noise (one draw is one number, not a measurement of the method).
  double sum = 0.0, worst = 0.0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    Scenario s(Walk{}, seed);
    const double e = formation_error(s, 10);
    sum += e;
    worst = std::max(worst, e);
    expect_scales(s, 0.9, 0.02);
  }
  std::printf("exact ranges, short strides: aligned max error mean %.3f m, worst %.3f m\n", sum / 10.0, worst);
  EXPECT_LT(sum / 10.0, 0.64);  // measured 0.583 m (shared_frame_rotation off: 0.659 m)
  EXPECT_LT(worst, 0.9);        // measured 0.808 m (off: 1.065 m)
}

TEST(MontageFormation, OffsetPriorBiasesDoNotRotateTheOthers) {
  // The walkers' offset estimates are off by +-0.3 rad (alternating per user, constant): the frame's
  // rotation from the world is one unknown shared by every prior, so one device's bias must not pull
  // the other users' headings (before: the origin's δ was held at its own biased prior and every
  // other δ was pulled by that error).
  Walk w;
  w.offset_noise_rad = 0.0;
  w.heading_noise_rad = 0.0;
  w.offset_bias_rad = 0.3;
  double sum = 0.0, sum_origin = 0.0;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    Scenario s(w, seed);
    sum += formation_error(s, 10);
    expect_scales(s, 0.9, 0.02);
    Scenario o(w, seed, false);  // the default: ψ from the origin's prior alone
    sum_origin += formation_error(o, 10);
  }
  std::printf("biased offset priors: aligned max error mean %.3f m (origin's prior alone: %.3f m)\n", sum / 5.0,
              sum_origin / 5.0);
  EXPECT_LT(sum / 5.0, 0.45);  // measured 0.330 m
  // The default mode measured 0.876 m here (printed, not asserted: a fix of the default must not fail
  // this test); the shared gauge must not be worse than it.
  EXPECT_LE(sum, sum_origin);
}

TEST(MontageFormation, NoisyRangesAndMissingPairs) {
  Walk w;
  w.range_noise_m = 0.05;
  w.drop_pairs = true;
  double sum = 0.0, worst = 0.0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    Scenario s(w, seed);
    const double e = formation_error(s, 8);
    sum += e;
    worst = std::max(worst, e);
    expect_scales(s, 0.9, 0.04);
    EXPECT_TRUE(s.f.origin_user().has_value());
  }
  std::printf("noisy ranges, missing pairs: aligned max error mean %.3f m, worst %.3f m\n", sum / 10.0, worst);
  EXPECT_LT(sum / 10.0, 0.6);  // measured 0.526 m (shared_frame_rotation off: 0.543 m)
  EXPECT_LT(worst, 0.95);       // measured 0.851 m (off: 0.841 m)
}

TEST(MontageFormation, NoMovementNoOrientation) {
  // Users standing still: every orientation fits (the paper's "infinite solutions"): nobody is placed.
  mt::Formation f({"A", "B", "C"});
  for (int k = 0; k < 5; ++k) f.add_round(k, {{0, 1, 3.0}, {0, 2, 4.0}, {1, 2, 5.0}});
  for (std::size_t k = 0; k < 5; ++k)
    for (const auto& fix : f.solve(k)) EXPECT_FALSE(fix.localized);
}

}  // namespace

// The std is widened by the window's reduced chi-square when the data fit worse than their stds say
// (ranges 4x noisier than range_std_m), and left alone when they fit as said.
TEST(MontageFormation, StdWidensWhenTheDataFitWorseThanTheirStds) {
  const auto last_stds = [](const Walk& w, bool inflate) {
    mt::FormationConfig c;
    c.chi2_std_inflation = inflate;
    Scenario s(w, 4, c);
    std::vector<mt::UserFix> fixes;
    for (std::size_t k = 0; k < s.f.rounds(); ++k) fixes = s.f.solve(k);
    std::vector<double> out;
    for (const auto& f : fixes) {
      EXPECT_TRUE(f.localized);
      out.push_back(f.std_m);
    }
    return out;
  };
  Walk clean;
  clean.range_noise_m = 0.05;  // configured range_std_m 0.15
  Walk noisy = clean;
  noisy.range_noise_m = 0.6;
  const auto clean_on = last_stds(clean, true), clean_off = last_stds(clean, false);
  const auto noisy_on = last_stds(noisy, true), noisy_off = last_stds(noisy, false);
  for (std::size_t u = 0; u < 4; ++u) {
    EXPECT_DOUBLE_EQ(clean_on[u], clean_off[u]) << u;
    EXPECT_GT(noisy_on[u], 1.5 * noisy_off[u]) << u;
  }
}

namespace {

class NullPublisher final : public locus::Publisher {
 public:
  void publish(const locus::Event&) override {}
};

}  // namespace

// A user's steps run ahead of its round reports (a round closes after the next arrival, the next own
// emission or 5 s of IMU time; steps go out as they come). The reporter must not take a step for
// progress: it solved rounds before that user's reports came and then dropped them as late, so the
// result depended on thread timing (montage-103: about 1 replay in 10 lost a walker).
TEST(MontageReporter, StepsAheadOfRoundReportsDoNotMakeThemLate) {
  locus::test::TestHost host;
  locus::HostContext ctx = host.context("montage", "B");
  std::unique_ptr<locus::Localizer> loc(mt::descriptor()->create_localizer());
  locus::Params p = locus::Params::defaults(mt::schema());
  p.set("users", std::string("A,B"));
  loc->configure(p, ctx);
  NullPublisher out;
  const auto round = [&](const std::string& dev, double tau, const std::string& other, double dt) {
    mt::RoundMessage m;
    m.device = dev;
    m.tau_own_s = tau;
    m.arrivals.emplace_back(other, dt);
    host.link.publish(mt::topic_round("montage", dev), mt::encode(m));
  };
  // B's reports of rounds 1..6 and its progress to 10 s; A's steps up to 7 s, but no round yet.
  for (int k = 1; k <= 6; ++k) round("B", k + 0.01, "A", 0.02);
  mt::ProgressMessage pb;
  pb.device = "B";
  pb.tau_s = 10.0;
  host.link.publish(mt::topic_progress("montage", "B"), mt::encode(pb));
  for (int k = 1; k <= 14; ++k) {
    mt::StepMessage st;
    st.device = "A";
    st.tau_s = 0.5 * k;
    st.t_s = 0.5 * k;
    st.stride_m = 0.7;
    host.link.publish(mt::topic_step("montage", "A"), mt::encode(st));
  }
  locus::Attitude a;  // any event of the reporter's device lets it solve what is ready
  a.device.assign("B");
  a.t_s = 1.0;
  loc->on_event(locus::Event{a}, out);
  // A's reports come now: none may be late.
  for (int k = 1; k <= 6; ++k) round("A", k, "B", 0.03);
  loc->on_event(locus::Event{a}, out);
  loc->finish(out);
  EXPECT_TRUE(host.log.contains(" 0 late reports")) << "the reporter dropped A's round reports";
  EXPECT_FALSE(host.log.contains(" 6 late reports"));
}
