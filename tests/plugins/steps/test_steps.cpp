// `steps` on synthetic walks (walk_sim.hpp): count error <= 2 %, step timing, stride models, no
// steps while standing, robustness to gaps and bad samples.
#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "motion_test_util.hpp"
#include "walk_sim.hpp"

namespace locus::test {
namespace {

struct StepRun {
  std::vector<Step> steps;
  WalkTruth truth;
};

StepRun run_steps(const std::string& mode, const std::string& stride, unsigned seed, double f_scale = 1.0,
                  WalkOptions o = {}) {
  TestHost host;
  Params p;
  p.set("mode", mode);
  p.set("stride_model", stride);
  auto det = make_detector("steps", host, p);
  StepRun r;
  o.seed = seed;
  const auto imu = simulate_walk(mixed_walk(f_scale), o, r.truth);
  CollectingSink sink;
  feed_imu(*det, imu, sink);
  det->finish(sink);
  r.steps = events_of<Step>(sink);
  return r;
}

void expect_counts(const std::string& mode) {
  long total_true = 0, total_det = 0, total_matched = 0;
  for (unsigned seed = 1; seed <= 4; ++seed) {
    for (double fs : {0.85, 1.0, 1.1}) {
      const StepRun r = run_steps(mode, "bounce", seed, fs);
      std::vector<double> det;
      for (const Step& s : r.steps) det.push_back(s.t_s);
      const auto matched = match_times(r.truth.step_t_s, det, 0.25);
      const double err = std::abs(static_cast<double>(det.size()) - static_cast<double>(r.truth.step_t_s.size())) /
                         static_cast<double>(r.truth.step_t_s.size());
      EXPECT_LE(err, 0.02) << mode << " seed " << seed << " f x" << fs << ": detected " << det.size() << " of "
                           << r.truth.step_t_s.size();
      if (err > 0.02) {  // say where the extra or missing steps are
        std::vector<double> extra;
        for (double d : det) {
          bool near = false;
          for (double t : r.truth.step_t_s) near |= std::abs(d - t) <= 0.25;
          if (!near) extra.push_back(d);
        }
        std::string where;
        for (double d : extra) where += " " + std::to_string(d);
        ADD_FAILURE() << "unmatched detections at" << where;
      }
      total_true += static_cast<long>(r.truth.step_t_s.size());
      total_det += static_cast<long>(det.size());
      total_matched += static_cast<long>(matched.size());
    }
  }
  const double matched_frac = static_cast<double>(total_matched) / static_cast<double>(total_true);
  std::printf("[ measured ] steps mode=%s: %ld true, %ld detected (%.2f %% count error), %.1f %% matched within 0.25 s\n",
              mode.c_str(), total_true, total_det,
              100.0 * std::abs(static_cast<double>(total_det - total_true)) / static_cast<double>(total_true),
              100.0 * matched_frac);
  EXPECT_GE(matched_frac, 0.97);
}

TEST(Steps, MontageCountErrorWithinTwoPercent) { expect_counts("montage"); }
TEST(Steps, SpyLocCountErrorWithinTwoPercent) { expect_counts("spyloc"); }

TEST(Steps, StepTimesNearHeelStrikes) {
  for (const char* mode : {"montage", "spyloc"}) {
    const StepRun r = run_steps(mode, "bounce", 7);
    std::vector<double> det;
    for (const Step& s : r.steps) det.push_back(s.t_s);
    const auto off = match_times(r.truth.step_t_s, det, 0.25);
    ASSERT_FALSE(off.empty());
    const double mean = std::accumulate(off.begin(), off.end(), 0.0) / static_cast<double>(off.size());
    double var = 0;
    for (double x : off) var += (x - mean) * (x - mean);
    const double sd = std::sqrt(var / static_cast<double>(off.size()));
    std::printf("[ measured ] steps mode=%s: step time offset mean %+.3f s, sd %.3f s\n", mode, mean, sd);
    EXPECT_LT(std::abs(mean), 0.15) << mode;
    EXPECT_LT(sd, 0.06) << mode;
  }
}

TEST(Steps, BounceStrideTracksTrueStride) {
  for (const char* mode : {"montage", "spyloc"}) {
    const StepRun r = run_steps(mode, "bounce", 3);
    std::vector<double> det;
    for (const Step& s : r.steps) det.push_back(s.t_s);
    // Relative error of each matched step's stride.
    double sum_rel = 0;
    int n = 0;
    for (const Step& s : r.steps) {
      std::size_t best = 0;
      for (std::size_t k = 1; k < r.truth.step_t_s.size(); ++k)
        if (std::abs(r.truth.step_t_s[k] - s.t_s) < std::abs(r.truth.step_t_s[best] - s.t_s)) best = k;
      if (std::abs(r.truth.step_t_s[best] - s.t_s) > 0.25 || !std::isfinite(s.stride_m)) continue;
      sum_rel += std::abs(s.stride_m - r.truth.step_stride_m[best]) / r.truth.step_stride_m[best];
      ++n;
    }
    ASSERT_GT(n, 100);
    const double mean_rel = sum_rel / n;
    std::printf("[ measured ] steps mode=%s bounce stride: mean |relative error| %.1f %% over %d steps\n", mode,
                100.0 * mean_rel, n);
    EXPECT_LT(mean_rel, 0.12) << mode;
  }
}

TEST(Steps, LinearStrideIsAfPlusB) {
  TestHost host;
  Params p;
  p.set("stride_model", std::string("linear"));
  p.set("stride_a", 0.3);
  p.set("stride_b", 0.1);
  auto det = make_detector("steps", host, p);
  WalkTruth truth;
  const auto imu = simulate_walk(mixed_walk(), WalkOptions{}, truth);
  CollectingSink sink;
  feed_imu(*det, imu, sink);
  const auto steps = events_of<Step>(sink);
  ASSERT_GT(steps.size(), 100u);
  for (const Step& s : steps) {
    EXPECT_NEAR(s.stride_m, 0.3 * s.frequency_hz + 0.1, 1e-5);
    EXPECT_GT(s.frequency_hz, 1.0);
    EXPECT_LT(s.frequency_hz, 4.0);
  }
}

// A gait whose mid-stride bump (a strong second harmonic) rises above the threshold every other
// step (left/right asymmetry), as foreign montage-103's walker U1 does with its phone's attitude
// (46 steps found for 30 before the secondary-peak check): the bumps are not steps.
TEST(Steps, MidStrideBumpsOfAnAsymmetricGaitAreNotSteps) {
  for (const char* mode_ratio : {"on", "off"}) {
    const bool on = std::string(mode_ratio) == "on";
    long total_true = 0, total_det = 0;
    for (unsigned seed = 1; seed <= 3; ++seed) {
      TestHost host;
      Params p;
      if (!on) p.set("secondary_ratio", 0.0);
      auto det = make_detector("steps", host, p);
      WalkOptions o;
      o.seed = seed;
      o.harmonic = 0.8;  // a mid-stride bump ...
      o.harmonic_phase = 0.0;
      o.asymmetry = 0.35;  // ... that crosses the threshold every other step
      WalkTruth truth;
      const auto imu = simulate_walk(mixed_walk(), o, truth);
      CollectingSink sink;
      feed_imu(*det, imu, sink);
      det->finish(sink);
      total_true += static_cast<long>(truth.step_t_s.size());
      total_det += static_cast<long>(events_of<Step>(sink).size());
      if (on) {  // say where the extra steps are
        std::string where;
        for (const Step& st : events_of<Step>(sink)) {
          bool near = false;
          for (double t : truth.step_t_s) near |= std::abs(st.t_s - t) <= 0.2;
          if (!near) where += " " + std::to_string(st.t_s).substr(0, 6);
        }
        if (!where.empty()) std::printf("[ measured ] seed %u: detections away from every heel strike at%s\n", seed, where.c_str());
      }
    }
    const double err = static_cast<double>(total_det - total_true) / static_cast<double>(total_true);
    std::printf("[ measured ] steps, asymmetric gait, secondary check %s: %ld true, %ld detected (%+.1f %%)\n", mode_ratio,
                total_true, total_det, 100.0 * err);
    // 2.5 %, not the 2 % of the regular gait: at each walk start (3 per walk, 0.4 s amplitude ramp)
    // a bump can pass before there is a cadence to call it early (8 of the 10 extra on seeds 1-3;
    // the ramp's first heel strike is not in the truth either).
    if (on) EXPECT_LE(std::abs(err), 0.025);
    else EXPECT_GT(err, 0.10) << "the walk no longer has the bumps this test is about";
  }
}

TEST(Steps, NoStepsWhileStandingOrHandTremor) {
  for (const char* mode : {"montage", "spyloc"}) {
    TestHost host;
    Params p;
    p.set("mode", std::string(mode));
    auto det = make_detector("steps", host, p);
    WalkTruth truth;
    WalkOptions o;
    o.accel_noise = 0.4;  // a noisy sensor in a shaking hand
    const auto imu = simulate_walk({{WalkSegment::Stand, 60.0}}, o, truth);
    CollectingSink sink;
    feed_imu(*det, imu, sink);
    EXPECT_EQ(events_of<Step>(sink).size(), 0u) << mode;
  }
}

TEST(Steps, SurvivesGapsBackwardsTimeAndNonFiniteSamples) {
  TestHost host;
  auto det = make_detector("steps", host);
  WalkTruth truth;
  auto imu = simulate_walk(mixed_walk(), WalkOptions{}, truth);
  imu.erase(imu.begin() + 3000, imu.begin() + 3200);  // a 2 s gap
  imu[5000].accel_mps2[0] = NAN;
  imu[6000].t_s -= 1.0;  // time going backwards
  CollectingSink sink;
  feed_imu(*det, imu, sink, 7);
  det->finish(sink);
  const auto steps = events_of<Step>(sink);
  EXPECT_GT(steps.size(), truth.step_t_s.size() * 8 / 10);
  EXPECT_LE(steps.size(), truth.step_t_s.size());
  for (std::size_t i = 1; i < steps.size(); ++i) EXPECT_TRUE(std::isfinite(steps[i].t_s));
  EXPECT_TRUE(host.log.contains("non-finite"));
}

TEST(Steps, RejectsInconsistentParameters) {
  TestHost host;
  Params p;
  p.set("min_step_s", 0.8);
  p.set("max_step_s", 0.5);
  EXPECT_THROW(make_detector("steps", host, p), std::runtime_error);
  Params q;
  q.set("template", std::vector<double>{1.0, 1.0, 1.0, 1.0});
  EXPECT_THROW(make_detector("steps", host, q), std::runtime_error);
}

}  // namespace
}  // namespace locus::test
