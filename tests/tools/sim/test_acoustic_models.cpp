// The acoustic realism models of the simulator: per-device transducer responses (ripple within the
// drawn bounds, roll-off near 20 kHz), babble/music interference with energy up to 20 kHz, ISO 9613-1
// air absorption (values and its effect on a rendered arrival), microphone self-noise.
#include <gtest/gtest.h>

#include <cmath>

#include "locus/dsp/iir.hpp"
#include "locus/sim/interference.hpp"
#include "locus/sim/response.hpp"
#include "sim_test_util.hpp"

namespace locus::sim {
namespace {

constexpr double kFs = 44100.0;

TEST(SimTransducer, RandomResponsesHaveTheDrawnRippleAndRollOff) {
  const TransducerSpread sp;  // ripple 1-1.5 dB, shelf 3-8 dB at 19.5-21 kHz
  Rng rng(17);
  double min_peak = 1e9, max_peak = 0.0;
  std::vector<double> at_20k;
  for (int dev = 0; dev < 60; ++dev) {
    const BandLimit r = random_transducer_response(BandLimit{60.0, 0.0, 2, {}}, sp, kFs, rng);
    ASSERT_EQ(r.eq.size(), 7u);  // 6 peaking + 1 shelf
    EXPECT_EQ(r.low_hz, 60.0);   // the band edges are kept
    const double peak = ripple_peak_db(r, sp.ripple_lo_hz, sp.ripple_hi_hz, kFs);
    min_peak = std::min(min_peak, peak);
    max_peak = std::max(max_peak, peak);
    EXPECT_GE(peak, sp.ripple_min_db - 0.05);
    EXPECT_LE(peak, sp.ripple_max_db + 0.05);
    // the whole response: within the ripple over the voice band, rolled off near 20 kHz
    for (double f : {300.0, 1000.0, 3000.0, 8000.0, 12000.0}) {
      EXPECT_LE(std::abs(response_db(r, f, kFs)), sp.ripple_max_db + 0.3) << f;
    }
    const double top = response_db(r, 21500.0, kFs), mid = response_db(r, 18500.0, kFs);
    EXPECT_LT(top, -sp.rolloff_min_db * 0.6 + sp.ripple_max_db) << "no roll-off at 21.5 kHz";
    EXPECT_LT(top, mid);
    at_20k.push_back(response_db(r, 20000.0, kFs));
  }
  EXPECT_LT(min_peak, 1.15);  // the levels spread over the range
  EXPECT_GT(max_peak, 1.35);
  // per device: different responses
  const auto [lo, hi] = std::minmax_element(at_20k.begin(), at_20k.end());
  EXPECT_GT(*hi - *lo, 2.0);
  // deterministic for the rng state
  Rng a(5), b(5);
  const BandLimit ra = random_transducer_response({}, sp, kFs, a), rb = random_transducer_response({}, sp, kFs, b);
  for (std::size_t i = 0; i < ra.eq.size(); ++i) EXPECT_EQ(ra.eq[i].gain_db, rb.eq[i].gain_db);
  TransducerSpread bad;
  bad.ripple_max_db = 0.5;  // < min
  EXPECT_THROW(random_transducer_response({}, bad, kFs, a), std::invalid_argument);
}

TEST(SimTransducer, PeakingAndShelfSectionsHitTheirGains) {
  BandLimit r;
  r.eq.push_back({EqSection::Kind::Peaking, 5000.0, 2.0, 2.0});
  EXPECT_NEAR(response_db(r, 5000.0, kFs), 2.0, 1e-9);
  EXPECT_NEAR(response_db(r, 200.0, kFs), 0.0, 0.05);
  BandLimit s;
  s.eq.push_back({EqSection::Kind::HighShelf, 15000.0, -6.0, 1.0});
  EXPECT_NEAR(response_db(s, 22000.0, kFs), -6.0, 0.05);
  EXPECT_NEAR(response_db(s, 15000.0, kFs), -3.0, 0.1);  // half the gain in dB at the corner
  EXPECT_NEAR(response_db(s, 1000.0, kFs), 0.0, 0.05);
  BandLimit bad;
  bad.eq.push_back({EqSection::Kind::Peaking, 30000.0, 1.0, 1.0});
  EXPECT_THROW(design_response(bad, kFs), std::invalid_argument);
}

// fraction of the energy of x in [lo, hi] Hz (Butterworth band-pass, order 8)
double band_fraction(const std::vector<double>& x, double lo, double hi) {
  dsp::SosFilter f(dsp::butter_bandpass(8, lo, hi, kFs));
  double e = 0.0, eb = 0.0;
  for (double v : x) {
    const double y = f.process_double(v);
    e += v * v;
    eb += y * y;
  }
  return eb / e;
}

TEST(SimInterference, BabbleAndMusicAreUnitRmsWithEnergyUpTo20kHz) {
  for (auto kind : {InterferenceKind::Babble, InterferenceKind::Music}) {
    Rng rng(kind == InterferenceKind::Babble ? 1 : 2);
    const std::vector<double> x = synth_interference(kind, static_cast<std::size_t>(1.5 * kFs), kFs, rng);
    double e = 0.0;
    for (double v : x) e += v * v;
    EXPECT_NEAR(std::sqrt(e / x.size()), 1.0, 1e-9);
    EXPECT_EQ(x.front(), 0.0);  // faded in
    // energy in AMIL's band (18-20 kHz here, as a fraction of the whole): far above a pink noise's
    // (~1.5 % of a pink 20 Hz-20 kHz spectrum is in 18-20 kHz; white: 9 %), not negligible
    const double f_hi = band_fraction(x, 18000.0, 20000.0);
    EXPECT_GT(f_hi, 1e-3) << (kind == InterferenceKind::Babble ? "babble" : "music");
    // most of the energy is where speech and music live
    EXPECT_GT(band_fraction(x, 80.0, 5000.0), 0.2);
    Rng again(kind == InterferenceKind::Babble ? 1 : 2);
    EXPECT_EQ(x, synth_interference(kind, x.size(), kFs, again));
  }
}

TEST(SimAirAbsorption, Iso9613ValuesAndTheRenderedArrival) {
  // ISO 9613-1 table values (20 °C, 50 % RH): 0.0049 dB/m at 1 kHz... 0.105 dB/m at 8 kHz; the
  // reference scene amil-101 states 0.470 dB/m at 19 kHz (20 °C, 52 % RH).
  EXPECT_NEAR(air_absorption_db_per_m(1000.0, 20.0, 50.0), 0.00488, 0.0003);
  EXPECT_NEAR(air_absorption_db_per_m(8000.0, 20.0, 50.0), 0.105, 0.006);
  EXPECT_NEAR(air_absorption_db_per_m(19000.0, 20.0, 52.4), 0.470, 0.02);
  // rendered: a 19-21 kHz chirp at 8 m loses α·8 dB, on top of 1/r
  Simulation s = test::quiet_simulation(1.0);
  s.devices.push_back(test::listener("L", Eigen::Vector3d(8, 0, 0)));
  s.emitters.push_back(test::emitter("E", std::make_shared<StaticTrajectory>(Eigen::Vector3d::Zero()),
                                     test::test_chirp(19000.0, 21000.0, 0.04)));
  s.emissions.push_back(Emission{"E", 0, 0.1, 0.0, 1.0});
  auto peak = [&](bool air) {
    Simulation t = s;
    t.acoustics.air_absorption = air;
    const auto x = SceneSimulator(t).render_audio("L", 0, 44100)[0];
    double m = 0.0;
    for (float v : x) m = std::max(m, std::abs(static_cast<double>(v)));
    return m;
  };
  const double ratio_db = 20.0 * std::log10(peak(true) / peak(false));
  EXPECT_NEAR(ratio_db, -air_absorption_db_per_m(20000.0, 20.0, 50.0) * 8.0, 0.02);
  EXPECT_LT(ratio_db, -3.0);
}

TEST(SimSelfNoise, AddsWhiteNoiseOfTheSetLevelAfterTheMic) {
  Simulation s = test::quiet_simulation(2.0);
  s.acoustics.noise.enabled = true;
  s.acoustics.noise.snr_db = 200.0;  // no acoustic noise
  s.acoustics.noise.self_noise_snr_db = 40.0;
  s.devices.push_back(test::listener("L", Eigen::Vector3d(1, 0, 0)));
  const auto x = SceneSimulator(s).render_audio("L", 0, 44100)[0];
  double e = 0.0;
  for (float v : x) e += static_cast<double>(v) * v;
  const double expect = s.acoustics.level_at_1m / std::sqrt(2.0) / 100.0;
  EXPECT_NEAR(std::sqrt(e / x.size()), expect, 0.02 * expect);
}

TEST(SimBursts, BabbleAndMusicBurstsAreTheSameOnEveryChannel) {
  Simulation s = test::quiet_simulation(30.0);
  s.acoustics.noise.enabled = true;
  s.acoustics.noise.snr_db = 200.0;
  s.acoustics.noise.bursts_per_minute = 20.0;
  s.acoustics.noise.burst_db = 200.0 - 40.0;  // bursts at SNR 40 dB
  s.acoustics.noise.burst_kind = NoiseModel::BurstKind::Mixed;
  s.acoustics.noise.burst_min_s = 0.3;
  s.acoustics.noise.burst_max_s = 1.0;
  DeviceModel d = test::listener("L", Eigen::Vector3d(1, 0, 0));
  d.mics_body_m = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0, 0)};
  s.devices.push_back(d);
  const auto x = SceneSimulator(s).render_audio("L", 0, 30 * 44100);
  double e = 0.0, diff = 0.0;
  for (std::size_t i = 0; i < x[0].size(); ++i) {
    e += static_cast<double>(x[0][i]) * x[0][i];
    diff += std::abs(static_cast<double>(x[0][i]) - x[1][i]);
  }
  EXPECT_GT(e, 0.0);  // some bursts in 30 s at 20 per minute
  EXPECT_LT(diff / static_cast<double>(x[0].size()), 1e-9);  // only the (200 dB down) stationary noise differs
  EXPECT_GT(std::sqrt(e / static_cast<double>(x[0].size())), 1e-4);
}

TEST(SimDiffuseTail, SabineEnergyAfterTheImageSources) {
  // A static pair in a room, direct path only + the diffuse tail: the tail is silent until t_s after
  // the direct arrival and carries at most the Sabine late energy 16π/A·e^(−2 t_s/τ) of the direct
  // sound at 1 m.
  Simulation s = test::quiet_simulation(1.0);
  Room room;
  room.size_m = {4.0, 6.0, 3.0};
  room.set_reflection(0.7);
  room.max_order = 0;
  room.diffuse_tail = true;
  room.tail_taps = 2000;
  s.acoustics.room = room;
  s.devices.push_back(test::listener("L", Eigen::Vector3d(2, 4, 1.5)));
  const dsp::SignalSpec chirp = test::test_chirp(2000.0, 8000.0, 0.04);
  s.emitters.push_back(test::emitter("E", std::make_shared<StaticTrajectory>(Eigen::Vector3d(2, 1, 1.5)), chirp));
  s.emissions.push_back(Emission{"E", 0, 0.1, 0.0, 1.0});
  Simulation dry = s;
  dry.acoustics.room->diffuse_tail = false;
  const auto wet_x = SceneSimulator(s).render_audio("L", 0, 44100)[0];
  const auto dry_x = SceneSimulator(dry).render_audio("L", 0, 44100)[0];
  ASSERT_EQ(wet_x.size(), dry_x.size());
  const double c = s.acoustics.speed_of_sound_mps;
  const double t_dir = 0.1 + 3.0 / c;
  const double t_s = 3.0 / c;  // max(1, order)·L_min/c
  double e_tail = 0.0, early = 0.0;
  for (std::size_t k = 0; k < wet_x.size(); ++k) {
    const double d = static_cast<double>(wet_x[k]) - dry_x[k];
    if (static_cast<double>(k) < (t_dir + t_s) * 44100.0 - 2.0) early = std::max(early, std::abs(d));
    e_tail += d * d;
  }
  EXPECT_LT(early, 1e-6);
  // expected: level² · relative energy · Σ s² (the dry signal's energy on the sample grid)
  const dsp::SignalEvaluator ev(chirp, 44100.0);
  double e_sig = 0.0;
  for (int i = 0; i < 44100; ++i) e_sig += std::pow(ev.value(i / 44100.0), 2);
  const double V = 72.0, S = 2.0 * (24.0 + 18.0 + 12.0), A = S * (1.0 - 0.49);
  const double tau = 0.161 * V / A / 6.91;
  const double expect = std::pow(s.acoustics.level_at_1m, 2) * 16.0 * M_PI / A * std::exp(-2.0 * t_s / tau) * e_sig;
  // Sabine's diffuse field is full from the first reflection on; a room's first late reflections are
  // fewer and weaker than that (each bounded by β^(max_order+1)/(ct)), so the tail carries up to the
  // Sabine energy, not all of it (0.53 here: the early part is cut to what single paths can carry).
  EXPECT_LE(e_tail / expect, 1.05);
  EXPECT_GE(e_tail / expect, 0.35);
}

}  // namespace
}  // namespace locus::sim
