// dsp::EmissionCanceller: a loud known emission (LFM chirp or Gold-code BPSK) that reaches the mic
// through an unknown response (gain, fractional delay, an early echo) is removed by fitted subtraction
// to far below a weak overlapping signal, which survives; audio without a clean copy of the template
// passes bit for bit; the result does not depend on how the input is cut into blocks; an emission
// just before the end of the stream is cancelled by flush().
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "locus/dsp/correlator.hpp"
#include "locus/dsp/emission_canceller.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"

namespace locus::dsp {
namespace {

constexpr double kFs = 44100.0;

SignalSpec lfm(double f0, double f1) {
  SignalSpec s;
  s.type = "lfm";
  s.f0_hz = f0;
  s.f1_hz = f1;
  s.duration_s = 0.04;
  s.fade_s = 0.005;
  return s;
}

SignalSpec gold(int index) {
  SignalSpec s;
  s.type = "gold";
  s.degree = 7;
  s.index = index;
  s.carrier_hz = 19000.0;
  s.chip_samples = 8;
  return s;
}

FftwPlanner& planner() {
  static FftwPlanner p("", true);
  return p;
}

/// Adds a * spec(t - t0) sampled at k / fs (t0 in samples, fractional) to x. LFM: the closed form at
/// the shifted times; other types (Gold BPSK: SignalEvaluator moves its chip edges by whole samples):
/// the rendered samples delayed by a band-limited (Hann-windowed sinc, 64 taps each side) fractional delay.
void add(std::vector<double>& x, const SignalSpec& spec, double t0, double a) {
  if (spec.type != "lfm") {
    const std::vector<float> h = render_signal(spec, kFs);
    const auto k0 = static_cast<std::ptrdiff_t>(std::floor(t0));
    const double frac = t0 - static_cast<double>(k0);
    constexpr int kHalf = 64;
    for (int d = -kHalf; d <= kHalf; ++d) {
      const double u = static_cast<double>(d) - frac;  // x[k0 + j + d] += h[j] sinc(d - frac)
      const double w = 0.5 * (1.0 + std::cos(std::numbers::pi * u / (kHalf + 1)));
      const double sinc = std::abs(u) < 1e-12 ? 1.0 : std::sin(std::numbers::pi * u) / (std::numbers::pi * u);
      for (std::size_t j = 0; j < h.size(); ++j) {
        const std::ptrdiff_t k = k0 + static_cast<std::ptrdiff_t>(j) + d;
        if (k >= 0 && k < static_cast<std::ptrdiff_t>(x.size())) x[static_cast<std::size_t>(k)] += a * h[j] * w * sinc;
      }
    }
    return;
  }
  const SignalEvaluator ev(spec, kFs);
  const double t0_s = t0 / kFs;
  const auto k0 = static_cast<std::ptrdiff_t>(std::floor(t0 + ev.begin_s() * kFs)) - 1;
  const auto k1 = static_cast<std::ptrdiff_t>(std::ceil(t0 + ev.end_s() * kFs)) + 1;
  for (std::ptrdiff_t k = std::max<std::ptrdiff_t>(k0, 0); k < std::min<std::ptrdiff_t>(k1, std::ptrdiff_t(x.size())); ++k)
    x[static_cast<std::size_t>(k)] += a * ev.value(static_cast<double>(k) / kFs - t0_s);
}

/// Streams x through the canceller (blocks of `block`), returns its output (same length).
std::vector<float> run(EmissionCanceller& c, const std::vector<float>& x, std::size_t block) {
  std::vector<float> out;
  for (std::size_t pos = 0; pos < x.size(); pos += block) {
    const std::size_t n = std::min(block, x.size() - pos);
    std::size_t done = 0;
    while (done < n) {
      done += c.push(0, x.data() + pos + done, n - done);
      if (c.full(0)) {
        const std::size_t m = c.process(0);
        EXPECT_EQ(c.output_start(0), out.size());
        out.insert(out.end(), c.output(0), c.output(0) + m);
        c.advance(0);
      }
    }
  }
  const std::size_t m = c.flush(0);
  EXPECT_EQ(c.output_start(0), out.size());
  out.insert(out.end(), c.output(0), c.output(0) + m);
  c.reset(0);
  return out;
}

double energy(const std::vector<double>& v, std::size_t a, std::size_t b) {
  double e = 0.0;
  for (std::size_t i = a; i < b && i < v.size(); ++i) e += v[i] * v[i];
  return e;
}

struct Case {
  SignalSpec own, other;
  double near_far_db;
  std::size_t taps_before = 4;
};

/// Own emission (amplitude 0.5) through gain + fractional delay + an echo 0.3 at +6.4 samples (Gold: 6); the
/// other signal near_far_db weaker, overlapping it; white noise 100 dB below the own emission.
void check_case(const Case& cs, double min_cancel_db) {
  const std::size_t n = 30000;
  std::vector<double> own(n, 0.0), other(n, 0.0), noise(n, 0.0);
  // Gold BPSK: chips of 8 samples with sharp edges carry energy up to Nyquist, where no short FIR is a
  // fractional delay; its own emission arrives at whole samples (the LFM cases test the fractions).
  const bool lfm_own = cs.own.type == "lfm";
  const double t_own = lfm_own ? 9000.37 : 9000.0, t_other = 9600.81, echo = lfm_own ? 6.4 : 6.0;
  add(own, cs.own, t_own, 0.5);
  add(own, cs.own, t_own + echo, 0.5 * 0.3);
  const double a_other = 0.5 * std::pow(10.0, -cs.near_far_db / 20.0);
  add(other, cs.other, t_other, a_other);
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 0.5e-5);
  for (double& v : noise) v = g(rng);
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>(own[i] + other[i] + noise[i]);

  const std::vector<float> h = render_signal(cs.own, kFs);
  EmissionCanceller c;
  EmissionCanceller::Options o;
  o.taps_before = cs.taps_before;
  o.taps_after = 16;
  c.configure(h, planner(), o);
  const std::vector<float> y = run(c, x, 1000);
  ASSERT_EQ(y.size(), n);
  ASSERT_EQ(c.cancelled(0), 1u);
  const EmissionCanceller::Fit& f = c.recent(0, 0);
  EXPECT_NEAR(static_cast<double>(f.start), t_own, 5.0);
  EXPECT_GT(f.coefficient, 0.8);

  // What is left of the own emission: output minus what should remain (other + noise).
  std::vector<double> left(n);
  for (std::size_t i = 0; i < n; ++i) left[i] = y[i] - other[i] - noise[i];
  const double e_own = energy(own, 0, n), e_left = energy(left, 0, n);
  const double cancel_db = 10.0 * std::log10(e_own / e_left);
  std::printf("[ measured ] %s own, other %s at -%.0f dB: own emission cancelled by %.1f dB (fit %.1f dB)\n",
              cs.own.type.c_str(), cs.other.type.c_str(), cs.near_far_db, cancel_db, f.cancelled_db);
  EXPECT_GT(cancel_db, min_cancel_db);
  // The other signal survives: what is left of the own emission is well below it.
  EXPECT_LT(e_left, 0.1 * energy(other, 0, n));
}

TEST(EmissionCanceller, LfmUnderDownChirp60dBNearFar) { check_case({lfm(2000, 8000), lfm(8000, 2000), 60.0}, 70.0); }
TEST(EmissionCanceller, LfmUnderDownChirp40dBNearFar) { check_case({lfm(8000, 2000), lfm(2000, 8000), 40.0}, 50.0); }
// 19 kHz carrier: the fractional delay needs taps on both sides of the start.
TEST(EmissionCanceller, GoldCodeUnderAnotherCode) { check_case({gold(0), gold(1), 40.0, 16}, 45.0); }

TEST(EmissionCanceller, NoCleanCopyPassesUnchanged) {
  // Noise with a chirp 10 dB below it: a detectable match but not a clean copy (coefficient < 0.5).
  const std::size_t n = 20000;
  std::vector<double> v(n, 0.0);
  add(v, lfm(2000, 8000), 5000.2, 0.01);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0.0, 0.02);
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>(v[i] + g(rng));
  EmissionCanceller c;
  c.configure(render_signal(lfm(2000, 8000), kFs), planner(), {});
  const std::vector<float> y = run(c, x, 777);
  ASSERT_EQ(y.size(), n);
  EXPECT_EQ(c.cancelled(0), 0u);
  for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(y[i], x[i]) << i;
}

TEST(EmissionCanceller, BlockSizeIndependentAndFlushesTheTail) {
  const std::size_t n = 12000;
  std::vector<double> v(n, 0.0);
  add(v, lfm(2000, 8000), 1500.6, 0.4);
  add(v, lfm(2000, 8000), n - 1800.0 - 40.3, 0.4);  // ends 40 samples before the end of the stream
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0.0, 1e-4);
  std::vector<float> x(n);
  for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>(v[i] + g(rng));
  EmissionCanceller::Options o;
  o.fft_size = 4096;
  EmissionCanceller a, b;
  a.configure(render_signal(lfm(2000, 8000), kFs), planner(), o);
  b.configure(render_signal(lfm(2000, 8000), kFs), planner(), o);
  const std::vector<float> ya = run(a, x, 64), yb = run(b, x, 5000);
  ASSERT_EQ(ya.size(), n);
  ASSERT_EQ(yb.size(), n);
  EXPECT_EQ(a.cancelled(0), 2u);
  EXPECT_EQ(b.cancelled(0), 2u);
  double e_in = 0.0, e_out = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_NEAR(ya[i], yb[i], 1e-6f) << i;
    e_in += double(x[i]) * x[i];
    e_out += double(ya[i]) * ya[i];
  }
  EXPECT_LT(e_out, e_in * 1e-4);  // both emissions gone (residual: the noise)
}

TEST(EmissionCanceller, RejectsBadConfiguration) {
  EmissionCanceller c;
  EXPECT_THROW(c.configure({}, planner(), {}), std::invalid_argument);
  EmissionCanceller::Options o;
  o.channels = 0;
  EXPECT_THROW(c.configure(render_signal(lfm(2000, 8000), kFs), planner(), o), std::invalid_argument);
  o.channels = 1;
  o.fft_size = 1024;  // not larger than the padded template (1764 + taps)
  EXPECT_THROW(c.configure(render_signal(lfm(2000, 8000), kFs), planner(), o), std::invalid_argument);
  o.fft_size = 0;
  o.min_coefficient = 1.5;
  EXPECT_THROW(c.configure(render_signal(lfm(2000, 8000), kFs), planner(), o), std::invalid_argument);
}

}  // namespace
}  // namespace locus::dsp
