// TUM maths (plugins/tum): exact synthetic exchanges (four two-mic devices, known poses and clocks)
// through the single-exchange solver, the clock pairing, the window solve and the particle filter.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "locus/dsp/signals.hpp"
#include "tum/messages.hpp"
#include "tum/network.hpp"
#include "tum/solver.hpp"
#include "tum/sync.hpp"
#include "tum/tracker.hpp"
#include "support/tum_synthetic.hpp"

namespace tum = locus::plugins::tum;
using Eigen::Quaterniond;
using Eigen::Vector3d;

using namespace locus::test::tum_synthetic;

TEST(TumSolver, PairRootsContainTheTruth) {
  const auto poses = layout(1.2);
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  const auto res = tum::solve_exchange(exchange(poses, 1.0, 1.02), cfg);
  ASSERT_TRUE(res.devices[1].ok) << res.devices[1].why;
  const Vector3d truth = in_body(poses[0], poses[1]);
  double best = 1e9;
  for (const auto& r : res.devices[1].roots) best = std::min(best, (r.x - truth).norm());
  std::string roots;
  for (const auto& r : res.devices[1].roots) roots += "[" + std::to_string(r.x[0]) + " " + std::to_string(r.x[1]) + " " + std::to_string(r.x[2]) + " c=" + std::to_string(r.cost) + "] ";
  EXPECT_LT(best, 1e-4) << "no root at the true position " << truth.transpose() << ": " << roots;
  EXPECT_GE(res.devices[1].roots.size(), 1u);
}

TEST(TumSolver, MonitorFromTruePairIsExact) {
  const auto poses = layout(1.2);
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  std::vector<std::optional<Vector3d>> priors{std::nullopt, in_body(poses[0], poses[1]), in_body(poses[0], poses[2]),
                                              in_body(poses[0], poses[3])};
  const auto res = tum::solve_exchange(exchange(poses, 1.0, 1.02), cfg, priors);
  ASSERT_TRUE(res.devices[1].ok) << res.devices[1].why;
  EXPECT_LT((res.devices[1].origin - in_body(poses[0], poses[1])).norm(), 0.02) << "the prior picks the true root";
  for (std::size_t i = 2; i < 4; ++i) {
    ASSERT_TRUE(res.devices[i].ok) << poses[i].id << ": " << res.devices[i].why;
    // One exchange leaves a monitor's height weakly determined; its distance from device 1 is not.
    EXPECT_NEAR(res.devices[i].origin.norm(), in_body(poses[0], poses[i]).norm(), 0.05) << poses[i].id;
  }
}

TEST(TumSolver, OwnEmissionGivesSpeedOfSound) {
  const auto poses = layout();
  const auto ex = exchange(poses, 1.0, 1.02);
  const auto c = tum::speed_of_sound_sample(ex[0], ex[0].t1_s);
  ASSERT_TRUE(c.has_value());
  EXPECT_NEAR(*c, kC, 1e-6);
}

TEST(TumSolver, ClockPairingFindsTheOffset) {
  const auto poses = layout();
  std::vector<tum::Stamp> ref, dev;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lat(-0.03, 0.04), jitter(0.005, 0.05);
  for (int k = 0; k < 10; ++k) {
    const double t1 = 1.0 + k / 3.0 + jitter(rng);  // speaker latency
    const auto ex = exchange(poses, t1, t1 + lat(rng));
    ref.push_back(tum::stamp_of(ex[0]));
    if (k >= 2) dev.push_back(tum::stamp_of(ex[2]));  // the monitor missed the first two
  }
  const auto p = tum::align_clocks(ref, dev, 5.0 / kC + 0.005, 2.0 * 5.0 / kC + 0.002, 3);
  ASSERT_TRUE(p.offset_s.has_value());
  const auto off = p.offset_s;
  EXPECT_NEAR(*off, poses[2].clock_offset_s - poses[0].clock_offset_s, 0.02);
  EXPECT_EQ(p.pairs, 8);
  EXPECT_EQ(tum::match_stamp(ref[2], dev, *off, 5.0 / kC + 0.005, 2.0 * 5.0 / kC + 0.002), 0);
  EXPECT_EQ(tum::match_stamp(ref[0], dev, *off, 5.0 / kC + 0.005, 2.0 * 5.0 / kC + 0.002), -1);
}

// Live (`./run hil tum`), device 1's tone comes on an exact period and device 2's a pseudo-random
// 0.11-0.16 s later (tone2_delay_s). A monitor whose exchanges lag device 1's by one pairs as many of
// them under a one-period shift (its exchange k with device 1's k+1): the tone-1 times agree under
// every shift, and the interval bound (twice the spread / c: 31 ms at 5 m) passes most differences of
// two rounds' delays. Measured live: both monitors paired 333 ms off, 1 run in 3. What tells the rounds
// apart is that under the right pairing the interval difference is the geometry's, the same in every
// exchange.
static void live_rounds(const std::vector<Pose>& poses, int first, int count, double jitter_s, double noise_s, unsigned seed,
                        std::vector<tum::Stamp>& ref, std::vector<tum::Stamp>& dev) {
  std::mt19937_64 rng(seed);
  for (int k = first; k < first + count; ++k) {
    const double t1 = 1.0 + k / 3.0;
    const auto ex = exchange(poses, t1, t1 + tum::tone2_delay_s(0.11, jitter_s, k), noise_s, &rng);
    ref.push_back(tum::stamp_of(ex[0]));
    if (k < first + count - 1) dev.push_back(tum::stamp_of(ex[2]));  // its last exchange not in yet
  }
}

TEST(TumSolver, ClockPairingTellsLiveRoundsApart) {
  const auto poses = layout();
  const double tol = 0.006, itol = 2.0 * 5.0 / kC + 0.002;  // the shipped pairing_tolerance_s, max_spread_m
  for (unsigned seed = 1; seed <= 20; ++seed) {
    // Rounds 22-27: every neighbouring pair of tone-2 delays differs by less than 13 ms.
    std::vector<tum::Stamp> ref, dev;
    live_rounds(poses, 22, 6, 0.05, 20e-6, seed, ref, dev);
    const double right = dev[0].t1 - ref[0].t1, wrong = dev[0].t1 - ref[1].t1;
    int by_bound_right = 0, by_bound_wrong = 0;  // the tone-1 times and the interval bound alone
    for (const auto& r : ref) {
      by_bound_right += tum::match_stamp(r, dev, right, tol, itol) >= 0;
      by_bound_wrong += tum::match_stamp(r, dev, wrong, tol, itol) >= 0;
    }
    ASSERT_EQ(by_bound_right, 5);
    ASSERT_EQ(by_bound_wrong, 5) << "the one-period shift ties under the bound alone";
    const auto p = tum::align_clocks(ref, dev, tol, itol, 3, 2);
    ASSERT_TRUE(p.offset_s.has_value()) << "seed " << seed << ": " << p.pairs << " vs " << p.runner_up_pairs;
    EXPECT_NEAR(*p.offset_s, right, 2e-4) << "seed " << seed;
    EXPECT_EQ(p.pairs, 5);
    EXPECT_LE(p.runner_up_pairs, 3) << "seed " << seed;
    EXPECT_EQ(tum::count_pairs(ref, dev, right, tol, itol), 5);
    EXPECT_LE(tum::count_pairs(ref, dev, wrong, tol, itol), 3) << "seed " << seed << ": a re-check sees the shift";
  }
}

TEST(TumSolver, ClockPairingRefusesIndistinctRounds) {
  // A constant interval (no jitter): every round looks alike and the lagging monitor pairs as many
  // under the one-period shift, so there is no offset to decide on.
  const auto poses = layout();
  const double tol = 0.006, itol = 2.0 * 5.0 / kC + 0.002;
  std::vector<tum::Stamp> ref, dev;
  live_rounds(poses, 0, 6, 0.0, 0.0, 1, ref, dev);
  const auto p = tum::align_clocks(ref, dev, tol, itol, 3, 2);
  EXPECT_FALSE(p.offset_s.has_value());
  EXPECT_EQ(p.pairs, 5);
  EXPECT_EQ(p.runner_up_pairs, 5);
  const double right = dev[0].t1 - ref[0].t1, wrong = dev[0].t1 - ref[1].t1;
  EXPECT_LT(std::min(std::abs(p.runner_up_offset_s - right), std::abs(p.runner_up_offset_s - wrong)), 1e-6);
}

// 15 still exchanges (timing noise 2 us, random latency of device 2's tone) through the window solve.
static tum::NetworkResult still_window(const std::vector<Pose>& poses, const tum::NetworkConfig& ncfg, unsigned seed) {
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  tum::NetworkSolver net(cfg, ncfg);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lat(-0.03, 0.04);
  tum::NetworkResult res;
  for (int k = 0; k < 15; ++k) {
    const double t1 = 1.0 + k / 3.0;
    res = net.add(exchange(poses, t1, t1 + lat(rng), 2e-6, &rng));
    if (!res.ok) return res;
  }
  return res;
}

// Four devices on one table (tum-102's office). Devices at different heights that never move leave
// the formation's elevation weakly observable (docs/tum.md, "Limits"); the scenario test measures it.
TEST(TumNetwork, StaticDevicesOnATable) {
  const auto poses = layout(0.8, true);
  tum::NetworkConfig ncfg;
  ncfg.still_yaw_prior_rad = 0.01;  // exact attitudes here: with nothing moving, headings are not observable
  const tum::NetworkResult res = still_window(poses, ncfg, 5);
  ASSERT_TRUE(res.ok);
  ASSERT_EQ(res.devices.size(), 4u);
  // Flat two-mic devices leave the formation's height weakly observable (docs/tum.md); what the paper
  // scores (Eq. 23), every pairwise distance, is well determined.
  std::map<std::string, Vector3d> est;
  for (const auto& d : res.devices) est[d.id] = d.origin;
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t j = i + 1; j < 4; ++j) {
      const double truth = (poses[i].p - poses[j].p).norm();
      const double e = (est[poses[i].id] - est[poses[j].id]).norm();
      EXPECT_NEAR(e, truth, 0.03) << poses[i].id << "-" << poses[j].id;
    }
}

// Flat two-mic devices at different heights, nothing moving: the data add almost nothing to the height
// prior, and the placement must say so (docs/tum.md, "Uncertainty"); its covariance's horizontal part,
// which then carries the sigma points' second-order term, must cover the horizontal error.
TEST(TumNetwork, UnobservedHeightIsSaidAndCovered) {
  const auto poses = layout(1.2, false);
  const tum::NetworkConfig ncfg;
  const tum::NetworkResult res = still_window(poses, ncfg, 7);
  ASSERT_TRUE(res.ok);
  ASSERT_EQ(res.devices.size(), 4u);
  const Eigen::Matrix3d h = Eigen::Matrix3d::Identity() - res.up * res.up.transpose();
  for (const auto& d : res.devices) {
    if (d.id == "N1") continue;
    const auto pose = std::find_if(poses.begin(), poses.end(), [&](const Pose& p) { return p.id == d.id; });
    ASSERT_NE(pose, poses.end());
    EXPECT_FALSE(d.height_observed) << d.id;
    EXPECT_GT(d.vertical_std_m, ncfg.unobserved_height_ratio * ncfg.height_prior_m) << d.id;
    const Vector3d err = h * (d.origin - in_body(poses[0], *pose));
    const double std_h = std::sqrt((h * d.cov * h).trace());
    EXPECT_LT(err.norm(), 3.0 * std_h) << d.id << ": horizontal error " << err.norm() << " m, std " << std_h << " m";
    EXPECT_GE(d.basins, 1) << d.id;
    EXPECT_GT(d.basin_weight, 0.0) << d.id;
    EXPECT_LE(d.basin_weight, 1.0) << d.id;
  }
}

// Motion within an exchange (docs/tum.md): working device 2 turns on a circle while the tones are out,
// 0-40 ms apart (overlapped) or 130 ms apart (live). Exact arrivals at their retarded times, with the
// chirps' range-Doppler coupling a phase-timed detector adds. The window solve with exchange_motion
// places M and the monitors to a millimetre (overlapped); without it, M's 1-4 cm of motion between
// its two arrivals and the coupling (up to ~1 sample) are errors of several sigma in every exchange.
static double moving_rms_error(bool exchange_motion, double gap_s) {
  auto poses = layout(0.8, true);  // one table: the height prior is right (heights are not the point here)
  const Vector3d centre = poses[1].p;
  const double radius = 0.4, speed = 0.3, rate = speed / radius;
  Mover m;
  m.pose = [=](double t) {
    const double a = rate * t;
    return std::make_pair(Vector3d(centre + radius * Vector3d(std::cos(a), std::sin(a), 0.0)), flat(a + 0.5 * M_PI));
  };
  m.rate = [=](double) { return Vector3d(0.0, 0.0, rate); };
  const std::map<std::string, Mover> movers{{"M", m}};
  locus::SignalSpec up;
  up.type = "lfm", up.f0_hz = 2000, up.f1_hz = 8000, up.duration_s = 0.04, up.fade_s = 0.005;
  locus::SignalSpec down = up;
  std::swap(down.f0_hz, down.f1_hz);
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  tum::NetworkConfig ncfg;
  ncfg.exchange_motion = exchange_motion;
  ncfg.yaw_prior_rad = ncfg.still_yaw_prior_rad = 0.01;  // exact attitudes: the test is about the motion
  ncfg.doppler_instant1_s = locus::dsp::doppler_timing_instant_s(up, 48000.0);
  ncfg.doppler_instant2_s = locus::dsp::doppler_timing_instant_s(down, 48000.0);
  tum::NetworkSolver net(cfg, ncfg);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> lat(0.0, 0.04);
  double sum2 = 0.0;
  int n = 0;
  for (int k = 0; k < 24; ++k) {
    const double t1 = 1.0 + k / 3.0, t2 = t1 + (gap_s > 0 ? gap_s : lat(rng));
    const tum::NetworkResult res = net.add(moving_exchange(poses, movers, t1, t2, ncfg.doppler_instant1_s, ncfg.doppler_instant2_s));
    if (!res.ok || k < 8) continue;  // the window fills (exchange 6 can still be in a transient)
    // truth at the placement's instant: M at its hearing of tone 1 (~t1 + 5 ms), the others still
    for (const auto& d : res.devices) {
      if (d.id == "N1") continue;
      Pose truth = *std::find_if(poses.begin(), poses.end(), [&](const Pose& p) { return p.id == d.id; });
      if (d.id == "M") {
        const double t_ref = t1 + (m.pose(t1).first - poses[0].p).norm() / kC;
        std::tie(truth.p, truth.q) = m.pose(t_ref);
      }
      sum2 += (d.origin - in_body(poses[0], truth)).squaredNorm();
      ++n;
    }
  }
  return n > 0 ? std::sqrt(sum2 / n) : 1e9;
}

TEST(TumNetwork, MotionWithinAnExchange) {
  for (double gap : {0.0, 0.13}) {
    const double with = moving_rms_error(true, gap), without = moving_rms_error(false, gap);
    std::printf("tones %s: rms position error %.4f m with exchange_motion, %.4f m without\n",
                gap > 0 ? "130 ms apart" : "0-40 ms apart", with, without);
    // Overlapped: 0.8 mm rms (96 mm without). 130 ms apart the formation slides a few cm along a direction
    // the exchanges barely see (chi2 0.03 per dof): what the live overlap would remove (docs/tum.md).
    EXPECT_LT(with, gap > 0 ? 0.04 : 0.004) << "gap " << gap;
    EXPECT_GT(without, (gap > 0 ? 2.0 : 10.0) * with) << "gap " << gap;
  }
}

TEST(TumMessages, RoundTripAndRefusals) {
  tum::ObsMessage m;
  m.device = "B";
  m.seq = 7;
  m.mics_m = {{0, 0.07, 0}, {0, -0.07, 0}};
  m.speaker_m = tum::Vec3a{0.02, -0.068, 0};
  m.q_wxyz = std::array<double, 4>{1, 0, 0, 0};
  m.moving = true;
  m.t1_s = {1.5, std::numeric_limits<double>::quiet_NaN()};
  m.t2_s = {1.52, 1.5201};
  const auto d = tum::decode("tum", "tum/obs/B", tum::encode(m));
  ASSERT_TRUE(d.obs) << d.error;
  EXPECT_EQ(d.obs->device, "B");
  EXPECT_EQ(d.obs->seq, 7u);
  EXPECT_TRUE(std::isnan(d.obs->t1_s[1]));
  EXPECT_DOUBLE_EQ(d.obs->t2_s[1], 1.5201);
  EXPECT_TRUE(d.obs->moving);
  EXPECT_FALSE(d.obs->gyro_radps) << "no gyro: no w_radps";
  m.gyro_radps = tum::Vec3a{0.1, -0.2, 0.75};
  const auto dg = tum::decode("tum", "tum/obs/B", tum::encode(m));
  ASSERT_TRUE(dg.obs && dg.obs->gyro_radps) << dg.error;
  EXPECT_DOUBLE_EQ((*dg.obs->gyro_radps)[2], 0.75);
  std::string bad_w = tum::encode(m);
  bad_w.replace(bad_w.find("\"w_radps\":["), 11, "\"w_radps\":[\"x\",");
  const auto dw = tum::decode("tum", "tum/obs/B", bad_w);
  EXPECT_FALSE(dw.obs);
  EXPECT_NE(dw.error.find("w_radps"), std::string::npos) << dw.error;
  EXPECT_FALSE(tum::decode("tum", "tum/obs/C", tum::encode(m)).obs);  // topic/device mismatch
  EXPECT_FALSE(tum::decode("tum", "tum/obs/B", "{").obs);
  EXPECT_FALSE(tum::decode("tum", "tum/obs/B", R"({"type":"tum_obs","device":"B","seq":1})").obs);
  std::string bad = tum::encode(m);
  bad.replace(bad.find("\"q_wxyz\":[1.0"), 13, "\"q_wxyz\":[2.0");
  EXPECT_FALSE(tum::decode("tum", "tum/obs/B", bad).obs) << "non-unit quaternion";
}

TEST(TumTracker, StillDeviceConverges) {
  tum::TrackerConfig cfg;
  tum::Tracker tr(cfg, 1);
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n01(0.0, 0.03);
  const Vector3d truth(1.0, -0.5, 0.1);
  tum::TrackOutput o;
  for (int k = 0; k < 30; ++k) {
    const Vector3d fix = truth + Vector3d(n01(rng), n01(rng), n01(rng));
    o = tr.update_gaussian(fix, Eigen::Matrix3d::Identity() * 0.03 * 0.03, false, k / 3.0);
  }
  EXPECT_LT((o.origin - truth).norm(), 0.02);
  // Sec. VIII: a fix 1.5 m away while the device is still is an outlier.
  o = tr.update_gaussian(truth + Vector3d(1.5, 0, 0), Eigen::Matrix3d::Identity() * 1e-3, false, 10.5);
  EXPECT_TRUE(o.outlier);
  EXPECT_LT((o.origin - truth).norm(), 0.03);
}
