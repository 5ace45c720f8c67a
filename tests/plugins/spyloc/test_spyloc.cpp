// spyloc: trilateration with a known answer (and the mirror of collinear beacons), the EKF converging
// on a walk from single ranges, the naive-Bayes GMM separating two known distributions and
// round-tripping its model file, the plugin end to end on synthetic sync/beep events (NLoS beeps kept
// out, lost syncs skipped), and clear errors on bad setups and model files.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "locus/events.hpp"
#include "locus/fftw_planner.hpp"
#include "spyloc/classifier.hpp"
#include "spyloc/solver.hpp"
#include "spyloc/spyloc.hpp"
#include "spyloc/tracker.hpp"
#include "support/spyloc_beacons.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

using namespace plugins::spyloc;

TEST(SpyLocSolver, TrilaterationKnownAnswer) {
  const std::vector<std::array<double, 3>> b = {{1.5, 1.5, 2.5}, {22.5, 1.5, 2.5}, {12.0, 14.5, 2.5}};
  const std::array<double, 2> truth = {7.3, 5.9};
  std::vector<RangeObs> obs;
  for (const auto& p : b) {
    RangeObs o;
    o.beacon_m = p;
    o.range_m = std::sqrt(std::pow(truth[0] - p[0], 2) + std::pow(truth[1] - p[1], 2) + std::pow(1.2 - p[2], 2));
    o.std_m = 0.05;
    obs.push_back(o);
  }
  const auto fixes = trilaterate(obs, 1.2);
  ASSERT_FALSE(fixes.empty());
  EXPECT_NEAR(fixes[0].xy_m[0], truth[0], 1e-6);
  EXPECT_NEAR(fixes[0].xy_m[1], truth[1], 1e-6);
  EXPECT_LT(fixes[0].rms_residual_m, 1e-6);
  // Collinear beacons (along y = 1.5): the mirror across their line fits as well, both are returned.
  std::vector<RangeObs> line = obs;
  line[2].beacon_m = {12.0, 1.5, 2.5};
  line[2].range_m = std::sqrt(std::pow(truth[0] - 12.0, 2) + std::pow(truth[1] - 1.5, 2) + std::pow(1.2 - 2.5, 2));
  const auto two = trilaterate(line, 1.2);
  ASSERT_EQ(two.size(), 2u);
  for (const Fix& f : two) {
    EXPECT_NEAR(f.xy_m[0], truth[0], 1e-4);
    EXPECT_NEAR(std::fabs(f.xy_m[1] - 1.5), truth[1] - 1.5, 1e-4);
  }
  EXPECT_TRUE(trilaterate({obs[0], obs[1]}, 1.2).empty());
}

TEST(SpyLocTracker, SingleRangesKeepAWalkOnTrack) {
  const std::vector<std::array<double, 3>> b = {{1.5, 1.5, 2.5}, {22.5, 1.5, 2.5}, {12.0, 14.5, 2.5}};
  Tracker t;
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 0.05);
  auto pos = [](double s) { return std::array<double, 2>{4.0 + 1.2 * s, 4.0 + 0.3 * s}; };
  t.init(0.0, {4.5, 3.6}, {0.5, 0.0, 0.5}, 1.5);
  double worst_late = 0.0;
  for (int k = 1; k < 40; ++k) {
    const double ts = 0.33 * k;
    const auto p = pos(ts);
    const auto& bk = b[static_cast<std::size_t>(k % 3)];
    const double r = std::sqrt(std::pow(p[0] - bk[0], 2) + std::pow(p[1] - bk[1], 2) + std::pow(1.2 - bk[2], 2)) + n(rng);
    t.predict(ts);
    double nis = 0.0;
    EXPECT_TRUE(t.update_range(bk, 1.2, r, 0.05, nis)) << k;
    const auto e = t.position();
    if (k > 15) worst_late = std::max(worst_late, std::hypot(e[0] - p[0], e[1] - p[1]));
  }
  EXPECT_LT(worst_late, 0.25);
  // A range 5 m too long (a missed NLoS beep) is gated out, the state unchanged.
  double nis = 0.0;
  t.predict(0.33 * 40 + 0.01);
  const auto before = t.position();
  const auto p = pos(0.33 * 40 + 0.01);
  const double r = std::sqrt(std::pow(p[0] - b[0][0], 2) + std::pow(p[1] - b[0][1], 2) + std::pow(1.2 - 2.5, 2));
  EXPECT_FALSE(t.update_range(b[0], 1.2, r + 5.0, 0.05, nis));
  EXPECT_GT(nis, 16.0);
  EXPECT_EQ(t.position()[0], before[0]);
  EXPECT_EQ(t.position()[1], before[1]);
}

TEST(SpyLocClassifier, SeparatesKnownClassesAndRoundTripsItsFile) {
  std::mt19937 rng(5);
  auto make = [&](double t10, double spread, std::size_t n, double nan_frac) {
    std::vector<DecayVector> out;
    std::normal_distribution<double> g(0.0, spread);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (std::size_t i = 0; i < n; ++i) {
      DecayVector v;
      for (std::size_t k = 0; k < kDecayFeatures; ++k) {
        const double base = t10 * (static_cast<double>(k) + 0.5);
        v[k] = u(rng) < nan_frac * static_cast<double>(k) / 5.0 ? NAN : static_cast<float>(base + g(rng));
      }
      out.push_back(v);
    }
    return out;
  };
  const auto los = make(0.004, 0.003, 200, 0.3), nlos = make(0.04, 0.01, 60, 0.8);
  LosClassifier c;
  c.train(los, nlos, 4);
  const auto los_t = make(0.004, 0.003, 100, 0.3), nlos_t = make(0.04, 0.01, 100, 0.8);
  int ok = 0;
  for (const auto& v : los_t) ok += c.p_los(v) >= 0.5;
  for (const auto& v : nlos_t) ok += c.p_los(v) < 0.5;
  EXPECT_GE(ok, 196) << "held-out accuracy " << ok / 2.0 << " %";
  const std::string path = (std::filesystem::temp_directory_path() / "locus_spyloc_model_test.yaml").string();
  c.save(path, "test");
  LosClassifier d;
  d.load(path);
  for (const auto& v : los_t) EXPECT_NEAR(d.p_los(v), c.p_los(v), 1e-6);
  EXPECT_EQ(d.trained_los(), 200u);
  // Bad files name the field.
  {
    std::ofstream f(path);
    f << "format: locus-spyloc-los/1\ncensor_s: 0.2\nprior_los: 1.5\n";
  }
  try {
    d.load(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("prior_los"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
  try {
    d.load(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot read"), std::string::npos) << e.what();
  }
  const double p_before = c.p_los(nlos_t[0]);
  EXPECT_THROW(c.train(los, make(0.04, 0.01, 5, 0.0), 4), std::invalid_argument);
  EXPECT_EQ(c.p_los(nlos_t[0]), p_before) << "a refused training changed the model";
  // Malformed texts (what a fuzzer or a hand edit makes): a clear error naming the field, nothing
  // else escaping (a scalar `trained_on` once leaked yaml-cpp's own exception).
  const std::string good = [&] {
    LosClassifier fresh;
    fresh.train(los, nlos, 4);
    fresh.save(path, "test");
    std::ifstream f(path);
    std::stringstream ss;
    ss << f.rdbuf();
    std::filesystem::remove(path);
    return ss.str();
  }();
  LosClassifier e;
  EXPECT_NO_THROW(e.load_text(good, "m.yaml"));
  const std::vector<std::pair<std::string, std::string>> bad = {
      {good.substr(0, good.find("trained_on")) + "trained_on: 7\n" + good.substr(good.find("los:\n")), "field 'trained_on'"},
      {"[", "m.yaml': not YAML"},
      {"", "field '(top)'"},
      {"format: locus-spyloc-los/2\n", "field 'format'"},
  };
  for (const auto& [text, want] : bad) {
    try {
      e.load_text(text, "m.yaml");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const std::runtime_error& err) {
      EXPECT_NE(std::string(err.what()).find(want), std::string::npos) << err.what();
    }
    EXPECT_TRUE(e.ready()) << "a refused file changed the loaded model";
    EXPECT_EQ(e.trained_los(), 200u);
  }
}

// `los_model: builtin` is config/spyloc-los.yaml as built: the same model from any working directory.
TEST(SpyLocClassifier, BuiltinIsTheShippedModelFile) {
  LosClassifier builtin;
  builtin.load_text(LosClassifier::builtin_text(), "builtin");
  ASSERT_TRUE(builtin.ready());
  LosClassifier file;
  file.load(std::string(LOCUS_SOURCE_DIR) + "/config/spyloc-los.yaml");
  EXPECT_EQ(builtin.trained_los(), file.trained_los());
  EXPECT_GT(builtin.trained_los(), 0u);
}

// Huber range update: a range 3.5 sigmas short (inside the 4-sigma gate: an early spurious path) is
// taken with the variance that puts it at 2 sigmas, so it moves the state (2 / 3.5)² as far as the
// plain EKF update; the likelihood still sees all of it; a range within 2 sigmas updates exactly as
// the plain EKF.
TEST(SpyLocPdrTracker, HuberBoundsWhatOneOutlierRangeMoves) {
  const auto run = [](double huber, double sigmas, double& nis) {
    PdrConfig c;
    c.huber_sigma = huber;
    PdrTracker t(c);
    t.init({5.0, 4.0}, {0.04, 0.0, 0.04}, 0.3, 0.25, 1.0, 0.1);
    t.step({1.0, 0.0});
    const std::array<double, 3> beacon{1.5, 1.5, 1.0};
    const auto p = t.position();
    const double predicted = std::hypot(p[0] - beacon[0], p[1] - beacon[1]);
    // The innovation's sigma: the predicted range's variance from the state plus the range's.
    t.update_range(beacon, 1.0, predicted, 0.1, nis);
    const double s = std::sqrt(t.last_innovation_var());
    PdrTracker u(c);
    u.init({5.0, 4.0}, {0.04, 0.0, 0.04}, 0.3, 0.25, 1.0, 0.1);
    u.step({1.0, 0.0});
    EXPECT_TRUE(u.update_range(beacon, 1.0, predicted - sigmas * s, 0.1, nis));
    const auto q = u.position();
    return std::array<double, 2>{std::hypot(q[0] - p[0], q[1] - p[1]), std::abs(u.psi_rad() - 0.3)};
  };
  double nis_plain = 0.0, nis_huber = 0.0;
  const auto plain = run(0.0, 3.5, nis_plain), huber = run(2.0, 3.5, nis_huber);
  EXPECT_NEAR(nis_plain, 3.5 * 3.5, 0.01);
  EXPECT_NEAR(nis_huber, nis_plain, 1e-9) << "the likelihood must see the whole innovation";
  EXPECT_NEAR(huber[0], plain[0] * (2.0 / 3.5) * (2.0 / 3.5), 1e-6);
  EXPECT_LT(huber[1], plain[1]);
  double n1 = 0.0, n2 = 0.0;
  const auto small_plain = run(0.0, 1.5, n1), small_huber = run(2.0, 1.5, n2);
  EXPECT_DOUBLE_EQ(small_plain[0], small_huber[0]);
}

// The dead-reckoning tracker learns the heading offset and the stride scale from single ranges: the
// steps come in a frame rotated by 0.7 rad with strides 1/0.9 too long; it starts 0.25 rad and 10 %
// off, walks an L with one range per step, and ends with both within a few percent, the position
// within 0.15 m; standing still (no step), the position holds.
TEST(SpyLocPdrTracker, StepsAndSingleRangesLearnHeadingAndStride) {
  const std::vector<std::array<double, 3>> b = {{1.5, 1.5, 2.5}, {22.5, 1.5, 2.5}, {12.0, 14.5, 2.5}};
  const double psi = 0.7, k = 0.9;
  PdrTracker t;
  t.init({4.0, 4.0}, {0.04, 0.0, 0.04}, psi - 0.25, 0.3, 1.0, 0.15);
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 0.05);
  std::array<double, 2> w{4.0, 4.0};
  for (int i = 0; i < 50; ++i) {
    const double phi = i < 25 ? 0.0 : M_PI / 2;  // east, then north
    const double stride = 0.66;
    w = {w[0] + stride * std::cos(phi), w[1] + stride * std::sin(phi)};
    // The same step in the dead-reckoning frame: R(-psi), stride / k.
    const double c = std::cos(-psi), sn = std::sin(-psi), sx = stride / k * std::cos(phi), sy = stride / k * std::sin(phi);
    t.step({c * sx - sn * sy, sn * sx + c * sy});
    const auto& bk = b[static_cast<std::size_t>(i % 3)];
    const double r = std::sqrt(std::pow(w[0] - bk[0], 2) + std::pow(w[1] - bk[1], 2) + std::pow(1.2 - bk[2], 2)) + n(rng);
    double nis = 0.0;
    EXPECT_TRUE(t.update_range(bk, 1.2, r, 0.05, nis)) << i;
  }
  EXPECT_NEAR(t.psi_rad(), psi, 0.04);
  EXPECT_NEAR(t.stride_scale(), k, 0.04);
  EXPECT_LT(std::hypot(t.position()[0] - w[0], t.position()[1] - w[1]), 0.15);
  const auto held = t.position();
  t.step({0.0, 0.0});
  EXPECT_EQ(t.position()[0], held[0]);
  EXPECT_EQ(t.position()[1], held[1]);
}

struct Pub : Publisher {
  std::vector<Estimate> est;
  std::vector<Step> steps;  ///< the steps the localizer publishes again (stride scaled by what it learnt)
  void publish(const Event& e) override {
    if (const auto* x = std::get_if<Estimate>(&e)) est.push_back(*x);
    if (const auto* x = std::get_if<Step>(&e)) steps.push_back(*x);
  }
};

/// Decay features growing by scale_s per 5 dB (T5 = scale, T10 = 2·scale, ...).
DecayVector decay_of(double scale_s) {
  DecayVector v{};
  for (std::size_t q = 0; q < kDecayFeatures; ++q) v[q] = static_cast<float>(scale_s * (q + 1));
  return v;
}

/// A classifier that knows short decays (3 ms per 5 dB) = LoS and long ones (30 ms) = NLoS, 40 beeps
/// of each with feature noise noise_sd_s, written to a temporary model file (returned).
std::string two_class_model(double noise_sd_s, const std::string& name, LosClassifier& c) {
  std::vector<DecayVector> los(40), nlos(40);
  std::mt19937 rng(9);
  std::normal_distribution<double> nz(0.0, noise_sd_s);
  for (auto& v : los)
    for (std::size_t k = 0; k < kDecayFeatures; ++k) v[k] = static_cast<float>(0.003 * (k + 1) + nz(rng));
  for (auto& v : nlos)
    for (std::size_t k = 0; k < kDecayFeatures; ++k) v[k] = static_cast<float>(0.03 * (k + 1) + nz(rng));
  c.train(los, nlos, 2);
  const std::string model = (std::filesystem::temp_directory_path() / name).string();
  c.save(model, "test");
  return model;
}

/// One beep of beacon i as the localizer receives it: its radio sync at t (unless lost), the
/// detection at t + 50 ms + range/c, then its decay features.
void send_beep(Localizer& loc, Pub& out, const test::SpyLocBeacons& beacons, int i, double t, double range_m,
               bool sync_heard, const DecayVector& decay) {
  if (sync_heard) {
    RadioSync s;
    s.device = DeviceId("W");
    s.t_s = t;
    s.source = NameTag("B" + std::to_string(i + 1));
    loc.on_event(Event{s}, out);
  }
  AudioDetection d;
  d.device = DeviceId("W");
  d.sample_rate_hz = 44100.0;
  d.frame = (t + 0.05 + range_m / 343.0) * 44100.0;
  d.template_index = beacons.mask(static_cast<std::size_t>(i));
  loc.on_event(Event{d}, out);
  DecayFeatures f;
  f.device = d.device;
  f.frame = d.frame;
  f.decay_s = decay;
  loc.on_event(Event{f}, out);
}

/// The plugin tests' world: a test host, an FFT planner, three beacons and the host context made of them.
class SpyLocPlugin : public ::testing::Test {
 protected:
  test::TestHost host;
  FftwPlanner fftw{{}, false};
  const test::SpyLocBeacons beacons;
  HostContext ctx{host.log, host.clock, fftw, host.link, "spyloc", "W", &beacons.geometry};
};

// Three beacons, a walker on a line; each beep: sync at t, beep at t + delay + r/c (+ 3 m for the
// NLoS ones, which carry long decay features), some syncs lost.
TEST_F(SpyLocPlugin, EndToEndOnSyntheticEvents) {
  const auto& b = beacons.anchors_m;
  LosClassifier c;
  const std::string model = two_class_model(0.002, "locus_spyloc_plugin_model.yaml", c);

  std::unique_ptr<Localizer> loc(descriptor()->create_localizer());
  Params p = Params::defaults(schema());
  p.set("los_model", model);
  p.set("speed_of_sound_mps", 343.0);
  loc->configure(p, ctx);
  Pub out;
  std::vector<double> errs;
  for (int k = 0; k < 120; ++k) {
    const double t = 0.5 + 0.333 * k;
    const int i = k % 3;
    const std::array<double, 2> w = {4.0 + 0.4 * t, 4.0 + 0.1 * t};
    const double r = std::sqrt(std::pow(w[0] - b[i][0], 2) + std::pow(w[1] - b[i][1], 2) + std::pow(1.2 - b[i][2], 2));
    const bool nlos_beep = k % 7 == 3, lost = k % 11 == 5;
    const std::size_t before = out.est.size();
    send_beep(*loc, out, beacons, i, t, r + (nlos_beep ? 3.0 : 0.0), !lost, decay_of(nlos_beep ? 0.03 : 0.003));
    if (out.est.size() > before) {
      const Estimate& e = out.est.back();
      EXPECT_EQ(e.los, nlos_beep ? 0 : 1) << k;
      const double tt = t + 0.05 + (r + (nlos_beep ? 3.0 : 0.0)) / 343.0;
      const std::array<double, 2> wt = {4.0 + 0.4 * (tt - 0.05 - r / 343.0), 4.0 + 0.1 * (tt - 0.05 - r / 343.0)};
      if (k > 20) errs.push_back(std::hypot(e.position_m[0] - wt[0], e.position_m[1] - wt[1]));
    }
  }
  loc->finish(out);
  std::filesystem::remove(model);
  ASSERT_GT(errs.size(), 60u);
  std::sort(errs.begin(), errs.end());
  const double p90 = errs[errs.size() * 9 / 10];
  std::printf("synthetic walk: %zu estimates scored, p90 error %.3f m\n", errs.size(), p90);
  EXPECT_LT(p90, 0.15);
}

// The published LoS/NLoS verdict weighs the decay's by the track (fuse_los): on a settled track, LoS
// beeps whose decay looks NLoS are cleared (their ranges agree with the track) and NLoS beeps whose
// decay looks LoS (3 m too long) are called NLoS. With nlos_excess_max_m 0 (the decay alone) the
// first kind stays NLoS; the second is still NLoS (gated out as too long).
TEST_F(SpyLocPlugin, TheTrackCorrectsTheDecayVerdict) {
  const auto& b = beacons.anchors_m;
  LosClassifier c;  // overlapping classes: P(LoS) varies smoothly between them
  const std::string model = two_class_model(0.01, "locus_spyloc_verdict_model.yaml", c);
  // A decay between the classes that the model calls NLoS, but not beyond doubt (5-50 % LoS): what the
  // real classifier says of a far LoS beep's long tail.
  double misread_scale = 0.0;
  for (double sc = 0.003; sc < 0.03 && misread_scale == 0.0; sc += 0.0001) {
    const double pl = c.p_los(decay_of(sc));
    if (pl < 0.5 && pl > 0.05) misread_scale = sc;
  }
  ASSERT_GT(misread_scale, 0.0);
  std::printf("decay scale %.5f s: P(LoS) %.3f from the decay\n", misread_scale, c.p_los(decay_of(misread_scale)));
  struct Counts {
    int misread_los = 0, misread_los_cleared = 0, misread_nlos = 0, misread_nlos_caught = 0;
  };
  auto run = [&](double excess_max_m) {
    std::unique_ptr<Localizer> loc(descriptor()->create_localizer());
    Params p = Params::defaults(schema());
    p.set("los_model", model);
    p.set("speed_of_sound_mps", 343.0);
    p.set("nlos_excess_max_m", excess_max_m);
    loc->configure(p, ctx);
    Pub out;
    Counts n;
    for (int k = 0; k < 120; ++k) {
      const double t = 0.5 + 0.333 * k;
      const int i = k % 3;
      const std::array<double, 2> w = {4.0 + 0.2 * t, 4.0 + 0.05 * t};
      const double r = std::sqrt(std::pow(w[0] - b[i][0], 2) + std::pow(w[1] - b[i][1], 2) + std::pow(1.2 - b[i][2], 2));
      // After the track settles: every 5th beep a LoS one that decays like NLoS, every 7th an NLoS
      // one (3 m long) that decays like LoS.
      const bool misread_los = k > 20 && k % 5 == 2, misread_nlos = k > 20 && k % 7 == 3 && !misread_los;
      const std::size_t before = out.est.size();
      send_beep(*loc, out, beacons, i, t, r + (misread_nlos ? 3.0 : 0.0), true,
                decay_of(misread_los ? misread_scale : 0.003));
      if (out.est.size() == before) continue;
      const Estimate& e = out.est.back();
      if (misread_los) {
        ++n.misread_los;
        n.misread_los_cleared += e.los == 1;
      }
      if (misread_nlos) {
        ++n.misread_nlos;
        n.misread_nlos_caught += e.los == 0;
      }
    }
    loc->finish(out);
    return n;
  };
  const Counts fused = run(8.0), decay_only = run(0.0);
  std::filesystem::remove(model);
  std::printf("LoS beeps misread as NLoS: %d/%d cleared by the track (%d/%d by the decay alone); NLoS misread as LoS: "
              "%d/%d caught (%d/%d)\n",
              fused.misread_los_cleared, fused.misread_los, decay_only.misread_los_cleared, decay_only.misread_los,
              fused.misread_nlos_caught, fused.misread_nlos, decay_only.misread_nlos_caught, decay_only.misread_nlos);
  ASSERT_GE(fused.misread_los, 15);
  ASSERT_GE(fused.misread_nlos, 10);
  EXPECT_EQ(fused.misread_los_cleared, fused.misread_los);
  EXPECT_EQ(fused.misread_nlos_caught, fused.misread_nlos);
  EXPECT_EQ(decay_only.misread_los_cleared, 0);
  EXPECT_EQ(decay_only.misread_nlos_caught, decay_only.misread_nlos);
}

TEST(SpyLocClassifier, FuseLosWeighsTheInnovation) {
  // On the track (ν = 0, σ 0.2 m): a beep the decay gives 20 % becomes LoS.
  EXPECT_GT(fuse_los(0.2, 0.0, 0.2, 8.0), 0.7);
  // 3 m longer than the track predicts: NLoS even at 95 % from the decay.
  EXPECT_LT(fuse_los(0.95, 3.0, 0.2, 8.0), 0.01);
  // Beyond the largest NLoS excess, or far shorter than predicted: neither class explains it; the
  // decay's answer stands.
  EXPECT_DOUBLE_EQ(fuse_los(0.3, -60.0, 0.2, 8.0), 0.3);
  // A vague track says little: ν = 0 with σ 5 m moves 20 % by less than a factor 2 of the odds.
  const double vague = fuse_los(0.2, 0.0, 5.0, 8.0);
  EXPECT_GT(vague, 0.2);
  EXPECT_LT(vague / (1 - vague), 2.0 * 0.25);
  // Off: the decay's alone.
  EXPECT_DOUBLE_EQ(fuse_los(0.2, 0.0, 0.2, 0.0), 0.2);
  EXPECT_DOUBLE_EQ(fuse_los(0.2, std::nan(""), 0.2, 8.0), 0.2);
  // Monotone: the longer the range against the track, the less LoS.
  double prev = 1.0;
  for (double nu = 0.0; nu <= 4.0; nu += 0.25) {
    const double p = fuse_los(0.5, nu, 0.3, 8.0);
    EXPECT_LE(p, prev + 1e-12) << nu;
    prev = p;
  }
}

// The decay's odds tempered: a burst over a beep's tail drives the naive-Bayes P(LoS) of a LoS beep to
// 1e-4 and below; on the track (ν = 0, σ 0.2 m: likelihood ratio ~32) the untempered verdict stays
// NLoS, the tempered one (0.3: odds 0.06) is LoS; a range 3 m long stays NLoS either way; 0.5 and
// the sign of the log-odds are kept.
TEST(SpyLocClassifier, TemperedDecayOddsLetTheTrackAnswer) {
  EXPECT_DOUBLE_EQ(temper_los(0.2, 1.0), 0.2);
  EXPECT_NEAR(temper_los(0.5, 0.3), 0.5, 1e-12);
  EXPECT_LT(temper_los(0.2, 0.3), 0.5);
  EXPECT_GT(temper_los(0.2, 0.3), 0.2);
  EXPECT_GT(temper_los(0.9, 0.3), 0.5);
  EXPECT_LT(temper_los(0.9, 0.3), 0.9);
  const double p = 1e-4;
  EXPECT_LT(fuse_los(p, 0.0, 0.2, 8.0), 0.5);
  EXPECT_GT(fuse_los(temper_los(p, 0.3), 0.0, 0.2, 8.0), 0.5);
  EXPECT_LT(fuse_los(temper_los(p, 0.3), 3.0, 0.2, 8.0), 0.01);
}

// Dead reckoning in the plugin: three beacons heard for 8 s, then only one for 22 s while the walker
// turns twice. The steps (in a frame rotated by an unknown 0.7 rad, strides 10 % long) carry the
// track through the turns; the constant-velocity tracker (dead_reckoning: false, same events) cannot.
TEST_F(SpyLocPlugin, DeadReckoningCarriesTheTrackOnOneBeacon) {
  const auto& b = beacons.anchors_m;
  // The walk: 1.2 m/s east for 10 s, north for 10 s, west for 10 s; a step every 0.55 s.
  auto phi_at = [](double t) { return t < 10.0 ? 0.0 : t < 20.0 ? M_PI / 2 : M_PI; };
  auto pos_at = [](double t) {
    const double a = std::min(t, 10.0), n = std::clamp(t - 10.0, 0.0, 10.0), w = std::clamp(t - 20.0, 0.0, 10.0);
    return std::array<double, 2>{5.0 + 1.2 * a - 1.2 * w, 3.0 + 1.2 * n};
  };
  const double psi = 0.7, stride_bias = 1.1;
  auto run = [&](bool dead_reckoning, std::vector<Step>* steps_out = nullptr) {
    std::unique_ptr<Localizer> loc(descriptor()->create_localizer());
    Params p = Params::defaults(schema());
    p.set("speed_of_sound_mps", 343.0);
    p.set("dead_reckoning", dead_reckoning);
    loc->configure(p, ctx);
    Pub out;
    std::vector<double> late;
    double next_att = 0.0, next_step = 0.55, next_beep = 0.2;
    int beep = 0;
    for (double t = 0.0; t < 30.0; t += 0.01) {
      if (t >= next_att) {  // relative heading: h = phi + pi/2 - psi (docs: step direction (-sin h, cos h))
        Attitude a;
        a.device = DeviceId("W");
        a.t_s = t;
        a.heading_rad = static_cast<float>(phi_at(t) + M_PI / 2 - psi);
        loc->on_event(Event{a}, out);
        next_att += 0.05;
      }
      if (t >= next_step) {
        Step st;
        st.device = DeviceId("W");
        st.t_s = t;
        st.stride_m = static_cast<float>(0.66 * stride_bias);
        st.frequency_hz = 1.0f / 0.55f;
        loc->on_event(Event{st}, out);
        next_step += 0.55;
      }
      if (t >= next_beep) {
        const int i = t < 8.0 ? beep % 3 : 0;
        ++beep;
        next_beep += 0.333;
        const auto w = pos_at(t);
        const double r = std::sqrt(std::pow(w[0] - b[i][0], 2) + std::pow(w[1] - b[i][1], 2) + std::pow(1.2 - b[i][2], 2));
        send_beep(*loc, out, beacons, i, t, r, true, DecayFeatures{}.decay_s);  // no decay: no model, all LoS
      }
    }
    loc->finish(out);
    for (const Estimate& e : out.est) {
      if (e.t_s < 9.0) continue;
      const auto w = pos_at(e.t_s);
      late.push_back(std::hypot(e.position_m[0] - w[0], e.position_m[1] - w[1]));
    }
    std::sort(late.begin(), late.end());
    if (steps_out) *steps_out = out.steps;
    return late;
  };
  std::vector<Step> published;
  const auto pdr = run(true, &published), cv = run(false);
  ASSERT_GT(pdr.size(), 50u);
  ASSERT_GT(cv.size(), 50u);
  const double pdr_p90 = pdr[pdr.size() * 9 / 10], cv_p90 = cv[cv.size() * 9 / 10];
  std::printf("one beacon for 22 s, two turns: p90 error %.2f m with dead reckoning, %.2f m without\n", pdr_p90, cv_p90);
  EXPECT_LT(pdr_p90, 0.5);
  EXPECT_LT(pdr_p90, 0.5 * cv_p90);
  // The steps published again: the detector's stride (10 % long) until ranging has learnt the scale k
  // (its std <= stride_scale_max_std), then scaled to the true 0.66 m.
  ASSERT_GT(published.size(), 40u);
  EXPECT_FLOAT_EQ(published.front().stride_m, static_cast<float>(0.66 * stride_bias));
  for (std::size_t i = published.size() - 10; i < published.size(); ++i) EXPECT_NEAR(published[i].stride_m, 0.66, 0.02) << i;
}

TEST_F(SpyLocPlugin, BadSetupsAreClearErrors) {
  auto configure = [&](const DeviceGeometry* g, const Params& p) {
    std::unique_ptr<Localizer> loc(descriptor()->create_localizer());
    HostContext ctx{host.log, host.clock, fftw, host.link, "spyloc", "W", g};
    loc->configure(p, ctx);
  };
  const Params p = Params::defaults(schema());
  auto expect_error = [&](const DeviceGeometry* g, const Params& q, const std::string& needle) {
    try {
      configure(g, q);
      ADD_FAILURE() << "no error, expected one mentioning " << needle;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error(nullptr, p, "no scene geometry");
  std::vector<SceneSignal> scene(3);
  for (int i = 0; i < 3; ++i) {
    scene[static_cast<std::size_t>(i)].id = "B" + std::to_string(i);
    scene[static_cast<std::size_t>(i)].signal.type = "multitone";
    scene[static_cast<std::size_t>(i)].signal.tones_hz = {18000.0 + 250.0 * i};
    scene[static_cast<std::size_t>(i)].has_anchor = true;
  }
  DeviceGeometry g;
  g.scene_emits = scene;
  expect_error(&g, p, "sync_delay_s");
  for (auto& s : scene) s.signal.sync_delay_s = 0.05;
  scene[2].signal.tones_hz = {17000.0};
  g.scene_emits = scene;
  expect_error(&g, p, "not in the tone grid");
  scene[2].signal.tones_hz = {18000.0};
  g.scene_emits = scene;
  expect_error(&g, p, "same tone set");
  scene[2].signal.tones_hz = {18750.0};
  g.scene_emits = scene;
  Params q = p;
  q.set("los_model", std::string("/nonexistent/model.yaml"));
  expect_error(&g, q, "los_model");
  Params r = p;
  r.set("region_m", std::vector<double>{0.0, 0.0, -1.0, 5.0});
  expect_error(&g, r, "region_m");
  scene.pop_back();
  g.scene_emits = scene;
  expect_error(&g, p, "at least 3");
}

}  // namespace
}  // namespace locus
