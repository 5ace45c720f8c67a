// LocBLE maths and plugin (plugins/locble): known answers on synthetic L walks (noise-free: exact;
// seeded noise: within the reported std), every malformed message, and the localizer fed events in
// memory (frame, guidance, bad inputs counted, not crashing).
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <numbers>
#include <random>

#include "locble/locble.hpp"
#include "locble/messages.hpp"
#include "locble/solver.hpp"
#include "support/test_host.hpp"

namespace {

using namespace locus;
namespace lb = locus::plugins::locble;
using lb::Vec2;

/// An L walk in the start frame: `n1` steps forward (+y), a turn (left = towards −x), `n2` steps.
struct Walk {
  std::vector<double> t;      ///< reading times
  std::vector<Vec2> pos;      ///< observer position at each
  lb::DeadReckoning dr;
};

Walk l_walk(int n1, int n2, bool left, double stride = 0.7, double step_s = 0.55, double rate_hz = 10.0) {
  Walk w;
  const double turn = left ? std::numbers::pi / 2 : -std::numbers::pi / 2;
  double t = 1.0;
  w.dr.add_heading(0.0, 0.3);  // raw heading of the frame's y axis (any value: relative is what counts)
  const int steps = n1 + n2;
  for (int k = 0; k < steps; ++k) {
    const double h = k < n1 ? 0.0 : turn;
    for (double s = t - step_s + 0.05; s <= t + 1e-9; s += 0.05) w.dr.add_heading(s, 0.3 + h);
    w.dr.add_step(t, stride, 1.0 / step_s);
    t += step_s;
  }
  for (double s = 0.5; s < t + 2.0; s += 1.0 / rate_hz) {
    w.t.push_back(s);
    w.pos.push_back(w.dr.position_at(s));
  }
  return w;
}

double model_rss(const Vec2& tag, const Vec2& obs, double gamma, double n) {
  return gamma - 10.0 * n * std::log10(std::max((tag - obs).norm(), 0.1));
}

TEST(LocBleDeadReckoning, LShapeIsExact) {
  const Walk w = l_walk(4, 3, /*left=*/true);
  // 4 steps forward (+y), then 3 to the left (−x).
  const Vec2 end = w.dr.position_at(100.0);
  EXPECT_NEAR(end.x(), -3 * 0.7, 1e-9);
  EXPECT_NEAR(end.y(), 4 * 0.7, 1e-9);
  EXPECT_NEAR(w.dr.path_length_at(100.0), 7 * 0.7, 1e-9);
  ASSERT_TRUE(w.dr.turn_step(0.7).has_value());
  EXPECT_EQ(*w.dr.turn_step(0.7), 4u);
  EXPECT_EQ(w.dr.position_at(-5.0), Vec2(0, 0));
  // Halfway through the first step.
  EXPECT_NEAR(w.dr.position_at(1.0 - 0.275).y(), 0.35, 1e-9);
}

TEST(LocBleDeadReckoning, RejectsBadSteps) {
  lb::DeadReckoning dr;
  dr.add_heading(0.0, 0.0);
  EXPECT_TRUE(dr.add_step(1.0, 0.7, 2.0));
  EXPECT_FALSE(dr.add_step(0.5, 0.7, 2.0));  // out of order
  EXPECT_FALSE(dr.add_step(2.0, std::nan(""), 2.0));
  EXPECT_FALSE(dr.add_step(2.0, -0.1, 2.0));
  EXPECT_EQ(dr.steps(), 1u);
}

TEST(LocBleDeadReckoning, HeadingWrapsAcrossPi) {
  lb::DeadReckoning dr;
  dr.add_heading(0.0, std::numbers::pi - 0.05);
  dr.add_heading(0.5, -std::numbers::pi + 0.05);  // +0.1 rad, across the branch cut
  dr.add_step(1.0, 1.0, 1.0);
  EXPECT_NEAR(dr.step_heading_rad(0), 0.05, 1e-9);  // mean of the samples 0 and +0.1 (not of 0 and −2π + 0.1)
}

TEST(LocBleRegression, RecoversTagExactlyFromNoiseFreeL) {
  const Walk w = l_walk(5, 5, true);
  const Vec2 tag(2.5, 3.0);
  std::vector<double> rss;
  for (const Vec2& p : w.pos) rss.push_back(model_rss(tag, p, -60.0, 2.0));
  lb::RegressionOptions opt;
  opt.n_min = 1.5;
  opt.n_max = 3.0;
  opt.n_step = 0.1;
  const lb::RegressionFit f = lb::elliptical_regression(w.pos, rss, opt);
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_NEAR(f.n, 2.0, 1e-6);
  EXPECT_NEAR(f.gamma_dbm, -60.0, 1e-6);
  EXPECT_NEAR((f.position_m - tag).norm(), 0.0, 1e-6);
}

TEST(LocBleRegression, StraightLegGivesTheMirrorPair) {
  std::vector<Vec2> o;
  std::vector<double> rss;
  const Vec2 tag(3.0, -2.0);  // leg along x: |h| = 2
  for (int i = 0; i < 30; ++i) {
    o.emplace_back(0.15 * i, 0.0);
    rss.push_back(model_rss(tag, o.back(), -55.0, 2.5));
  }
  lb::RegressionOptions opt;
  opt.straight = true;
  const lb::RegressionFit f = lb::elliptical_regression(o, rss, opt);
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_NEAR(f.position_m.x(), 3.0, 1e-5);
  EXPECT_NEAR(f.position_m.y(), 2.0, 1e-5);
  EXPECT_NEAR(f.n, 2.5, 1e-6);
}

TEST(LocBleRegression, RejectsTooFewOrMismatched) {
  std::vector<Vec2> o(3, Vec2(0, 0));
  std::vector<double> r(3, -60.0);
  EXPECT_THROW(lb::elliptical_regression(o, r), std::invalid_argument);
  std::vector<double> r2(2, -60.0);
  EXPECT_THROW(lb::elliptical_regression(o, r2), std::invalid_argument);
}

TEST(LocBleRegression, RisingRssWithDistanceHasNoSolution) {
  std::vector<Vec2> o;
  std::vector<double> rss;
  for (int i = 0; i < 20; ++i) {
    o.emplace_back(0.2 * i, 0.1 * i * i * 0.05);
    rss.push_back(-90.0 + 0.0 * i);  // flat: no distance information at all
  }
  const lb::RegressionFit f = lb::elliptical_regression(o, rss);
  if (f.ok) EXPECT_TRUE(std::isfinite(f.position_m.norm()));
  else EXPECT_FALSE(f.why.empty());
}

std::vector<lb::Bin> bins_for(const Walk& w, const Vec2& tag, double gamma, double n, double noise_db, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<lb::Reading> r;
  std::vector<double> len;
  for (std::size_t i = 0; i < w.t.size(); ++i) {
    r.push_back({w.t[i], model_rss(tag, w.pos[i], gamma, n) + noise_db * g(rng)});
    len.push_back(w.dr.path_length_at(w.t[i]));
  }
  return lb::make_bins(r, w.pos, len, 0.5);
}

TEST(LocBleLShape, PicksTheTrueSideOfBothLegs) {
  for (const bool left : {true, false}) {
    const Walk w = l_walk(6, 6, left);
    // Tags beside both legs (their projections fall on each leg: what the L is for); a tag off the
    // end of a leg leaves that leg's along-track position ill-conditioned (Eq. 2-5 trades it for n).
    const double s = left ? -1.0 : 1.0;
    for (const Vec2& tag : {Vec2(s * 1.5, 2.5), Vec2(s * 3.0, 1.5), Vec2(s * 2.0, 3.0)}) {
      const auto bins = bins_for(w, tag, -60.0, 2.0, 0.0, 1);
      std::vector<std::size_t> l1, l2;
      const double t_turn = w.dr.step_begin_s(*w.dr.turn_step(0.7));
      for (std::size_t i = 0; i < bins.size(); ++i) (bins[i].t_s < t_turn ? l1 : l2).push_back(i);
      const auto p = lb::l_shape(bins, l1, l2);
      ASSERT_TRUE(p.has_value());
      EXPECT_LT((*p - tag).norm(), 0.3) << "left=" << left << " tag " << tag.transpose() << " got " << p->transpose();
    }
  }
}

TEST(LocBlePosterior, NoiseFreeTightPriorsFindTheTag) {
  const Walk w = l_walk(5, 5, true);
  const Vec2 tag(2.0, 4.0);
  const auto bins = bins_for(w, tag, -60.0, 2.0, 0.0, 1);
  lb::PosteriorOptions po;
  po.gamma_mean_dbm = -60.0;
  po.gamma_sd_db = 0.5;
  po.n_mean = 2.0;
  po.n_sd = 0.05;
  po.shadowing_sd_db = 0.5;
  po.fading_sd_db = 0.5;
  lb::PositionPosterior post(po);
  const lb::TagEstimate e = post.solve(bins, Vec2(0, 1));
  ASSERT_TRUE(e.ok) << e.why;
  EXPECT_LT((e.position_m - tag).norm(), 0.25);
  EXPECT_LT(e.std_m, 0.5);
  EXPECT_NEAR(e.n, 2.0, 0.1);
  EXPECT_NEAR(e.gamma_dbm, -60.0, 1.0);
  EXPECT_LT(e.mirror_mass, 0.05);
  EXPECT_GT(e.confidence, 0.5);
}

TEST(LocBlePosterior, NoisyErrorsAreWithinTheStd) {
  // 40 seeded noisy walks (4 dB per reading, known model): ~68 % of errors within 1 std; we ask for
  // a wide band (45-95 %) so that the test checks the calibration, not the random draw.
  const Walk w = l_walk(5, 5, true);
  lb::PositionPosterior post(lb::PosteriorOptions{.gamma_mean_dbm = -60.0, .gamma_sd_db = 2.0, .n_mean = 2.0,
                                                  .n_sd = 0.2, .shadowing_sd_db = 0.5, .fading_sd_db = 4.0});
  int within = 0;
  const int runs = 40;
  for (int s = 0; s < runs; ++s) {
    const Vec2 tag(1.0 + 0.1 * s, 3.0 + 0.05 * s);
    const auto e = post.solve(bins_for(w, tag, -60.0 + (s % 3 - 1), 2.0, 4.0, 100 + s), Vec2(0, 1));
    ASSERT_TRUE(e.ok);
    if ((e.position_m - tag).norm() <= e.std_m) ++within;
  }
  EXPECT_GE(within, runs * 45 / 100);
  EXPECT_LE(within, runs * 95 / 100);
}

TEST(LocBlePosterior, RefusesBadOptionsAndTooFewBins) {
  EXPECT_THROW(lb::PositionPosterior(lb::PosteriorOptions{.gamma_sd_db = 0.0}), std::invalid_argument);
  EXPECT_THROW(lb::PositionPosterior(lb::PosteriorOptions{.search_radius_m = 1.0, .grid_step_m = 2.0}), std::invalid_argument);
  lb::PositionPosterior post(lb::PosteriorOptions{});
  std::vector<lb::Bin> one(1);
  const auto e = post.solve(one, Vec2(0, 1));
  EXPECT_FALSE(e.ok);
  EXPECT_FALSE(e.why.empty());
}

TEST(LocBleBins, GroupByWalkedDistance) {
  std::vector<lb::Reading> r = {{0.0, -60}, {0.1, -62}, {1.0, -70}};
  std::vector<Vec2> p = {{0, 0}, {0, 0.2}, {0, 1.2}};
  std::vector<double> len = {0.0, 0.2, 1.2};
  const auto b = lb::make_bins(r, p, len, 0.5);
  ASSERT_EQ(b.size(), 2u);
  EXPECT_EQ(b[0].count, 2);
  EXPECT_DOUBLE_EQ(b[0].rssi_dbm, -61.0);
  EXPECT_DOUBLE_EQ(b[0].observer_m.y(), 0.1);
  std::vector<double> short_len = {0.0};
  EXPECT_THROW(lb::make_bins(r, p, short_len, 0.5), std::invalid_argument);
  EXPECT_THROW(lb::make_bins(r, p, len, 0.0), std::invalid_argument);
}

TEST(LocBleCluster, MatchesTracesThatMoveTogether) {
  std::vector<float> target, near, far, gappy;
  for (int i = 0; i < 80; ++i) {
    const float x = static_cast<float>(i);
    target.push_back(-70.0f + 6.0f * std::sin(x * 0.15f));
    near.push_back(-78.0f + 6.0f * std::sin(x * 0.15f + 0.05f));  // offset does not matter (differenced)
    far.push_back(-70.0f - 6.0f * std::sin(x * 0.15f));            // opposite trend
    gappy.push_back(i % 3 == 0 ? std::numeric_limits<float>::quiet_NaN() : target.back());
  }
  const auto m = lb::cluster_members(target, {near, far, gappy}, lb::ClusterOptions{.segment = 10, .window = 2, .threshold = 0.5});
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], 0u);
  std::vector<float> wrong_len(10, 0.0f);
  EXPECT_THROW(lb::cluster_members(target, {wrong_len}), std::invalid_argument);
  // The all-pairs form agrees with the target-vs-others form, and is symmetric.
  const lb::ClusterOptions o{.segment = 10, .window = 2, .threshold = 0.5};
  const auto mm = lb::cluster_matrix({target, near, far, gappy}, o);
  EXPECT_TRUE(mm[0][1]);
  EXPECT_TRUE(mm[1][0]);
  EXPECT_FALSE(mm[0][2]);
  EXPECT_FALSE(mm[0][3]);
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t j = 0; j < 4; ++j) EXPECT_EQ(mm[i][j], mm[j][i]);
  EXPECT_THROW(lb::cluster_matrix({target, wrong_len}), std::invalid_argument);
}

// The co-location gate (Sec. 6 + solver.hpp): two tags at one place have overlapping posteriors (Bayes
// factor > 1); a tag 10 m away from a well-located one is excluded (≪ 1), even though its posterior is
// wide; an empty grid never clusters.
TEST(LocBleCluster, ColocationBayesFactor) {
  // An L walk; readings from the log-distance model (noise-free) for tags at a and b.
  auto readings = [](const Vec2& tag) {
    std::vector<lb::Bin> bins;
    for (int k = 0; k <= 16; ++k) {
      const Vec2 o = k <= 8 ? Vec2{0.0, 0.3 * k} : Vec2{-0.3 * (k - 8), 2.4};
      bins.push_back({o, -60.0 - 20.0 * std::log10(std::max((tag - o).norm(), 0.5)), 5, static_cast<double>(k)});
    }
    return bins;
  };
  lb::PosteriorOptions po;
  po.gamma_mean_dbm = -60.0;
  po.n_mean = 2.0;
  po.shadowing_sd_db = 1.0;  // a clean link
  po.fading_sd_db = 2.0;
  lb::PositionPosterior post(po);
  const Vec2 axis{0.0, 1.0};
  const auto a = post.solve_coarse_to_fine(readings({2.0, 3.0}), axis, false, 0.1);
  const auto a2 = post.solve_coarse_to_fine(readings({2.5, 3.3}), axis, false, 0.1);
  const auto far = post.solve_coarse_to_fine(readings({-8.0, -6.0}), axis, false, 0.1);
  ASSERT_TRUE(a.ok && a2.ok && far.ok);
  ASSERT_FALSE(a.grid.empty());
  double total = 0.0;
  for (float p : a.grid.p) total += p;
  EXPECT_NEAR(total, 1.0, 1e-3);
  EXPECT_GT(lb::colocation_bayes_factor(a.grid, a2.grid), 3.0);
  EXPECT_LT(lb::colocation_bayes_factor(a.grid, far.grid), 0.1);
  EXPECT_LT(lb::colocation_bayes_factor(far.grid, a.grid), 0.1);
  EXPECT_EQ(lb::colocation_bayes_factor(a.grid, lb::PosteriorGrid{}), 0.0);
}

TEST(LocBleCluster, FuseWeightsByConfidence) {
  std::vector<Vec2> p = {{0, 0}, {4, 0}};
  std::vector<double> w = {3.0, 1.0};
  const Vec2 f = lb::fuse(p, w);
  EXPECT_DOUBLE_EQ(f.x(), 1.0);
  std::vector<double> zero = {0.0, 0.0};
  EXPECT_THROW(lb::fuse(p, zero), std::invalid_argument);
  std::vector<double> shortw = {1.0};
  EXPECT_THROW(lb::fuse(p, shortw), std::invalid_argument);
}

TEST(LocBleMessages, RoundTripAndMalformed) {
  lb::TargetMotion m;
  m.address = {0x73, 0x45, 0x42, 0xA0, 0x2A, 0x93};
  m.t_s = 12.5;
  m.east_m = -1.25;
  m.north_m = 3.0;
  const auto d = lb::decode(lb::encode(m));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->address, m.address);
  EXPECT_DOUBLE_EQ(d->t_s, 12.5);
  EXPECT_DOUBLE_EQ(d->east_m, -1.25);
  EXPECT_DOUBLE_EQ(d->north_m, 3.0);
  EXPECT_EQ(lb::format_address(m.address), "73:45:42:A0:2A:93");
  ASSERT_TRUE(lb::parse_address("73:45:42:a0:2a:93").has_value());
  for (const char* bad : {"", "73:45:42:A0:2A 1 2 3", "73-45-42-A0-2A-93 1 2 3", "73:45:42:A0:2A:9G 1 2 3",
                          "73:45:42:A0:2A:93 1 2", "73:45:42:A0:2A:93 1 2 3 4", "73:45:42:A0:2A:93 nan 2 3",
                          "73:45:42:A0:2A:93 1 inf 3", "73:45:42:A0:2A:93 x 2 3"}) {
    std::string why;
    EXPECT_FALSE(lb::decode(bad, &why).has_value()) << bad;
    EXPECT_FALSE(why.empty()) << bad;
  }
}

// ------------------------------------------------------------------------------------ the plugin

class CollectingPublisher final : public Publisher {
 public:
  void publish(const Event& e) override {
    if (const auto* est = std::get_if<Estimate>(&e)) estimates.push_back(*est);
  }
  std::vector<Estimate> estimates;
};

Params params(std::initializer_list<std::pair<const char*, ParamValue>> kv = {}) {
  Params p = Params::defaults(lb::schema());
  for (const auto& [k, v] : kv) p.set(k, v);
  return p;
}

/// The L walk of LocatesATagFromEventsInMemory through a localizer with `point` (mean | map); the
/// estimates published.
std::vector<Estimate> locate_in_memory(const std::string& point);

TEST(LocBlePlugin, LocatesATagFromEventsInMemory) {
  const std::vector<Estimate> estimates = locate_in_memory("mean");
  ASSERT_FALSE(estimates.empty());
  const Estimate& e = estimates.back();
  const Vec2 tag(2.0, 3.0);
  const double stride = 0.7;
  EXPECT_EQ(e.target.str(), "C4:2C:03:01:02:03");
  EXPECT_EQ(e.reference.str(), "O");
  EXPECT_EQ(e.frame.str().rfind("observer_start@", 0), 0u);
  EXPECT_EQ(e.dims, 2);
  EXPECT_LT(std::hypot(e.position_m[0] - tag.x(), e.position_m[1] - tag.y()), 0.5)
      << e.position_m[0] << " " << e.position_m[1];
  // Guidance from the end of the walk (5 steps forward, 5 to the left).
  const Vec2 here(-5 * stride, 5 * stride);
  EXPECT_NEAR(e.distance_m, (tag - here).norm(), 0.5);
  EXPECT_NEAR(e.direction_rad, std::atan2(tag.y() - here.y(), tag.x() - here.x()), 0.2);
  EXPECT_TRUE(std::isfinite(e.std_m));
  EXPECT_GT(e.confidence, 0.0f);
}

std::vector<Estimate> locate_in_memory(const std::string& point) {
  test::TestHost host;
  HostContext ctx = host.context("locble", "O");
  std::unique_ptr<Localizer> loc(lb::descriptor()->create_localizer());
  loc->configure(params({{"gamma_sd_db", 1.0}, {"n_mean", 2.0}, {"n_sd", 0.1}, {"shadowing_sd_db", 0.5},
                         {"fading_sd_db", 1.0}, {"grid_step_m", 0.5}, {"point", point}}),
                 ctx);
  CollectingPublisher out;
  const Vec2 tag(2.0, 3.0);
  const std::array<std::uint8_t, 6> addr{0xC4, 0x2C, 0x03, 0x01, 0x02, 0x03};
  // Events in time order: headings at 20 Hz, steps, adverts at 10 Hz (each followed by a filtered
  // copy with the same time, as ble_rss emits: ignored).
  const double step_s = 0.55, stride = 0.7;
  double next_step = 1.0;
  int steps = 0;
  lb::DeadReckoning truth;  // the same path, to place the adverts
  truth.add_heading(0.0, 1.0);
  std::vector<double> step_t;
  for (int k = 0; k < 10; ++k) step_t.push_back(1.0 + k * step_s);
  for (int k = 0; k < 10; ++k) {
    const double h = k < 5 ? 1.0 : 1.0 + std::numbers::pi / 2;
    for (double s = step_t[k] - step_s + 0.05; s <= step_t[k] + 1e-9; s += 0.05) truth.add_heading(s, h);
    truth.add_step(step_t[k], stride, 1.0 / step_s);
  }
  for (double t = 0.0; t < 10.0; t += 0.05) {
    Attitude a;
    a.device.assign("O");
    a.detector.assign("attitude");
    a.t_s = t;
    a.heading_rad = static_cast<float>(t < step_t[4] ? 1.0 : (t < step_t[5] - step_s + 0.05 ? 1.0 : 1.0 + std::numbers::pi / 2));
    loc->on_event(Event{a}, out);
    if (steps < 10 && t >= next_step) {
      Step s;
      s.device.assign("O");
      s.detector.assign("steps");
      s.t_s = step_t[static_cast<std::size_t>(steps)];
      s.stride_m = static_cast<float>(stride);
      s.frequency_hz = static_cast<float>(1.0 / step_s);
      loc->on_event(Event{s}, out);
      ++steps;
      next_step += step_s;
    }
    if (static_cast<int>(std::lround(t * 20)) % 2 == 0) {
      BleAdvertisement b;
      b.device.assign("O");
      b.t_s = t;
      b.address = addr;
      b.rssi_dbm = static_cast<float>(model_rss(tag, truth.position_at(t), -60.0, 2.0));
      b.tx_power_dbm = -60.0f;
      b.has_tx_power = true;
      loc->on_event(Event{b}, out);
      b.rssi_dbm = -20.0f;  // the filtered copy: must not count
      loc->on_event(Event{b}, out);
    }
  }
  loc->finish(out);
  return out.estimates;
}

// point: map publishes the most probable cell; its std is the spread about that cell, never below
// the spread about the mean.
TEST(LocBlePlugin, MapPointIsTheMostProbableCell) {
  const std::vector<Estimate> mean = locate_in_memory("mean"), map = locate_in_memory("map");
  ASSERT_FALSE(map.empty());
  ASSERT_EQ(mean.size(), map.size());
  const Estimate& e = map.back();
  EXPECT_LT(std::hypot(e.position_m[0] - 2.0, e.position_m[1] - 3.0), 0.5) << e.position_m[0] << " " << e.position_m[1];
  EXPECT_GE(e.std_m, mean.back().std_m - 1e-9);
}

TEST(LocBlePlugin, MovingTargetPublishesItsMotion) {
  // The observer walks an L; the tag drifts at 0.15 m/s along the frame's x and publishes its
  // displacement (east, north) over the link; the estimate is where the tag is at the end.
  test::TestHost host;
  HostContext ctx = host.context("locble", "O");
  std::unique_ptr<Localizer> loc(lb::descriptor()->create_localizer());
  loc->configure(params({{"gamma_sd_db", 1.0}, {"n_mean", 2.0}, {"n_sd", 0.1}, {"shadowing_sd_db", 0.5},
                         {"fading_sd_db", 1.0}, {"grid_step_m", 0.5}, {"clustering", false}}),
                 ctx);
  CollectingPublisher out;
  const double psi = 1.0;  // raw heading of the frame's y axis (north-referenced: x north, y west)
  const Vec2 start(2.0, 3.0), vel(0.15, 0.0);
  const std::array<std::uint8_t, 6> addr{0xC4, 0x2C, 0x03, 0x09, 0x08, 0x07};
  const double step_s = 0.55, stride = 0.7;
  lb::DeadReckoning truth;
  truth.add_heading(0.0, psi);
  std::vector<double> step_t;
  for (int k = 0; k < 10; ++k) step_t.push_back(1.0 + k * step_s);
  for (int k = 0; k < 10; ++k) {
    const double h = k < 5 ? psi : psi + std::numbers::pi / 2;
    for (double s = step_t[k] - step_s + 0.05; s <= step_t[k] + 1e-9; s += 0.05) truth.add_heading(s, h);
    truth.add_step(step_t[k], stride, 1.0 / step_s);
  }
  int steps = 0;
  for (double t = 0.0; t < 10.0; t += 0.05) {
    Attitude a;
    a.device.assign("O");
    a.detector.assign("attitude");
    a.t_s = t;
    a.heading_rad = static_cast<float>(t < step_t[5] - step_s + 0.05 ? psi : psi + std::numbers::pi / 2);
    loc->on_event(Event{a}, out);
    if (steps < 10 && t >= step_t[static_cast<std::size_t>(steps)]) {
      Step s;
      s.device.assign("O");
      s.detector.assign("steps");
      s.t_s = step_t[static_cast<std::size_t>(steps)];
      s.stride_m = static_cast<float>(stride);
      s.frequency_hz = static_cast<float>(1.0 / step_s);
      loc->on_event(Event{s}, out);
      ++steps;
    }
    const Vec2 d = vel * t;  // displacement in the frame -> east, north (x north, y west reference)
    lb::TargetMotion m;
    m.address = addr;
    m.t_s = t;
    m.east_m = d.x() * std::cos(psi) - d.y() * std::sin(psi);
    m.north_m = d.x() * std::sin(psi) + d.y() * std::cos(psi);
    ctx.link.publish("locble/motion/" + lb::format_address(addr), lb::encode(m));
    if (static_cast<int>(std::lround(t * 20)) % 2 == 0) {
      BleAdvertisement b;
      b.device.assign("O");
      b.t_s = t;
      b.address = addr;
      b.rssi_dbm = static_cast<float>(model_rss(start + d, truth.position_at(t), -60.0, 2.0));
      b.tx_power_dbm = -60.0f;
      b.has_tx_power = true;
      loc->on_event(Event{b}, out);
    }
  }
  loc->finish(out);
  ASSERT_FALSE(out.estimates.empty());
  const Estimate& e = out.estimates.back();
  const Vec2 now = start + vel * e.t_s;
  EXPECT_LT(std::hypot(e.position_m[0] - now.x(), e.position_m[1] - now.y()), 0.5)
      << e.position_m[0] << " " << e.position_m[1] << " vs " << now.transpose();
}

TEST(LocBlePlugin, BadParamsAndMessagesAreRefusedOrCounted) {
  test::TestHost host;
  HostContext ctx = host.context("locble", "O");
  std::unique_ptr<Localizer> loc(lb::descriptor()->create_localizer());
  EXPECT_THROW(loc->configure(params({{"n_min", 3.0}, {"n_max", 2.0}}), ctx), std::runtime_error);
  std::unique_ptr<Localizer> loc2(lb::descriptor()->create_localizer());
  EXPECT_THROW(loc2->configure(params({{"grid_step_m", 5.0}, {"search_radius_m", 2.0}}), ctx), std::runtime_error);
  std::unique_ptr<Localizer> ok(lb::descriptor()->create_localizer());
  ok->configure(params(), ctx);
  ctx.link.publish("locble/motion/x", "not a message");
  CollectingPublisher out;
  ok->finish(out);  // no data: no estimate, warnings, no crash
  EXPECT_TRUE(out.estimates.empty());
  EXPECT_TRUE(host.log.contains("malformed motion messages"));
  EXPECT_FALSE(host.log.contains("no heading"));  // heard no tag: not an observer, nothing to say
  // An observer that heard a tag but got no motion says why it has no estimate.
  std::unique_ptr<Localizer> obs(lb::descriptor()->create_localizer());
  obs->configure(params(), ctx);
  BleAdvertisement b;
  b.device.assign("O");
  b.t_s = 1.0;
  b.address = {1, 2, 3, 4, 5, 6};
  b.rssi_dbm = -70.0f;
  obs->on_event(Event{b}, out);
  obs->finish(out);
  EXPECT_TRUE(out.estimates.empty());
  EXPECT_TRUE(host.log.contains("no heading"));
}

}  // namespace

// ------------------------------------------------------------------------------------ EnvAware

#include <filesystem>
#include <fstream>

#include "locble/envaware.hpp"

namespace {

TEST(LocBleEnvAware, FeaturesOfAKnownWindow) {
  const std::vector<double> x = {-70, -72, -74, -76, -78};
  const auto f = lb::envaware_features(x);
  EXPECT_DOUBLE_EQ(f[0], -74.0);      // mean
  EXPECT_DOUBLE_EQ(f[1], 8.0);        // variance (population)
  EXPECT_NEAR(f[2], 0.0, 1e-12);      // skewness
  EXPECT_NEAR(f[3], -1.3, 1e-12);     // excess kurtosis of 5 equally spaced values
  EXPECT_DOUBLE_EQ(f[4], -78.0);
  EXPECT_DOUBLE_EQ(f[5], -76.0);
  EXPECT_DOUBLE_EQ(f[6], -74.0);
  EXPECT_DOUBLE_EQ(f[7], -72.0);
  EXPECT_DOUBLE_EQ(f[8], -70.0);
  const std::vector<double> one = {-70};
  EXPECT_THROW(lb::envaware_features(one), std::invalid_argument);
  EXPECT_EQ(lb::envaware_class("plos"), 1);
  EXPECT_EQ(lb::envaware_class("NLOS"), 2);
  EXPECT_FALSE(lb::envaware_class("maybe").has_value());
}

TEST(LocBleEnvAware, ModelRoundTripAndBadFiles) {
  const auto dir = std::filesystem::temp_directory_path() / "locble_envaware_test";
  std::filesystem::create_directories(dir);
  lb::EnvAwareModel m;
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(3, lb::kEnvFeatures);
  w(0, 0) = 1.0;   // LOS: loud
  w(2, 0) = -1.0;  // NLOS: quiet
  m.mean = Eigen::VectorXd::Constant(lb::kEnvFeatures, -70.0);
  m.scale = Eigen::VectorXd::Constant(lb::kEnvFeatures, 10.0);
  m.svm = locus::dsp::LinearSvm(w, Eigen::Vector3d(0.0, 0.1, 0.0));
  m.svm.set_standardization(m.mean, m.scale);
  const auto good = (dir / "good.yaml").string();
  std::ofstream(good) << lb::envaware_model_yaml(m, "test");
  const lb::EnvAwareModel r = lb::load_envaware_model(good);
  std::array<double, lb::kEnvFeatures> loud{}, quiet{};
  loud.fill(-50.0);
  quiet.fill(-90.0);
  EXPECT_EQ(r.predict(loud), 0);
  EXPECT_EQ(r.predict(quiet), 2);
  const std::string text = lb::envaware_model_yaml(m, "test");
  struct Bad {
    std::string from, to, field;
  };
  for (const Bad& b : {Bad{"format: locble-envaware/1", "format: other", "format"},
                       Bad{"classes: [LOS, pLOS, NLOS]", "classes: [A, B, C]", "classes"},
                       Bad{"mean: [", "mean: [x, ", "mean"}, Bad{"bias: [", "bias: [1, ", "bias"}}) {
    std::string t = text;
    t.replace(t.find(b.from), b.from.size(), b.to);
    const auto path = (dir / "bad.yaml").string();
    std::ofstream(path) << t;
    try {
      lb::load_envaware_model(path);
      ADD_FAILURE() << "accepted a model with a bad " << b.field;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(b.field), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad.yaml"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(lb::load_envaware_model((dir / "missing.yaml").string()), std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
