// Correlator against direct correlation (random data, several templates, any block cut), the analytic
// output against the exact quadrature of a tone, EnvelopeFft, the peak interpolators on shapes with a
// known vertex, and the band pre-screen's statistic on white noise and on in-band energy.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "locus/dsp/correlator.hpp"
#include "locus/dsp/envelope.hpp"
#include "locus/dsp/peak.hpp"
#include "locus/dsp/prescreen.hpp"
#include "locus/fftw_planner.hpp"

namespace locus::dsp {
namespace {

std::vector<float> noise(std::size_t n, unsigned seed, double sigma = 1.0) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<float> v(n);
  for (float& x : v) x = static_cast<float>(g(rng));
  return v;
}

/// Streams x through the correlator in blocks of `block`, collecting every template's real (and
/// imaginary) output per lag, flushing at the end.
struct Collected {
  std::vector<std::vector<float>> re, im;
};
Collected stream(Correlator& c, const std::vector<float>& x, std::size_t block) {
  Collected out;
  out.re.resize(c.template_count());
  out.im.resize(c.template_count());
  auto take = [&](std::size_t count) {
    for (std::size_t t = 0; t < c.template_count(); ++t) {
      c.correlate(t);
      EXPECT_EQ(out.re[t].size(), c.window_start(0));
      out.re[t].insert(out.re[t].end(), c.real(t), c.real(t) + count);
      if (c.analytic()) out.im[t].insert(out.im[t].end(), c.imag(t), c.imag(t) + count);
    }
  };
  for (std::size_t pos = 0; pos < x.size();) {
    const std::size_t n = std::min(block, x.size() - pos);
    std::size_t done = 0;
    while (done < n) {
      done += c.push(0, x.data() + pos + done, n - done);
      if (c.full(0)) {
        c.transform(0);
        take(c.hop());
        c.advance(0);
      }
    }
    pos += n;
  }
  if (const std::size_t valid = c.flush(0)) take(valid);
  c.reset(0);
  return out;
}

TEST(Correlator, MatchesDirectCorrelationForAnyBlockCut) {
  FftwPlanner planner("", false);
  const std::vector<std::vector<float>> templates = {noise(300, 1), noise(117, 2), noise(64, 3)};
  const std::vector<float> x = noise(20000, 4);
  for (std::size_t block : {1u, 100u, 511u, 4096u}) {
    Correlator c;
    c.configure(templates, planner, {1, 1024, false});
    EXPECT_EQ(c.hop(), 1024u - 300u + 1u);
    const Collected got = stream(c, x, block);
    for (std::size_t t = 0; t < templates.size(); ++t) {
      std::vector<float> ref(x.size() - templates[t].size() + 1);
      correlate_direct(x.data(), x.size(), templates[t].data(), templates[t].size(), ref.data());
      // Every lag whose longest template fits in x: x.size() - 300 + 1 of them.
      ASSERT_EQ(got.re[t].size(), x.size() - 300 + 1) << "block " << block;
      double maxerr = 0, scale = 0;
      for (std::size_t k = 0; k < got.re[t].size(); ++k) {
        maxerr = std::max(maxerr, double(std::abs(got.re[t][k] - ref[k])));
        scale = std::max(scale, double(std::abs(ref[k])));
      }
      EXPECT_LT(maxerr, 1e-4 * scale) << "template " << t << " block " << block;
    }
  }
}

TEST(Correlator, OverlappedWindowsOutputEveryLagOnceAsSoonAsItsTemplateIsWhole) {
  // Options::hop: the same outputs as plain overlap-save, each lag output once, from lag 0 on, and a
  // lag leaves in the first window whose samples cover its template (the live latency it buys).
  FftwPlanner planner("", false);
  const std::vector<std::vector<float>> templates = {noise(300, 1), noise(117, 2)};
  const std::vector<float> x = noise(9000, 4);
  for (std::size_t hop : {1u, 100u, 37u, 725u, 5000u}) {
    for (std::size_t block : {1u, 256u, 4096u}) {
      Correlator c;
      Correlator::Options opt{1, 1024, true};
      opt.hop = hop;
      c.configure(templates, planner, opt);
      const std::size_t full = 1024 - 300 + 1;
      EXPECT_LE(c.hop(), std::min(hop, full));
      EXPECT_GE(c.hop() + 3, std::min(hop, full));
      const Collected got = stream(c, x, block);
      for (std::size_t t = 0; t < templates.size(); ++t) {
        std::vector<float> ref(x.size() - templates[t].size() + 1);
        correlate_direct(x.data(), x.size(), templates[t].data(), templates[t].size(), ref.data());
        ASSERT_EQ(got.re[t].size(), x.size() - 300 + 1) << "hop " << hop << " block " << block;
        ASSERT_EQ(got.im[t].size(), got.re[t].size());
        double maxerr = 0, scale = 0;
        for (std::size_t k = 0; k < got.re[t].size(); ++k) {
          maxerr = std::max(maxerr, double(std::abs(got.re[t][k] - ref[k])));
          scale = std::max(scale, double(std::abs(ref[k])));
        }
        EXPECT_LT(maxerr, 1e-4 * scale) << "template " << t << " hop " << hop << " block " << block;
      }
    }
    // Latency: after pushing the samples of lag k's template (k + 300 of them), lag k has been output
    // once at most hop() - 1 more samples arrived.
    Correlator c;
    Correlator::Options opt{1, 1024, true};
    opt.hop = hop;
    c.configure(templates, planner, opt);
    std::size_t pushed = 0, worst_wait = 0;
    std::uint64_t next_lag = 0;
    while (pushed < x.size()) {
      pushed += c.push(0, x.data() + pushed, 1);
      if (c.full(0)) {
        c.transform(0);
        for (std::uint64_t k = next_lag; k < c.window_start(0) + c.hop(); ++k) worst_wait = std::max(worst_wait, pushed - (k + 300));
        next_lag = c.window_start(0) + c.hop();
        c.advance(0);
      }
    }
    EXPECT_LT(worst_wait, c.hop()) << "hop " << hop;
  }
}

TEST(Correlator, DirectCorrelationIsTheDefinition) {
  const std::vector<float> x = {1, 2, 3, 4, 5}, h = {1, -1};
  std::vector<float> y(4);
  correlate_direct(x.data(), x.size(), h.data(), h.size(), y.data());
  EXPECT_EQ(y, (std::vector<float>{-1, -1, -1, -1}));
}

TEST(Correlator, AnalyticOutputIsTheQuadratureOfATone) {
  // x = cos(w n), h = Hann-windowed cos: y[k] = A cos(w k + p), H{y}[k] = A sin(w k + p), |z| = A.
  FftwPlanner planner("", false);
  const double w = 2 * std::numbers::pi * 3000.0 / 44100.0;
  std::vector<float> h(200), x(30000);
  for (std::size_t j = 0; j < h.size(); ++j)
    h[j] = float(std::cos(w * j) * 0.5 * (1 - std::cos(2 * std::numbers::pi * j / (h.size() - 1))));
  for (std::size_t n = 0; n < x.size(); ++n) x[n] = float(std::cos(w * n));
  Correlator c;
  c.configure({h}, planner, {1, 2048, true});
  const Collected got = stream(c, x, 777);
  const double amp = std::abs(std::complex<double>(got.re[0][1000], got.im[0][1000]));
  double worst_env = 0, worst_phase = 0;
  for (std::size_t k = 0; k < got.re[0].size(); ++k) {
    const std::complex<double> z(got.re[0][k], got.im[0][k]);
    worst_env = std::max(worst_env, std::abs(std::abs(z) - amp) / amp);
    // Phase advances by w per lag.
    if (k > 0) {
      const std::complex<double> zp(got.re[0][k - 1], got.im[0][k - 1]);
      worst_phase = std::max(worst_phase, std::abs(std::arg(z * std::conj(zp)) - w));
    }
  }
  EXPECT_LT(worst_env, 0.01);
  EXPECT_LT(worst_phase, 0.01);
  EXPECT_NEAR(c.centroid_omega(0), w, 0.02);
}

/// Uses FftPlanner's default plan_complex (two real transforms) instead of FFTW's native one.
struct RealOnlyPlanner final : FftPlanner {
  FftwPlanner inner{"", false};
  std::unique_ptr<RealFft> plan_real(std::size_t n) override { return inner.plan_real(n); }
};

TEST(Correlator, BasebandOutputIsTheDecimatedAnalyticOutput) {
  // A Hann-windowed 2-8 kHz sweep at 44.1 kHz in noise: the baseband output at every D-th lag must
  // match the full-rate analytic output, with FFTW's complex FFT and with the default one.
  const double fs = 44100.0;
  std::vector<float> h(1000);
  for (std::size_t j = 0; j < h.size(); ++j) {
    const double t = double(j) / fs, dur = double(h.size()) / fs;
    const double ph = 2 * std::numbers::pi * (2000.0 * t + 0.5 * (6000.0 / dur) * t * t);
    h[j] = float(std::cos(ph) * 0.5 * (1 - std::cos(2 * std::numbers::pi * double(j) / double(h.size() - 1))));
  }
  std::vector<float> x = noise(20000, 7, 0.3);
  for (std::size_t j = 0; j < h.size(); ++j) x[5000 + j] += h[j];
  FftwPlanner fftw("", false);
  RealOnlyPlanner real_only;
  for (FftPlanner* planner : {static_cast<FftPlanner*>(&fftw), static_cast<FftPlanner*>(&real_only)})
  for (std::size_t hop : {std::size_t{0}, std::size_t{801}}) {  // plain, and overlapped windows
    Correlator c;
    Correlator::Options opt{1, 4096, true};
    opt.baseband = true;
    opt.hop = hop;
    c.configure({h}, *planner, opt);
    const std::size_t d = c.baseband_decimation(0);
    ASSERT_EQ(d, 4u);  // 2-8 kHz (+ skirts) fits in N/4 bins = 11 kHz
    EXPECT_GT(c.baseband_peak_ratio(0), 0.5);
    EXPECT_LE(c.baseband_peak_ratio(0), 1.0);
    double peak = 0, worst = 0, worst_lag = 0;
    std::size_t pos = 0, windows = 0;
    while (pos < x.size()) {
      pos += c.push(0, x.data() + pos, x.size() - pos);
      if (!c.full(0)) break;
      c.transform(0);
      c.correlate(0);
      c.correlate_baseband(0);
      for (std::size_t i = 0; i < c.hop(); ++i) peak = std::max(peak, double(std::hypot(c.real(0)[i], c.imag(0)[i])));
      for (std::size_t m = 0; m * d < c.hop(); ++m) {
        const double full = std::hypot(c.real(0)[m * d], c.imag(0)[m * d]);
        worst = std::max(worst, std::abs(std::abs(std::complex<double>(c.baseband(0)[m])) - full));
      }
      for (std::size_t i : {std::size_t{0}, std::size_t{1}, std::size_t{777} % c.hop(), c.hop() - 1}) {
        const std::complex<double> z = c.baseband_lag(0, i);
        worst_lag = std::max(worst_lag, std::abs(z - std::complex<double>(c.real(0)[i], c.imag(0)[i])));
      }
      c.advance(0);
      ++windows;
    }
    EXPECT_GE(windows, 5u) << "hop " << hop;
    EXPECT_LT(worst, 1e-2 * peak) << "hop " << hop;
    EXPECT_LT(worst_lag, 1e-2 * peak);
  }
}

TEST(Correlator, RejectsBadSetups) {
  FftwPlanner planner("", false);
  Correlator c;
  EXPECT_THROW(c.configure({}, planner, {}), std::invalid_argument);
  EXPECT_THROW(c.configure({{}}, planner, {}), std::invalid_argument);
  EXPECT_THROW(c.configure({noise(600, 1)}, planner, {1, 512, true}), std::invalid_argument);
  EXPECT_THROW(c.configure({noise(60, 1)}, planner, {0, 512, true}), std::invalid_argument);
  c.configure({noise(600, 1)}, planner, {});
  EXPECT_EQ(c.fft_size(), 4096u);  // bit_ceil(4 * 600)
}

TEST(EnvelopeFft, RecoversTheModulationOfAnAmTone) {
  FftwPlanner planner("", false);
  EnvelopeFft env;
  env.configure(4096, planner);
  std::vector<float> x(4096), e(4096);
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double m = 1.0 + 0.5 * std::sin(2 * std::numbers::pi * 20.0 * n / 44100.0);
    x[n] = float(m * std::cos(2 * std::numbers::pi * 5000.0 * n / 44100.0));
  }
  env.envelope(x.data(), x.size(), e.data());
  double worst = 0;
  for (std::size_t n = 300; n + 300 < x.size(); ++n) {  // away from the block edges
    const double m = 1.0 + 0.5 * std::sin(2 * std::numbers::pi * 20.0 * n / 44100.0);
    worst = std::max(worst, std::abs(e[n] - m));
  }
  EXPECT_LT(worst, 0.02);
  std::vector<float> mag(3);
  const float re[3] = {3, 0, 1}, im[3] = {4, 2, 0};
  magnitude(re, im, 3, mag.data());
  EXPECT_FLOAT_EQ(mag[0], 5.0f);
  EXPECT_FLOAT_EQ(mag[1], 2.0f);
}

TEST(Peak, ParabolicAndGaussianAreExactOnTheirShapes) {
  for (double d : {-0.45, -0.2, 0.0, 0.13, 0.49}) {
    auto par = [&](double x) { return 5.0 - 2.0 * (x - d) * (x - d); };
    const PeakFit p = parabolic_peak(par(-1), par(0), par(1));
    EXPECT_NEAR(p.offset, d, 1e-12);
    EXPECT_NEAR(p.value, 5.0, 1e-12);
    auto gau = [&](double x) { return 3.0 * std::exp(-(x - d) * (x - d) / 4.0); };
    const PeakFit g = gaussian_peak(gau(-1), gau(0), gau(1));
    EXPECT_NEAR(g.offset, d, 1e-12);
    EXPECT_NEAR(g.value, 3.0, 1e-12);
  }
  EXPECT_EQ(parabolic_peak(1, 1, 1).offset, 0.0);  // flat: no vertex
}

TEST(Peak, SincPeakFindsABandLimitedPulse) {
  // A sampled sinc pulse (band-limited at Nyquist*0.8) centred at 50.3: parabola is biased, sinc is not.
  std::vector<float> x(100);
  const double c = 50.3, b = 0.8;
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double u = b * (double(n) - c);
    x[n] = float(std::abs(u) < 1e-12 ? 1.0 : std::sin(std::numbers::pi * u) / (std::numbers::pi * u));
  }
  const PeakFit s = sinc_peak(x.data(), x.size(), 50, 24);
  EXPECT_NEAR(50 + s.offset, c, 0.01);
  const PeakFit p = parabolic_peak(x[49], x[50], x[51]);
  EXPECT_GT(std::abs(50 + p.offset - c), std::abs(50 + s.offset - c));
}

TEST(Peak, PhaseRefinementUndoesALinearPhase) {
  const double w = 2 * std::numbers::pi * 20000.0 / 44100.0;  // 2.2 samples per carrier cycle
  for (double d : {-0.4, -0.1, 0.0, 0.25, 0.45}) {
    // z at lag 0 of an analytic correlation peaking at lag d: phase w * (0 - d).
    const std::complex<double> z = std::polar(2.0, w * (0.0 - d));
    EXPECT_NEAR(phase_refine(z.real(), z.imag(), w), d, 1e-12);
    // Coarse estimate off by 0.3 samples still picks the right carrier cycle.
    EXPECT_NEAR(phase_refine_near(z.real(), z.imag(), w, d + 0.3), d, 1e-12);
    // From a neighbouring lag (k0 = 1): the offset is d - 1.
    const std::complex<double> z1 = std::polar(2.0, w * (1.0 - d));
    EXPECT_NEAR(phase_refine_near(z1.real(), z1.imag(), w, d - 1.0 + 0.2), d - 1.0, 1e-12);
  }
}

TEST(Peak, AnalyticPeakIsTheSameForEveryFractionalDelayOfASkewedShape) {
  // A skewed envelope (a transducer or a close reflection): its maximum is not at the delay, and a
  // 3-point fit of it moves with the fractional delay; the band-limited baseband maximum does not.
  const double w = 2.0 * std::numbers::pi * 20000.0 / 44100.0;
  auto envelope = [](double t) {
    const double x = std::numbers::pi * 4000.0 / 44100.0 * t;
    const double s = std::fabs(x) < 1e-12 ? 1.0 : std::sin(x) / x;
    return s * (1.0 + 0.3 * std::tanh(t / 6.0));
  };
  double lo_ap = 1e9, hi_ap = -1e9, lo_g = 1e9, hi_g = -1e9, first_cycle = 0.0;
  for (int i = 0; i < 20; ++i) {
    const double tau = 40.0 + 0.05 * i;
    std::vector<std::complex<float>> z(80);
    for (std::size_t k = 0; k < z.size(); ++k) {
      const double t = static_cast<double>(k) - tau;
      z[k] = std::complex<float>(std::polar(envelope(t), w * t));
    }
    std::size_t k0 = 0;
    for (std::size_t k = 1; k < z.size(); ++k)
      if (std::abs(z[k]) > std::abs(z[k0])) k0 = k;
    const AnalyticPeak ap = analytic_peak(z.data(), z.size(), k0, w);
    const double env_ap = static_cast<double>(k0) + ap.envelope - tau;
    // a phase zero of the delay, in the same carrier cycle for every fractional delay
    const double period = 2.0 * std::numbers::pi / w;
    const double cycles = (static_cast<double>(k0) + ap.delay - tau) / period;
    EXPECT_NEAR(cycles, std::round(cycles), 1e-3);
    if (i == 0) first_cycle = std::round(cycles);
    EXPECT_EQ(std::round(cycles), first_cycle);
    const PeakFit g = gaussian_peak(std::abs(z[k0 - 1]), std::abs(z[k0]), std::abs(z[k0 + 1]));
    const double env_g = static_cast<double>(k0) + g.offset - tau;
    lo_ap = std::min(lo_ap, env_ap), hi_ap = std::max(hi_ap, env_ap);
    lo_g = std::min(lo_g, env_g), hi_g = std::max(hi_g, env_g);
  }
  EXPECT_LT(hi_ap - lo_ap, 0.01) << "envelope offset depends on the fractional delay";
  EXPECT_GT(hi_g - lo_g, 2.0 * (hi_ap - lo_ap));  // the 3-point fit's does (why analytic_peak exists)
  // too close to an end: falls back to a 3-point fit and still returns the phase zero near it
  std::vector<std::complex<float>> z(5);
  for (std::size_t k = 0; k < z.size(); ++k) z[k] = std::complex<float>(std::polar(envelope(k - 1.2), w * (k - 1.2)));
  EXPECT_NEAR(1.0 + analytic_peak(z.data(), z.size(), 1, w).delay, 1.2, 1e-3);
}

TEST(BandPrescreen, WhiteNoiseIsNearZeroAndInBandEnergyPasses) {
  FftwPlanner planner("", false);
  auto fft = planner.plan_real(8192);
  std::vector<std::complex<float>> spec(4097);
  BandPrescreen p;
  p.configure(8192, 44100.0, 2000, 8000, 1.0);
  const auto x = noise(8192, 7);
  fft->forward(x.data(), spec.data());
  EXPECT_NEAR(p.ratio_db(spec.data()), 0.0, 0.5);
  EXPECT_FALSE(p.pass(spec.data()));
  p.note_quiet(true);
  // Add a 5 kHz tone with 1/4 of the noise power: the band gains ~ 0.25 * 22050/6000 ~ +0.9 of its power.
  std::vector<float> y = x;
  for (std::size_t n = 0; n < y.size(); ++n) y[n] += float(std::sqrt(0.5) * std::cos(2 * std::numbers::pi * 5000.0 * n / 44100.0));
  fft->forward(y.data(), spec.data());
  EXPECT_GT(p.ratio_db(spec.data()), 2.0);
  EXPECT_TRUE(p.pass(spec.data()));
  // Silence never passes.
  std::vector<std::complex<float>> zero(4097);
  EXPECT_FALSE(p.pass(zero.data()));
  EXPECT_THROW(p.configure(8192, 44100.0, 9000, 8000, 1.0), std::invalid_argument);
}

TEST(BandPrescreen, BaselineLearnsColouredNoise) {
  BandPrescreen p;
  p.configure(1024, 44100.0, 2000, 8000, 1.0);
  std::vector<std::complex<float>> spec(513, {1.0f, 0.0f});
  // Colour: the band 4 dB above the rest. Correlated windows without detections teach it slowly.
  for (std::size_t k = 47; k <= 185; ++k) spec[k] = {float(std::pow(10.0, 4.0 / 20.0)), 0.0f};
  EXPECT_NEAR(p.ratio_db(spec.data()), 4.0, 0.01);
  EXPECT_TRUE(p.pass(spec.data()));
  for (int i = 0; i < 400; ++i) {
    p.pass(spec.data());
    p.note_quiet(false);
  }
  EXPECT_NEAR(p.baseline_db(), 4.0, 0.1);
  EXPECT_FALSE(p.pass(spec.data()));
  p.reset();
  EXPECT_EQ(p.baseline_db(), 0.0);
}

}  // namespace
}  // namespace locus::dsp
