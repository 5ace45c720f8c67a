#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <numeric>

#include "locus/dsp/signals.hpp"

using namespace locus::dsp;

namespace {
SignalSpec lfm(double f0, double f1, double d, double fade) {
  SignalSpec s;
  s.type = "lfm";
  s.f0_hz = f0;
  s.f1_hz = f1;
  s.duration_s = d;
  s.fade_s = fade;
  return s;
}
}  // namespace

TEST(Signals, MSequenceIsMaximalLengthAndBalanced) {
  for (int r : {5, 6, 7, 9, 10, 11}) {
    const auto [pu, pv] = gold_preferred_pair(r);
    for (unsigned p : {pu, pv}) {
      const auto seq = m_sequence(r, p);
      ASSERT_EQ(seq.size(), (1u << r) - 1);
      EXPECT_EQ(std::accumulate(seq.begin(), seq.end(), 0u), 1u << (r - 1)) << "degree " << r;
      // the first r chips are the all-ones seed
      for (int i = 0; i < r; ++i) EXPECT_EQ(seq[i], 1);
      // two-valued periodic autocorrelation: L at 0, -1 elsewhere
      const int n = static_cast<int>(seq.size());
      for (int shift : {1, 2, n / 3, n - 1}) {
        int acc = 0;
        for (int i = 0; i < n; ++i) acc += (seq[i] ? -1 : 1) * (seq[(i + shift) % n] ? -1 : 1);
        EXPECT_EQ(acc, -1) << "degree " << r << " shift " << shift;
      }
    }
  }
}

TEST(Signals, GoldIndexConvention) {
  SignalSpec s;
  s.type = "gold";
  s.degree = 5;
  const auto [pu, pv] = gold_preferred_pair(5);
  const auto u = m_sequence(5, pu), v = m_sequence(5, pv);
  s.index = 0;
  EXPECT_EQ(gold_chips(s), u);
  s.index = 1;
  EXPECT_EQ(gold_chips(s), v);
  s.index = 4;  // u XOR v shifted left by 2
  const auto g = gold_chips(s);
  for (std::size_t n = 0; n < u.size(); ++n) EXPECT_EQ(g[n], u[n] ^ v[(n + 2) % v.size()]);
  s.index = 32;  // 2^5 = L + 1: the last valid index
  EXPECT_NO_THROW(gold_chips(s));
  s.index = 33;
  EXPECT_THROW(gold_chips(s), std::invalid_argument);
  s.index = 0;
  s.degree = 8;
  EXPECT_THROW(gold_chips(s), std::invalid_argument);
  s.chips = "0110";
  EXPECT_EQ(gold_chips(s), (std::vector<std::uint8_t>{0, 1, 1, 0}));  // authoritative, degree ignored
  s.chips = "01x0";
  EXPECT_THROW(gold_chips(s), std::invalid_argument);
}

TEST(Signals, GoldSamplesFollowTheFormula) {
  SignalSpec s;
  s.type = "gold";
  s.degree = 5;
  s.index = 3;
  s.carrier_hz = 19000;
  s.chip_samples = 7;
  s.amplitude = 0.5;
  const double fs = 44100;
  const auto x = render_signal(s, fs);
  const auto chips = gold_chips(s);
  ASSERT_EQ(x.size(), 31u * 7u);
  const SignalEvaluator eval(s, fs);
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double expect = 0.5 * (chips[n / 7] ? -1.0 : 1.0) * std::cos(2 * std::numbers::pi * 19000 * n / fs);
    ASSERT_NEAR(x[n], expect, 1e-6);
    ASSERT_NEAR(eval.value(n / fs), expect, 1e-6);  // samples are stored as float
  }
}

TEST(Signals, LfmClosedFormAndFade) {
  const SignalSpec s = lfm(2000, 8000, 0.04, 0.005);
  const double fs = 44100;
  const auto x = render_signal(s, fs);
  ASSERT_EQ(x.size(), 1764u);
  EXPECT_EQ(x[0], 0.0f);  // faded in from zero
  const SignalEvaluator eval(s, fs);
  EXPECT_DOUBLE_EQ(eval.value(-1e-9), 0.0);
  EXPECT_DOUBLE_EQ(eval.value(0.04), 0.0);
  // mid-chirp: unit amplitude, instantaneous frequency f0 + k t
  const double t = 0.02, k = 6000 / 0.04;
  EXPECT_NEAR(eval.value(t), std::sin(2 * std::numbers::pi * (2000 * t + 0.5 * k * t * t)), 1e-12);
  EXPECT_DOUBLE_EQ(fade_weight(0.0025, 0.04, 0.005), 0.5);
  EXPECT_NEAR(fade_weight(0.0375, 0.04, 0.005), 0.5, 1e-12);
  EXPECT_DOUBLE_EQ(fade_weight(0.02, 0.04, 0.005), 1.0);
  EXPECT_DOUBLE_EQ(fade_weight(0.02, 0.04, 0.0), 1.0);
}

TEST(Signals, MultitoneIsNormalisedByToneCount) {
  SignalSpec s;
  s.type = "multitone";
  s.tones_hz = {18000, 18250, 18500, 18750};
  s.duration_s = 0.05;
  s.amplitude = 0.8;
  const auto x = render_signal(s, 44100);
  float peak = 0;
  for (float v : x) peak = std::max(peak, std::abs(v));
  EXPECT_LE(peak, 0.8f + 1e-6f);
  EXPECT_GT(peak, 0.5f);
}

TEST(Signals, BadSpecsAreRefusedWithTheReason) {
  SignalSpec s = lfm(2000, 8000, 0.0, 0.0);
  try {
    render_signal(s, 44100);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("lfm: duration must be > 0 s"), std::string::npos) << e.what();
  }
  s.type = "ble";
  EXPECT_THROW(render_signal(s, 44100), std::invalid_argument);
  EXPECT_EQ(signal_length(s, 44100), 0u);
  SignalSpec m;
  m.type = "multitone";
  m.duration_s = 0.1;
  EXPECT_THROW(render_signal(m, 44100), std::invalid_argument);
}

// Gold codes are defined at the sample instants only; between them the evaluator is the DAC's
// band-limited interpolation: exact at n/fs, and a fractional delay moves the whole waveform (chip
// edges included) by the fraction, which a band-limited reference confirms.
TEST(Signals, GoldEvaluatorIsBandLimitedInterpolation) {
  SignalSpec s;
  s.type = "gold";
  s.degree = 6;
  s.index = 5;
  s.carrier_hz = 6000;  // well inside the band, so a short windowed sinc is accurate
  s.chip_samples = 8;
  const double fs = 44100;
  const auto x = render_signal(s, fs);
  const SignalEvaluator eval(s, fs);
  for (std::size_t n = 0; n < x.size(); n += 7) ASSERT_NEAR(eval.value(n / fs), x[n], 1e-6);
  EXPECT_LT(eval.begin_s(), 0.0);
  EXPECT_GT(eval.end_s(), eval.duration_s());
  EXPECT_EQ(eval.value(eval.end_s() + 1e-6), 0.0);
  // Half-sample shifted copy: compare against a long (±400 samples) plain sinc interpolation.
  double err = 0, ref_power = 0;
  for (std::size_t n = 100; n + 100 < x.size(); ++n) {
    const double t = (n + 0.5) / fs;
    double ref = 0;
    for (long k = static_cast<long>(n) - 400; k <= static_cast<long>(n) + 400; ++k) {
      if (k < 0 || k >= static_cast<long>(x.size())) continue;
      const double d = (n + 0.5) - k;
      ref += x[static_cast<std::size_t>(k)] * std::sin(std::numbers::pi * d) / (std::numbers::pi * d);
    }
    err += (eval.value(t) - ref) * (eval.value(t) - ref);
    ref_power += ref * ref;
  }
  // The residual is the windowed kernel's transition band at Nyquist (rectangular chips put energy
  // there); -37 dB measured.
  EXPECT_LT(10 * std::log10(err / ref_power), -33.0);
}

// doppler_timing_instant_s against its closed forms: an lfm without fades is timed at
// T (f0 + 2 f1) / (3 (f0 + f1)) (the frequency-weighted mean instant), constant-frequency signals at
// their middle; fades pull the up and down chirps symmetrically (their instants still sum to T). The
// chirp detector's timing under Doppler is checked against it in tests/plugins/chirp.
TEST(Signals, DopplerTimingInstant) {
  SignalSpec up;
  up.type = "lfm", up.f0_hz = 2000, up.f1_hz = 8000, up.duration_s = 0.04;
  EXPECT_NEAR(doppler_timing_instant_s(up, 44100.0), 0.04 * (2000 + 16000) / (3.0 * 10000), 1e-8);
  SignalSpec down = up;
  std::swap(down.f0_hz, down.f1_hz);
  EXPECT_NEAR(doppler_timing_instant_s(down, 44100.0), 0.04 * 0.4, 1e-8);
  up.fade_s = down.fade_s = 0.005;
  const double iu = doppler_timing_instant_s(up, 44100.0), id = doppler_timing_instant_s(down, 44100.0);
  EXPECT_NEAR(iu + id, 0.04, 1e-8);
  EXPECT_LT(iu, 0.024);  // the fades weigh the ends less: closer to the middle than 0.6 T
  EXPECT_GT(iu, 0.020);
  SignalSpec tones;
  tones.type = "multitone", tones.tones_hz = {1000, 2000}, tones.duration_s = 0.06, tones.fade_s = 0.01;
  EXPECT_NEAR(doppler_timing_instant_s(tones, 44100.0), 0.03, 1e-8);
  SignalSpec gold;
  gold.type = "gold", gold.degree = 7, gold.index = 3, gold.carrier_hz = 19000, gold.chip_samples = 40;
  EXPECT_NEAR(doppler_timing_instant_s(gold, 44100.0), 0.5 * 127 * 40 / 44100.0, 1e-12);
  SignalSpec ble;
  ble.type = "ble";
  EXPECT_EQ(doppler_timing_instant_s(ble, 44100.0), 0.0);
}
