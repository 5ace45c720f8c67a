// Every metric family on hand-built truth and estimates with known answers.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>

#include "eval_test_support.hpp"
#include "locus/eval/error.hpp"
#include "locus/eval/metric.hpp"
#include "locus/eval/metrics.hpp"

namespace locus::eval {
namespace {

using test::deg;
using test::estimate_line;
using test::yaw;

double sum_num(const nlohmann::ordered_json& s, const char* key) {
  EXPECT_TRUE(s.contains(key)) << key;
  if (!s.contains(key) || !s[key].is_number()) return std::nan("");
  return s[key].get<double>();
}

/// Options naming the metric, as `--metric NAME` does.
EvalOptions with_metric(const std::string& name) {
  EvalOptions o;
  o.metric = name;
  return o;
}

/// The truth of a scene whose scene.yaml says `environment: {family: NAME}`.
TruthData scene_of(TruthData truth, const std::string& family) {
  truth.family = family;
  return truth;
}

const nlohmann::ordered_json& row(const GroupResult& g, const std::string& target) {
  for (const auto& r : g.targets)
    if (r["target"] == target) return r;
  static const nlohmann::ordered_json none;
  ADD_FAILURE() << "no row for " << target;
  return none;
}

TEST(EvalStats, PercentilesInterpolateLinearly) {
  std::vector<double> v;
  for (int i = 10; i >= 1; --i) v.push_back(i / 10.0);
  const Stats s = stats_of(v);
  EXPECT_EQ(s.n, 10u);
  EXPECT_NEAR(s.mean, 0.55, 1e-12);
  EXPECT_NEAR(s.median, 0.55, 1e-12);
  EXPECT_NEAR(s.p80, 0.82, 1e-12);
  EXPECT_NEAR(s.p90, 0.91, 1e-12);
  EXPECT_NEAR(s.max, 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(stats_of({}).mean));
}

TEST(EvalFamilies, EveryMetricIsRegisteredByName) {
  EXPECT_EQ(metric_names(), (std::vector<std::string>{"amil", "locble", "montage", "position", "spyloc", "tum"}));
  ASSERT_NE(find_metric("montage"), nullptr);
  EXPECT_EQ(find_metric("montage")->name, "montage");
  EXPECT_EQ(find_metric("gps"), nullptr);
  for (const Metric* m : metrics()) {
    EXPECT_NE(m->expects, nullptr) << m->name;
    EXPECT_NE(m->score, nullptr) << m->name;
    EXPECT_FALSE(m->summary.empty()) << m->name;
  }
}

TEST(EvalFamilies, NamedByTheSceneOrMetricNeverByThePluginName) {
  // Plugins called "tum_A", "SpyLoc", "finder" (frames world, player_start, observer_start) on a scene
  // of family spyloc are all scored as SpyLoc: neither an instance's name nor its frame picks the
  // metric (they used to: "tum_A" was TUM by substring, player_start AMIL).
  TruthData truth;
  truth.objects = {test::device("A"), test::device("B")};
  test::place(truth, "A", Vec3(0, 0, 0));
  test::place(truth, "B", Vec3(3, 0, 0));
  const auto file = test::parse_lines({estimate_line("tum_A", "", "world", "A", 1.0, {0, 0}),
                                       estimate_line("SpyLoc", "B", "player_start@1.0", "A", 1.0, {3, 0}),
                                       estimate_line("finder", "B", "observer_start", "A", 1.0, {3, 0})});
  truth.family = "spyloc";
  EvalResult r = evaluate(truth, file, {});
  ASSERT_EQ(r.groups.size(), 3u);
  for (const GroupResult& g : r.groups) EXPECT_EQ(g.family, "spyloc") << g.plugin;
  // --metric wins over the scene.
  r = evaluate(truth, file, with_metric("position"));
  for (const GroupResult& g : r.groups) EXPECT_EQ(g.family, "position") << g.plugin;
  // Neither names one: a clear error, no guess from the names or frames.
  truth.family.clear();
  truth.scene_dir = "/scenes/s1";
  try {
    evaluate(truth, file, {});
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.messages()[0].find("/scenes/s1/scene.yaml: the scene names no family (environment.family) and no --metric"),
              std::string::npos) << e.messages()[0];
    EXPECT_NE(e.messages()[0].find("amil, locble, montage, position, spyloc, tum"), std::string::npos) << e.messages()[0];
  }
  // A family without a metric, and an unknown --metric, name what is known.
  truth.family = "gps";
  try {
    evaluate(truth, file, {});
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.messages()[0].find("environment.family 'gps' has no metric (known: amil,"), std::string::npos) << e.messages()[0];
  }
  try {
    evaluate(truth, file, with_metric("gps"));
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.messages()[0].find("--metric gps: no such metric"), std::string::npos) << e.messages()[0];
  }
  // Nothing to score needs no metric.
  EXPECT_NO_THROW(evaluate(truth, test::parse_lines({}), {}));
}

// ------------------------------------------------------------------------------------ clocks
TEST(EvalClock, EstimateTimeIsConvertedWithTheReferenceClock) {
  // W walks along x at 1 m/s from true t = 0 to 100; its clock runs 0.5 s ahead and 200 ppm fast.
  TruthData truth;
  truth.objects = {test::device("W", true, true)};
  truth.tracks["W"].add(TruthPose{0.0, Vec3(0, 0, 0), yaw(0)});
  truth.tracks["W"].add(TruthPose{100.0, Vec3(100, 0, 0), yaw(0)});
  truth.clocks["W"] = ClockModel{0.5, 200.0};
  const ClockModel c = truth.clock("W");
  // Estimates stamped on W's clock at true 10 s and 80 s, positioned exactly at the truth.
  std::vector<std::string> lines;
  for (double t_true : {10.0, 80.0})
    lines.push_back(estimate_line("walker", "", "world", "W", c.local_from_true(t_true), {t_true, 0.0}));
  EvalResult r = evaluate(truth, test::parse_lines(lines), with_metric("position"));
  ASSERT_EQ(r.groups.size(), 1u);
  EXPECT_NEAR(sum_num(r.groups[0].summary, "max_error_m"), 0.0, 1e-9);
  // Stamped with true time instead (the plugin forgot the clock): the error is the clock error · speed.
  lines.clear();
  lines.push_back(estimate_line("walker", "", "world", "W", 80.0, {80.0, 0.0}));
  r = evaluate(truth, test::parse_lines(lines), with_metric("position"));
  EXPECT_NEAR(sum_num(r.groups[0].summary, "max_error_m"), 80.0 - c.true_from_local(80.0), 1e-9);
  EXPECT_GT(sum_num(r.groups[0].summary, "max_error_m"), 0.5);
}

TEST(EvalClock, ExtrapolatedEstimatesAreCountedAndWarned) {
  TruthData truth;
  truth.objects = {test::device("W")};
  truth.tracks["W"].add(TruthPose{0.0, Vec3(0, 0, 0), yaw(0)});
  truth.tracks["W"].add(TruthPose{10.0, Vec3(10, 0, 0), yaw(0)});
  const EvalResult r = evaluate(truth, test::parse_lines({estimate_line("p", "", "world", "W", 12.0, {10.0, 0.0})}), with_metric("position"));
  EXPECT_EQ(r.groups[0].summary["extrapolated_estimates"], 1);
  EXPECT_NEAR(sum_num(r.groups[0].summary, "mean_error_m"), 0.0, 1e-12);  // truth held at its last pose
  bool warned = false;
  for (const auto& w : r.groups[0].warnings) warned = warned || w.find("outside their target's truth time span") != std::string::npos;
  EXPECT_TRUE(warned);
}

// ------------------------------------------------------------------------------------ TUM
TruthData formation() {
  TruthData truth;
  truth.objects = {test::device("A"), test::device("B"), test::device("C"), test::device("D")};
  test::place(truth, "A", Vec3(0, 0, 0.0));
  test::place(truth, "B", Vec3(3, 0, 0.5));
  test::place(truth, "C", Vec3(0, 4, 1.0));
  test::place(truth, "D", Vec3(2, 2, 0.2));
  return truth;
}

TEST(EvalTum, RotatedAndTranslatedFormationScoresZero) {
  const TruthData truth = formation();
  const Eigen::Matrix3d r = Eigen::AngleAxisd(1.1, Vec3(0.3, -0.2, 1).normalized()).toRotationMatrix();
  std::vector<std::string> lines;
  for (double t : {1.0, 2.0}) {
    for (const char* id : {"A", "B", "C", "D"}) {
      const Vec3 p = r * truth.tracks.at(id).at(0).position_m + Vec3(5, -7, 2);
      lines.push_back(estimate_line("tum", "A", "relative", id, t, {p.x(), p.y(), p.z()}));
    }
  }
  const EvalResult res = evaluate(scene_of(truth, "tum"), test::parse_lines(lines), {});
  ASSERT_EQ(res.groups.size(), 1u);
  const GroupResult& g = res.groups[0];
  EXPECT_EQ(g.family, "tum");
  EXPECT_EQ(g.summary["snapshots_scored"], 2);
  EXPECT_NEAR(sum_num(g.summary, "mean_error_m"), 0.0, 1e-9);
  EXPECT_EQ(g.summary["targets_located"], 4);
  EXPECT_EQ(g.summary["targets_missing"], 0);
  EXPECT_EQ(g.details["pairs"].size(), 6u);
}

TEST(EvalTum, Equation23IsTheMeanAbsolutePairDistanceError) {
  // A(0,0,0) B(3,0,0) C(0,4,0): true distances 3, 4, 5. Estimated B at 3.3: errors 0.3, 0, |√(3.3²+16) − 5|.
  TruthData truth;
  truth.objects = {test::device("A"), test::device("B"), test::device("C")};
  test::place(truth, "A", Vec3(0, 0, 0));
  test::place(truth, "B", Vec3(3, 0, 0));
  test::place(truth, "C", Vec3(0, 4, 0));
  const std::vector<std::string> lines = {
      estimate_line("tum", "A", "A_start", "A", 1.0, {0, 0, 0}),
      estimate_line("tum", "A", "A_start", "B", 1.0, {3.3, 0, 0}),
      estimate_line("tum", "A", "A_start", "C", 1.0002, {0, 4, 0}),  // same snapshot (within 1 ms)
      // second snapshot: exact
      estimate_line("tum", "A", "A_start", "A", 2.0, {0, 0, 0}),
      estimate_line("tum", "A", "A_start", "B", 2.0, {3, 0, 0}),
      estimate_line("tum", "A", "A_start", "C", 2.0, {0, 4, 0}),
  };
  const GroupResult g = evaluate(scene_of(truth, "tum"), test::parse_lines(lines), {}).groups.at(0);
  const double e1 = (0.3 + 0.0 + std::abs(std::sqrt(3.3 * 3.3 + 16.0) - 5.0)) / 3.0;
  EXPECT_NEAR(g.details["snapshots"][0]["error_m"].get<double>(), e1, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "mean_error_m"), e1 / 2.0, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "max_error_m"), e1, 1e-12);
  EXPECT_NEAR(row(g, "B")["mean_pair_error_m"].get<double>(), (0.3 + std::abs(std::sqrt(3.3 * 3.3 + 16.0) - 5.0)) / 4.0, 1e-12);
}

// ------------------------------------------------------------------------------------ relative
TEST(EvalRelative, SnapshotAlignmentMakesARigidlyMovedFormationExact2D) {
  const TruthData truth = formation();
  std::vector<std::string> lines;
  const Eigen::Matrix3d r = Eigen::AngleAxisd(deg(130), Vec3::UnitZ()).toRotationMatrix();
  for (const char* id : {"A", "B", "C", "D"}) {
    const Vec3 p = r * truth.tracks.at(id).at(0).position_m + Vec3(-2, 9, 0);
    lines.push_back(estimate_line("formation", "A", "relative", id, 4.0, {p.x(), p.y()}));
  }
  // A second snapshot with one point off by 1 m (in the estimate frame): error is not zero.
  for (const char* id : {"A", "B", "C", "D"}) {
    Vec3 p = truth.tracks.at(id).at(0).position_m;
    if (std::string(id) == "D") p.x() += 1.0;
    lines.push_back(estimate_line("formation", "A", "relative", id, 5.0, {p.x(), p.y()}));
  }
  const GroupResult g = evaluate(truth, test::parse_lines(lines), with_metric("position")).groups.at(0);
  EXPECT_EQ(g.family, "position");
  // Per-target max errors: the first snapshot contributes 0; D's second error is below 1 m after the fit.
  EXPECT_NEAR(row(g, "A")["median_error_m"].get<double>(), row(g, "A")["max_error_m"].get<double>() / 2, 1e-9);
  const double d_err = row(g, "D")["max_error_m"].get<double>();
  EXPECT_GT(d_err, 0.3);
  EXPECT_LT(d_err, 1.0);
  EXPECT_EQ(g.summary["scored_estimates"], 8);
}

TEST(EvalRelative, TraceAlignmentUsesOneTransformForTheWholeTrace) {
  // W walks an L: 10 m along +x then 5 m along +y. The estimate is the same trace rotated by 40°
  // and shifted: aligned over the trace, the deviation is 0. Montage family (relative_trace).
  TruthData truth;
  truth.objects = {test::device("W", true, true)};
  auto& tr = truth.tracks["W"];
  tr.add(TruthPose{0.0, Vec3(0, 0, 0), yaw(0)});
  tr.add(TruthPose{10.0, Vec3(10, 0, 0), yaw(0)});
  tr.add(TruthPose{15.0, Vec3(10, 5, 0), yaw(0)});
  const Eigen::Matrix3d r = Eigen::AngleAxisd(deg(40), Vec3::UnitZ()).toRotationMatrix();
  std::vector<std::string> lines;
  for (double t = 0.5; t < 15.0; t += 0.5) {
    const Vec3 p = r * tr.at(t).position_m + Vec3(3, 3, 0);
    lines.push_back(estimate_line("montage", "W", "relative_trace", "W", t, {p.x(), p.y()}));
  }
  const GroupResult g = evaluate(scene_of(truth, "montage"), test::parse_lines(lines), {}).groups.at(0);
  EXPECT_EQ(g.family, "montage");
  EXPECT_NEAR(sum_num(g.summary, "mean_error_m"), 0.0, 1e-9);
  EXPECT_NEAR(row(g, "W")["path_length_m"].get<double>(), 15.0 - 0.5, 1e-9);  // path from t=0 start to 14.5
  // Without truth_steps.csv the stride error is reported as not scored (null), never silently absent.
  EXPECT_TRUE(g.summary["mean_stride_error_m"].is_null());
  ASSERT_FALSE(g.warnings.empty());
}

// ------------------------------------------------------------------------------------ AMIL
TEST(EvalAmil, KnownDirectionBiasAndDistanceScale) {
  // The player stands at (1,1) facing world −x (yaw 90°); three listeners, one never located.
  TruthData truth;
  truth.objects = {test::device("player"), test::device("L1"), test::device("L2"), test::device("L3")};
  test::place(truth, "player", Vec3(1, 1, 0), yaw(deg(90)));
  test::place(truth, "L1", Vec3(1, 3, 0));     // 2 m to the player's right
  test::place(truth, "L2", Vec3(-2, 1, 0));    // 3 m ahead
  test::place(truth, "L3", Vec3(1, -4, 0));
  // The frame: x = world +y, y = world −x. True L1 = (2, 0), L2 = (0, 3).
  const auto biased = [](double x, double y) {  // +10° bias, +10 % range
    const double a = std::atan2(y, x) + deg(10), d = 1.1 * std::hypot(x, y);
    return std::vector<double>{d * std::cos(a), d * std::sin(a)};
  };
  const std::vector<std::string> lines = {
      estimate_line("amil", "player", "player_start", "L1", 3.0, biased(2, 0)),
      estimate_line("amil", "player", "player_start", "L2", 3.0, biased(0, 3)),
      estimate_line("amil", "player", "player_start", "ghost", 3.0, {1, 1}),
  };
  const GroupResult g = evaluate(scene_of(truth, "amil"), test::parse_lines(lines), {}).groups.at(0);
  ASSERT_EQ(g.family, "amil");
  EXPECT_NEAR(sum_num(g.summary, "mean_direction_error_deg"), 10.0, 1e-9);
  EXPECT_NEAR(sum_num(g.summary, "median_distance_error_pct"), 10.0, 1e-9);
  EXPECT_NEAR(row(g, "L1")["distance_error_m"].get<double>(), 0.2, 1e-9);
  EXPECT_NEAR(row(g, "L2")["distance_error_m"].get<double>(), 0.3, 1e-9);
  // Position error: |1.1·d·e^{i10°} − d| = d·|1.1 e^{i10°} − 1|.
  const double k = std::abs(std::complex<double>(1.1 * std::cos(deg(10)), 1.1 * std::sin(deg(10))) - 1.0);
  EXPECT_NEAR(row(g, "L2")["position_error_m"].get<double>(), 3 * k, 1e-9);
  EXPECT_EQ(g.summary["targets_expected"], 3);
  EXPECT_EQ(g.summary["targets_located"], 2);
  EXPECT_NEAR(sum_num(g.summary, "located_fraction"), 2.0 / 3.0, 1e-12);
  EXPECT_EQ(row(g, "L3")["status"], "no estimate");
  EXPECT_EQ(row(g, "ghost")["status"], "unknown target");
  EXPECT_EQ(g.summary["unknown_target_estimates"], 1);
}

TEST(EvalAmil, DirectionOnlyEstimatesAndWrapAround) {
  TruthData truth;
  truth.objects = {test::device("player"), test::device("L1")};
  test::place(truth, "player", Vec3(0, 0, 0));
  test::place(truth, "L1", Vec3(-2, -0.01, 0));  // direction just below −180°... i.e. ≈ −179.7°
  // Direction 175° (no position): the error wraps to ≈ 5.3°, not 354.7°.
  const auto lines = {estimate_line("amil", "player", "player_start@0", "L1", 1.0, {nullptr, nullptr},
                                    {{"direction_rad", deg(175)}})};
  const GroupResult g = evaluate(scene_of(truth, "amil"), test::parse_lines(lines), {}).groups.at(0);
  const double truth_deg = std::atan2(-0.01, -2.0) * 180 / std::numbers::pi;
  EXPECT_NEAR(sum_num(g.summary, "mean_direction_error_deg"), 360 - (175 - truth_deg), 1e-9);
  EXPECT_EQ(g.summary["targets_located"], 1);
  EXPECT_TRUE(g.summary["mean_error_m"].is_null());  // no position, so no position error
}

// ------------------------------------------------------------------------------------ SpyLoc
TEST(EvalSpyloc, ErrorCdfAndLosSplit) {
  TruthData truth;
  truth.objects = {test::device("P", true, true)};
  TruthObject beacon;
  beacon.id = "B1";
  beacon.anchor_m = Vec3(0, 0, 2.5);
  truth.objects.push_back(beacon);
  truth.tracks["P"].add(TruthPose{0.0, Vec3(0, 0, 0), yaw(0)});
  truth.tracks["P"].add(TruthPose{20.0, Vec3(20, 0, 0), yaw(0)});
  // Errors 0.1 .. 1.0 m (along y); odd ones flagged NLOS by the plugin.
  std::vector<std::string> lines;
  for (int i = 1; i <= 10; ++i)
    lines.push_back(estimate_line("spyloc", "", "world", "P", i, {double(i), 0.1 * i}, {{"los", i % 2 == 0}}));
  const GroupResult g = evaluate(scene_of(truth, "spyloc"), test::parse_lines(lines), {}).groups.at(0);
  ASSERT_EQ(g.family, "spyloc");
  EXPECT_NEAR(sum_num(g.summary, "median_error_m"), 0.55, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "p80_error_m"), 0.82, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "p90_error_m"), 0.91, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "los_median_error_m"), 0.6, 1e-12);   // 0.2 0.4 0.6 0.8 1.0
  EXPECT_NEAR(sum_num(g.summary, "nlos_median_error_m"), 0.5, 1e-12);  // 0.1 0.3 0.5 0.7 0.9
  EXPECT_EQ(g.details["cdf"].size(), 20u);
  EXPECT_EQ(g.details["los_source"], "estimates");
  EXPECT_EQ(g.summary["targets_expected"], 1);  // the anchored beacon is not a target
}

TEST(EvalSpyloc, LosFromTruthWhenEstimatesCarryNoFlag) {
  TruthData truth;
  truth.objects = {test::device("P", true, true)};
  test::place(truth, "P", Vec3(0, 0, 0));
  truth.los = std::vector<TruthLos>{{0.5, "B1", true}, {2.5, "B2", false}};
  const std::vector<std::string> lines = {
      estimate_line("spyloc", "", "world", "P", 1.0, {0.2, 0}),   // after the LoS beep
      estimate_line("spyloc", "", "world", "P", 3.0, {0.8, 0}),   // after the NLoS beep
      estimate_line("spyloc", "", "world", "P", 0.1, {0.4, 0}),   // before any beep: unflagged
  };
  const GroupResult g = evaluate(scene_of(truth, "spyloc"), test::parse_lines(lines), {}).groups.at(0);
  EXPECT_EQ(g.summary["los_estimates"], 1);
  EXPECT_EQ(g.summary["nlos_estimates"], 1);
  EXPECT_NEAR(sum_num(g.summary, "los_median_error_m"), 0.2, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "nlos_median_error_m"), 0.8, 1e-12);
}

// ------------------------------------------------------------------------------------ LocBLE
TEST(EvalLocble, PerTagFinalErrorWithTargetsGivenAsBleAddresses) {
  TruthData truth;
  truth.objects = {test::device("O", false, true)};
  for (auto [id, addr] : {std::pair{"tag1", "C4:2C:03:3A:2C:A1"}, std::pair{"tag2", "C4:2C:03:3A:2C:A2"}}) {
    TruthObject t;
    t.id = id;
    t.ble_addresses = {addr};
    truth.objects.push_back(t);
  }
  // Observer starts at (5,5) facing world +x (yaw −90°): frame x = world −y, y = world +x.
  truth.tracks["O"].add(TruthPose{0.0, Vec3(5, 5, 0), yaw(deg(-90))});
  truth.tracks["O"].add(TruthPose{10.0, Vec3(9, 5, 0), yaw(deg(-90))});
  test::place(truth, "tag1", Vec3(8, 3, 0));  // frame: (2, 3)
  test::place(truth, "tag2", Vec3(5, 9, 0));  // frame: (−4, 0)
  const std::vector<std::string> lines = {
      estimate_line("locble", "O", "observer_start", "c4:2c:03:3a:2c:a1", 5.0, {0, 0}),  // early, 3.6 m off
      estimate_line("locble", "O", "observer_start", "C4:2C:03:3A:2C:A1", 9.0, {2.5, 3}),  // final, 0.5 m off
      estimate_line("locble", "O", "observer_start", "tag2", 9.0, {-4, 1.5}),              // by id, 1.5 m off
  };
  const GroupResult g = evaluate(scene_of(truth, "locble"), test::parse_lines(lines), {}).groups.at(0);
  ASSERT_EQ(g.family, "locble");
  EXPECT_NEAR(row(g, "tag1")["final_error_m"].get<double>(), 0.5, 1e-12);
  EXPECT_NEAR(row(g, "tag2")["final_error_m"].get<double>(), 1.5, 1e-12);
  EXPECT_NEAR(sum_num(g.summary, "mean_error_m"), 1.0, 1e-12);  // mean of the per-tag final errors
  EXPECT_NEAR(sum_num(g.summary, "all_estimates_mean_error_m"), (std::hypot(2, 3) + 0.5 + 1.5) / 3, 1e-12);
  EXPECT_EQ(g.summary["targets_expected"], 2);
  EXPECT_NEAR(sum_num(g.summary, "located_fraction"), 1.0, 1e-12);
}

// ------------------------------------------------------------------------------------ Montage
TEST(EvalMontage, StrideErrorAgainstTruthSteps) {
  TruthData truth;
  truth.objects = {test::device("W1", true, true)};
  truth.tracks["W1"].add(TruthPose{0.0, Vec3(0, 0, 0), yaw(0)});
  truth.tracks["W1"].add(TruthPose{10.0, Vec3(7, 0, 0), yaw(0)});
  truth.clocks["W1"] = ClockModel{1.0, 0.0};  // local = true + 1
  std::vector<TruthStep> steps;
  for (int i = 1; i <= 10; ++i) steps.push_back({0.5 * i, "W1", 0.70});
  truth.steps = steps;
  std::vector<std::string> lines;
  for (int i = 1; i <= 10; ++i) {
    if (i == 4) continue;                                                // one missed step
    lines.push_back(test::step_line("W1", 1.0 + 0.5 * i + 0.05, i % 2 ? 0.75 : 0.64));  // 5-6 cm off, 50 ms late
  }
  lines.push_back(test::step_line("W1", 1.0 + 9.0, 0.7));  // an extra step far from any true one
  lines.push_back(estimate_line("montage", "W1", "W1_origin", "W1", 2.0, {0.7, 0.0}));
  const GroupResult g = evaluate(scene_of(truth, "montage"), test::parse_lines(lines), {}).groups.at(0);
  ASSERT_EQ(g.family, "montage");
  EXPECT_EQ(g.summary["steps_true"], 10);
  EXPECT_EQ(g.summary["steps_detected"], 10);
  EXPECT_EQ(g.summary["steps_matched"], 9);
  EXPECT_EQ(g.summary["steps_missed"], 1);
  EXPECT_EQ(g.summary["steps_extra"], 1);
  // Matched: i = 1,3,5,7,9 → 0.05; i = 2,6,8,10 → 0.06.
  EXPECT_NEAR(sum_num(g.summary, "mean_stride_error_m"), (5 * 0.05 + 4 * 0.06) / 9, 1e-9);
  EXPECT_NEAR(sum_num(g.summary, "max_stride_error_m"), 0.06, 1e-9);
  EXPECT_NEAR(sum_num(g.summary, "mean_error_m"), 0.0, 1e-9);  // estimate at true 1.0 s: (0.7, 0)
}

// ------------------------------------------------------------------------------------ input checks
TEST(EvalInput, UnknownFrameAndMissingReferenceAreBadInputNamingTheLine) {
  const TruthData truth = formation();
  try {
    evaluate(truth,
             test::parse_lines({estimate_line("p", "A", "world", "B", 1, {0, 0}), estimate_line("p", "A", "map", "B", 1, {0, 0}),
                                estimate_line("p", "", "A_start", "B", 1, {0, 0})}),
             {});
    FAIL();
  } catch (const InputError& e) {
    ASSERT_EQ(e.messages().size(), 2u);
    EXPECT_NE(e.messages()[0].find("est.jsonl:2: frame 'map' is unknown"), std::string::npos) << e.messages()[0];
    EXPECT_NE(e.messages()[1].find("est.jsonl:3: frame 'A_start' is tied to a device but 'reference' is empty"),
              std::string::npos) << e.messages()[1];
  }
}

TEST(EvalInput, PluginFilterAndForcedMetric) {
  const TruthData truth = formation();
  const auto file = test::parse_lines({estimate_line("one", "", "world", "B", 1, {3, 0}), estimate_line("two", "", "world", "C", 1, {0, 3})});
  EvalOptions o;
  o.plugins = {"two", "three"};
  o.metric = "spyloc";
  const EvalResult r = evaluate(truth, file, o);
  ASSERT_EQ(r.groups.size(), 1u);
  EXPECT_EQ(r.groups[0].plugin, "two");
  EXPECT_EQ(r.groups[0].family, "spyloc");
  EXPECT_NEAR(sum_num(r.groups[0].summary, "mean_error_m"), std::hypot(0.0, 1.0), 1e-12);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("plugin 'three'"), std::string::npos);
}

}  // namespace
}  // namespace locus::eval
