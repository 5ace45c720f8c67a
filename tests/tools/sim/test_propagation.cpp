// Physics properties of the renderer: exact fractional delays, the clock model, Doppler from motion,
// image-source reflections, obstruction, self-recording.
#include <gtest/gtest.h>

#include <cmath>

#include "sim_test_util.hpp"

namespace locus::sim {
namespace {

using test::emitter;
using test::fit_arrival_frame;
using test::listener;
using test::quiet_simulation;
using test::test_chirp;

constexpr double kRateHz = 44100.0;

// Static pair, skewed and offset receiver clock: every rendered sample equals the analytic delayed
// signal, and the fitted arrival lies at fs·local_from_true(te0 + r/c) within 0.05 samples.
TEST(SimPropagation, StaticPairMatchesAnalyticDelayAndClockModel) {
  Simulation s = quiet_simulation(25.0);
  const Eigen::Vector3d src(1.0, 2.0, 1.5), rx(3.7, 0.4, 0.9);
  const scene::ClockTruth clock{1.37, 47.0};
  s.devices.push_back(listener("R", rx, clock));
  const auto sig = test_chirp();
  s.emitters.push_back(emitter("E", std::make_shared<StaticTrajectory>(src), sig));
  const double te0 = 20.123456;  // late, so the 47 ppm skew matters (~0.95 ms = 42 samples)
  s.emissions.push_back(Emission{"E", 0, te0, 0.0});
  SceneSimulator sim(s);

  const double c = s.acoustics.speed_of_sound_mps, r = (rx - src).norm();
  const double t_arr = te0 + r / c;
  const double expected_frame = clock.local_from_true(t_arr) * kRateHz;
  const auto first = static_cast<std::uint64_t>(expected_frame) - 200;
  const auto audio = sim.render_audio("R", first, 2400);
  ASSERT_EQ(audio.size(), 1u);

  // sample by sample against the closed form
  const dsp::SignalEvaluator ev(sig, kRateHz);
  double max_err = 0.0, peak = 0.0;
  for (std::size_t i = 0; i < audio[0].size(); ++i) {
    const double t = clock.true_from_local(static_cast<double>(first + i) / kRateHz);
    const double want = s.acoustics.level_at_1m / r * ev.value(t - r / c - te0);
    max_err = std::max(max_err, std::abs(want - audio[0][i]));
    peak = std::max(peak, std::abs(want));
  }
  EXPECT_GT(peak, 0.01);
  EXPECT_LT(max_err, 1e-6 * 10);  // float rounding only

  std::vector<float> x(static_cast<std::size_t>(first), 0.0f);
  x.insert(x.end(), audio[0].begin(), audio[0].end());
  const double fitted = fit_arrival_frame(x, sig, kRateHz, expected_frame, 3.0, 1.0 + clock.skew_ppm * 1e-6);
  EXPECT_NEAR(fitted, expected_frame, 0.05);
  // and the skew matters: ignoring it would be ~40 samples off
  EXPECT_GT(std::abs((t_arr + clock.offset_s) * kRateHz - expected_frame), 30.0);
}

// A source moving at constant speed towards a static receiver: the received tone frequency is
// f·c/(c − v) in true time, divided by (1 + skew) on the receiver's sample grid.
TEST(SimPropagation, MovingSourceGivesDoppler) {
  for (double v : {6.0, -6.0}) {
    Simulation s = quiet_simulation(3.0);
    const scene::ClockTruth clock{0.2, -30.0};
    s.devices.push_back(listener("R", {0.0, 0.0, 1.0}, clock));
    dsp::SignalSpec tone;
    tone.type = "multitone";
    tone.tones_hz = {3000.0};
    tone.duration_s = 1.0;
    tone.fade_s = 0.01;
    // moving along +x towards the receiver at x=0 from x = −10 (v > 0 approaches)
    auto tr = std::make_shared<FunctionTrajectory>(
        [v](double t) { return Pose{Eigen::Vector3d(-10.0 + v * (t - 1.0), 0.0, 1.0), Eigen::Quaterniond::Identity()}; },
        std::abs(v));
    s.emitters.push_back(emitter("E", tr, tone));
    s.emissions.push_back(Emission{"E", 0, 1.0, 0.0});
    SceneSimulator sim(s);
    const auto audio = sim.render_audio("R", 0, static_cast<std::size_t>(3.0 * kRateHz));
    // zero crossings with linear interpolation over the middle of the received tone
    const auto& x = audio[0];
    const double c = s.acoustics.speed_of_sound_mps;
    const double arrive = (1.0 + 10.0 / c + 0.1) + clock.offset_s;  // well inside the tone (local s)
    const auto k0 = static_cast<std::size_t>(arrive * kRateHz), k1 = k0 + static_cast<std::size_t>(0.6 * kRateHz);
    double first = -1, last = -1;
    int crossings = 0;
    for (std::size_t k = k0; k < k1; ++k) {
      if (x[k] < 0 && x[k + 1] >= 0) {
        const double frac = x[k] / (x[k] - x[k + 1]);
        const double at = static_cast<double>(k) + frac;
        if (first < 0) first = at;
        last = at;
        ++crossings;
      }
    }
    ASSERT_GT(crossings, 100);
    const double f_local = (crossings - 1) / ((last - first) / kRateHz);
    const double f_expected = 3000.0 * c / (c - v) / (1.0 + clock.skew_ppm * 1e-6);
    EXPECT_NEAR(f_local, f_expected, 0.05) << "v=" << v;
    EXPECT_GT(std::abs(f_local - 3000.0), 40.0);
  }
}

// Moving receiver and moving source (circular motion): every sample against an independent solution
// of t − te = |p_mic(t) − p_spk(te)|/c.
TEST(SimPropagation, MovingBothMatchesRetardedTimeSolution) {
  Simulation s = quiet_simulation(2.0);
  auto circle = [](Eigen::Vector3d c, double r, double w) {
    return std::make_shared<FunctionTrajectory>(
        [=](double t) { return Pose{c + Eigen::Vector3d(r * std::cos(w * t), r * std::sin(w * t), 0), Eigen::Quaterniond::Identity()}; },
        r * std::abs(w));
  };
  DeviceModel d = listener("R", {0, 0, 0}, {0.05, 12.0});
  d.trajectory = circle({3, 0, 1}, 0.5, 9.0);
  s.devices.push_back(d);
  const auto sig = test_chirp(1000, 9000, 0.2);
  auto src_tr = circle({0, 0, 1}, 0.3, -7.0);
  s.emitters.push_back(emitter("E", src_tr, sig));
  s.emissions.push_back(Emission{"E", 0, 0.5, 0.0});
  SceneSimulator sim(s);
  const auto audio = sim.render_audio("R", 0, static_cast<std::size_t>(1.0 * kRateHz));
  const dsp::SignalEvaluator ev(sig, kRateHz);
  const double c = s.acoustics.speed_of_sound_mps;
  double max_err = 0.0;
  int nonzero = 0;
  for (std::size_t k = 0; k < audio[0].size(); ++k) {
    const double t = d.clock.true_from_local(static_cast<double>(k) / kRateHz);
    const Eigen::Vector3d pm = d.trajectory->pose(t).position_m;
    double te = t;  // Newton-free bisection on f(te) = t − te − |pm − ps(te)|/c (monotone)
    double lo = t - 1.0, hi = t;
    for (int i = 0; i < 200; ++i) {
      te = 0.5 * (lo + hi);
      const double f = t - te - (pm - src_tr->pose(te).position_m).norm() / c;
      (f > 0 ? lo : hi) = te;
    }
    const double r = c * (t - te);
    const double want = s.acoustics.level_at_1m / r * ev.value(te - 0.5);
    if (want != 0.0) ++nonzero;
    max_err = std::max(max_err, std::abs(want - audio[0][k]));
  }
  EXPECT_GT(nonzero, 8000);
  EXPECT_LT(max_err, 2e-6);
}

// Image sources: the difference between order 1 and order 0 is the first-order reflections; in a big
// room the floor reflection arrives first, at the mirrored geometry's delay, with amplitude β/r'.
TEST(SimPropagation, FirstReflectionMatchesMirroredGeometry) {
  const Eigen::Vector3d src(10.0, 9.0, 0.5), rx(10.0, 11.0, 0.6);
  const scene::ClockTruth clock{0.3, 20.0};
  auto make = [&](int order) {
    Simulation s = quiet_simulation(2.0);
    s.acoustics.room = Room{};
    s.acoustics.room->size_m = {20.0, 20.0, 10.0};
    s.acoustics.room->max_order = order;
    s.acoustics.room->set_reflection(0.6);
    s.acoustics.room->reflection[4] = 0.8;  // the floor
    s.devices.push_back(listener("R", rx, clock));
    s.emitters.push_back(emitter("E", std::make_shared<StaticTrajectory>(src), test_chirp()));
    s.emissions.push_back(Emission{"E", 0, 0.7, 0.0});
    return SceneSimulator(s);
  };
  const auto a1 = make(1).render_audio("R", 0, static_cast<std::size_t>(1.5 * kRateHz));
  const auto a0 = make(0).render_audio("R", 0, static_cast<std::size_t>(1.5 * kRateHz));
  std::vector<float> refl(a1[0].size());
  for (std::size_t i = 0; i < refl.size(); ++i) refl[i] = a1[0][i] - a0[0][i];
  const double c = 343.2;
  const Eigen::Vector3d mirrored(src.x(), src.y(), -src.z());
  const double r1 = (rx - mirrored).norm();
  const double expected = clock.local_from_true(0.7 + r1 / c) * kRateHz;
  // the next reflection (a wall, 2·9 m away) comes much later: the fit window holds the floor only
  const double fitted = fit_arrival_frame(refl, test_chirp(), kRateHz, expected, 4.0, 1.0 + clock.skew_ppm * 1e-6);
  EXPECT_NEAR(fitted, expected, 0.05);
  // amplitude β/r': peak of the reflection vs the direct path's 1/r
  float peak_refl = 0, peak_direct = 0;
  for (std::size_t i = 0; i < refl.size(); ++i) {
    if (std::abs(static_cast<double>(i) - expected) < 0.05 * kRateHz) peak_refl = std::max(peak_refl, std::abs(refl[i]));
    peak_direct = std::max(peak_direct, std::abs(a0[0][i]));
  }
  const double r0 = (rx - src).norm();
  EXPECT_NEAR(peak_refl / peak_direct, 0.8 * r0 / r1, 0.01);
}

TEST(SimPropagation, ObstructionAttenuatesDirectPathOnly) {
  auto make = [&](bool obstructed) {
    Simulation s = quiet_simulation(1.0);
    s.acoustics.room = Room{};
    s.acoustics.room->size_m = {6, 6, 3};
    s.acoustics.room->max_order = 1;
    s.devices.push_back(listener("R", {2, 3, 1}));
    s.emitters.push_back(emitter("E", std::make_shared<StaticTrajectory>(Eigen::Vector3d(4, 3, 1)), test_chirp()));
    s.emissions.push_back(Emission{"E", 0, 0.3, 0.0});
    if (obstructed) s.acoustics.obstructions.push_back(Obstruction{"R", "E", 20.0});
    return SceneSimulator(s).render_audio("R", 0, static_cast<std::size_t>(0.6 * kRateHz))[0];
  };
  const auto clear = make(false), blocked = make(true);
  const double direct = 0.3 + 2.0 / 343.2;
  float peak_clear = 0, peak_blocked = 0, late_diff = 0;
  for (std::size_t i = 0; i < clear.size(); ++i) {
    const double t = static_cast<double>(i) / kRateHz;
    if (t >= direct && t < direct + 0.002) {  // before the floor reflection (+0.83 m = 2.4 ms)
      peak_clear = std::max(peak_clear, std::abs(clear[i]));
      peak_blocked = std::max(peak_blocked, std::abs(blocked[i]));
    }
    if (t > direct + 0.045 && t < direct + 0.2) late_diff = std::max(late_diff, std::abs(clear[i] - blocked[i]));
  }
  EXPECT_NEAR(peak_blocked / peak_clear, 0.1, 0.005);
  EXPECT_LT(late_diff, 1e-6);  // reflections (arriving after the direct chirp ended) untouched
}

// A partition (Obstruction::wall_m, x = 3 m from y = 2 to 4 m) between a source and a receiver: the
// floor reflection, in the direct path's vertical plane, crosses it and loses the same 20 dB as the
// direct path; the reflection off the y = 0 wall goes around it and is kept. One reflecting surface
// at a time (the others' coefficients 0), so each render holds the direct path and that reflection.
TEST(SimPropagation, PartitionBlocksTheReflectionsThatCrossIt) {
  auto make = [&](std::size_t surface, int mode) {  // mode 0: clear, 1: direct obstructed, 2: with the wall
    Simulation s = quiet_simulation(1.0);
    s.acoustics.room = Room{};
    s.acoustics.room->size_m = {6, 6, 3};
    s.acoustics.room->max_order = 1;
    s.acoustics.room->reflection.fill(0.0);
    s.acoustics.room->reflection[surface] = 0.8;
    s.devices.push_back(listener("R", {2, 3, 1}));
    s.emitters.push_back(emitter("E", std::make_shared<StaticTrajectory>(Eigen::Vector3d(4, 3, 1)), test_chirp()));
    s.emissions.push_back(Emission{"E", 0, 0.3, 0.0});
    if (mode > 0) {
      Obstruction o{"R", "E", 20.0};
      if (mode == 2) o.wall_m = {{Eigen::Vector2d(3, 2), Eigen::Vector2d(3, 4)}};
      s.acoustics.obstructions.push_back(o);
    }
    return SceneSimulator(s).render_audio("R", 0, static_cast<std::size_t>(0.6 * kRateHz))[0];
  };
  auto max_abs_diff = [](const std::vector<float>& a, const std::vector<float>& b, double scale_b) {
    double m = 0.0, peak = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      m = std::max(m, std::abs(a[i] - scale_b * b[i]));
      peak = std::max(peak, std::abs(static_cast<double>(a[i])));
    }
    return m / peak;
  };
  // floor (surface index 4: z = 0): blocked with the wall, so everything is 20 dB down
  const auto floor_clear = make(4, 0), floor_direct = make(4, 1), floor_wall = make(4, 2);
  EXPECT_LT(max_abs_diff(floor_wall, floor_clear, 0.1), 1e-4);
  EXPECT_GT(max_abs_diff(floor_direct, floor_clear, 0.1), 0.1);  // without the wall the reflection stays
  // the y = 0 wall (index 2): its reflection passes beside the partition, the same as without it
  const auto side_direct = make(2, 1), side_wall = make(2, 2);
  EXPECT_LT(max_abs_diff(side_wall, side_direct, 1.0), 1e-6);
}

// A device hears its own emission, near field and loud; its recording shows the speaker latency.
TEST(SimPropagation, SelfRecordingRevealsLatency) {
  Simulation s = quiet_simulation(2.0);
  DeviceModel d = listener("P", {1, 1, 1}, {0.4, 15.0});
  d.speaker_body_m = Eigen::Vector3d(0.03, -0.07, 0.0);
  d.mics_body_m = {{0.0, -0.07, 0.0}};
  d.emits = {test_chirp()};
  s.devices.push_back(d);
  const double latency = 0.0873;
  s.emissions.push_back(Emission{"P", 0, 0.5, latency});
  SceneSimulator sim(s);
  const auto audio = sim.render_audio("P", 0, static_cast<std::size_t>(1.5 * kRateHz));
  const double expected = d.clock.local_from_true(0.5 + latency + 0.03 / 343.2) * kRateHz;
  const double fitted = fit_arrival_frame(audio[0], test_chirp(), kRateHz, expected, 3.0, 1.0 + d.clock.skew_ppm * 1e-6);
  EXPECT_NEAR(fitted, expected, 0.05);
  float peak = 0;
  for (float v : audio[0]) peak = std::max(peak, std::abs(v));
  EXPECT_FLOAT_EQ(peak, 1.0f);  // 0.1 / 0.03 m = 3.3 × full scale: clipped
}

TEST(SimPropagation, RejectsInvalidSimulation) {
  Simulation s = quiet_simulation(1.0);
  s.devices.push_back(listener("R", {0, 0, 0}));
  s.emissions.push_back(Emission{"nobody", 0, 0.1, 0.0});
  try {
    SceneSimulator sim(s);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("emission 0 (source 'nobody'): unknown source"), std::string::npos) << e.what();
  }
  Simulation s2 = quiet_simulation(1.0);
  s2.devices.push_back(listener("R", {0, 0, 0}));
  s2.devices.push_back(listener("R", {1, 0, 0}));
  EXPECT_THROW(SceneSimulator{s2}, std::invalid_argument);
  Simulation s3 = quiet_simulation(1.0);
  s3.acoustics.room = Room{};
  s3.devices.push_back(listener("R", {9, 0, 0}));
  EXPECT_THROW(SceneSimulator{s3}, std::invalid_argument);
}

}  // namespace
}  // namespace locus::sim
