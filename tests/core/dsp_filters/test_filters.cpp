// Unit tests of the DSP filters: Butterworth responses at the band edges, stability, streaming vs block,
// filtfilt zero phase, FIR design properties, decimator alignment, Goertzel block and sliding forms.
// (The coefficient-level comparison with scipy is reference/check_filters.py.)
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "locus/dsp/fir.hpp"
#include "locus/dsp/goertzel.hpp"
#include "locus/dsp/iir.hpp"

namespace locus::dsp {
namespace {

constexpr double kPi = std::numbers::pi;

double db(std::complex<double> h) { return 20.0 * std::log10(std::abs(h)); }

TEST(Butterworth, MinusThreeDbAtEdgesAndMonotoneSkirts) {
  for (int order : {1, 2, 3, 4, 5, 8, 12}) {
    const auto lp = butter_lowpass(order, 2000.0, 44100.0);
    EXPECT_EQ(lp.size(), static_cast<std::size_t>((order + 1) / 2));
    EXPECT_NEAR(db(sos_response(lp, 0.0, 44100.0)), 0.0, 1e-9);
    EXPECT_NEAR(db(sos_response(lp, 2000.0, 44100.0)), -3.0103, 1e-3) << order;
    // Butterworth: -20·N dB/decade far above the cut-off (before the bilinear warping bites).
    EXPECT_LT(db(sos_response(lp, 8000.0, 44100.0)), -10.0 * order) << order;
    const auto hp = butter_highpass(order, 500.0, 44100.0);
    EXPECT_NEAR(db(sos_response(hp, 22050.0, 44100.0)), 0.0, 1e-9);
    EXPECT_NEAR(db(sos_response(hp, 500.0, 44100.0)), -3.0103, 1e-3);
    const auto bp = butter_bandpass(order, 18000.0, 20000.0, 44100.0);
    EXPECT_EQ(bp.size(), static_cast<std::size_t>(order));
    EXPECT_NEAR(db(sos_response(bp, 18000.0, 44100.0)), -3.0103, 1e-3);
    EXPECT_NEAR(db(sos_response(bp, 20000.0, 44100.0)), -3.0103, 1e-3);
    EXPECT_LT(db(sos_response(bp, 15000.0, 44100.0)), -6.0 * order);
    const auto bs = butter_bandstop(order, 900.0, 1100.0, 8000.0);
    EXPECT_NEAR(db(sos_response(bs, 0.0, 8000.0)), 0.0, 1e-9);
    // The notch sits at the bilinear image of the analog geometric centre.
    const double w1 = 2 * 8000.0 * std::tan(kPi * 900.0 / 8000.0), w2 = 2 * 8000.0 * std::tan(kPi * 1100.0 / 8000.0);
    const double notch = 8000.0 / kPi * std::atan(std::sqrt(w1 * w2) / (2 * 8000.0));
    EXPECT_LT(db(sos_response(bs, notch, 8000.0)), -100.0);
    for (const auto* s : {&lp, &hp, &bp, &bs})
      for (const Biquad& b : *s) {
        // Stability: both poles inside the unit circle (|a2| < 1, |a1| < 1 + a2).
        EXPECT_LT(std::abs(b.a2), 1.0);
        EXPECT_LT(std::abs(b.a1), 1.0 + b.a2 + 1e-12);
      }
  }
}

TEST(Butterworth, RejectsBadArguments) {
  EXPECT_THROW(butter_lowpass(0, 100.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(butter_lowpass(2, 600.0, 1000.0), std::invalid_argument);
  EXPECT_THROW(butter_bandpass(2, 300.0, 200.0, 1000.0), std::invalid_argument);
  try {
    butter_highpass(2, -1.0, 1000.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cutoff_hz"), std::string::npos);
  }
}

TEST(SosFilter, SineGainMatchesResponseAndBlockEqualsSamples) {
  const auto bp = butter_bandpass(4, 18000.0, 20000.0, 44100.0);
  SosFilter a(bp), b(bp);
  const double f = 19000.0;
  std::vector<float> x(8000), ya(8000), yb(8000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(std::sin(2 * kPi * f * i / 44100.0));
  a.process(x.data(), ya.data(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) yb[i] = b.process(x[i]);
  EXPECT_EQ(ya, yb);
  double p = 0.0;
  for (std::size_t i = 4000; i < 8000; ++i) p += static_cast<double>(ya[i]) * ya[i];
  const double gain = std::sqrt(2.0 * p / 4000.0);
  EXPECT_NEAR(gain, std::abs(sos_response(bp, f, 44100.0)), 2e-3);
  a.reset();
  EXPECT_EQ(a.process(0.0f), 0.0f);
}

TEST(SosFilter, SteadyStateStartHasNoTransient) {
  SosFilter f(butter_lowpass(3, 100.0, 1000.0));
  f.set_steady_state(0.7);
  for (int i = 0; i < 50; ++i) EXPECT_NEAR(f.process_double(0.7), 0.7, 1e-12);
}

TEST(Filtfilt, ZeroPhaseOnAPulse) {
  // A symmetric pulse stays centred after filtfilt (zero phase), while one pass delays it.
  std::vector<float> x(2001, 0.0f);
  for (int i = -30; i <= 30; ++i) x[1000 + i] = static_cast<float>(std::exp(-0.5 * (i / 10.0) * (i / 10.0)));
  const auto sos = butter_lowpass(4, 800.0, 44100.0);
  const auto y = filtfilt(sos, x);
  ASSERT_EQ(y.size(), x.size());
  const auto peak = std::max_element(y.begin(), y.end()) - y.begin();
  EXPECT_EQ(peak, 1000);
  for (int i = 1; i < 200; ++i) EXPECT_NEAR(y[1000 + i], y[1000 - i], 1e-5);
  EXPECT_TRUE(filtfilt(sos, std::vector<float>{}).empty());
  EXPECT_EQ(filtfilt(sos, std::vector<float>{1.0f}).size(), 1u);
}

TEST(Fir, DesignPropertiesAndStreamingDelay) {
  const auto h = fir_lowpass(101, 3000.0, 44100.0, {FirWindow::kaiser, kaiser_beta(80.0)});
  ASSERT_EQ(h.size(), 101u);
  double dc = 0.0;
  for (std::size_t i = 0; i < h.size(); ++i) {
    dc += h[i];
    EXPECT_NEAR(h[i], h[h.size() - 1 - i], 1e-15);  // linear phase
  }
  EXPECT_NEAR(dc, 1.0, 1e-12);
  // Stop band: response at 6 kHz below -70 dB.
  std::complex<double> r(0.0, 0.0);
  for (std::size_t i = 0; i < h.size(); ++i) r += h[i] * std::exp(std::complex<double>(0.0, -2 * kPi * 6000.0 * i / 44100.0));
  EXPECT_LT(db(r), -70.0);
  // The streaming filter delays an impulse by its taps: output = h.
  FirFilter f(h);
  for (std::size_t i = 0; i < h.size(); ++i) EXPECT_NEAR(f.process(i == 0 ? 1.0f : 0.0f), h[i], 1e-7);
  EXPECT_DOUBLE_EQ(f.group_delay_samples(), 50.0);
  EXPECT_THROW(fir_highpass(64, 1000.0, 8000.0), std::invalid_argument);
  EXPECT_THROW(fir_bandpass(31, 2000.0, 1000.0, 8000.0), std::invalid_argument);
}

TEST(FirDecimator, EqualsFilterThenPickEveryFactorth) {
  const auto h = fir_lowpass(48, 1000.0, 16000.0, {FirWindow::blackman});
  FirFilter f(h);
  FirDecimator d(h, 5);
  std::mt19937 rng(1);
  std::normal_distribution<float> g;
  std::vector<float> x(1003);
  for (float& v : x) v = g(rng);
  std::vector<float> full(x.size()), dec(x.size());
  f.process(x.data(), full.data(), x.size());
  d.set_next_output(2);  // outputs at input indices 2, 7, 12, ...
  std::size_t k = 0;
  for (std::size_t pos = 0; pos < x.size(); pos += 17)
    k += d.process(x.data() + pos, std::min<std::size_t>(17, x.size() - pos), dec.data() + k);
  ASSERT_EQ(k, (x.size() - 2 + 4) / 5);
  for (std::size_t j = 0; j < k; ++j) EXPECT_NEAR(dec[j], full[2 + 5 * j], 1e-5);
}

TEST(Goertzel, BlockSlidingAndBankAgreeWithDft) {
  const double fs = 44100.0, f = 18250.0;
  std::vector<float> x(2048);
  for (std::size_t i = 0; i < x.size(); ++i)
    x[i] = static_cast<float>(0.5 * std::sin(2 * kPi * f * i / fs + 0.3) + 0.2 * std::sin(2 * kPi * 18500.0 * i / fs));
  std::complex<double> dft(0.0, 0.0);
  for (std::size_t i = 0; i < 512; ++i) dft += static_cast<double>(x[i]) * std::exp(std::complex<double>(0.0, -2 * kPi * f * i / fs));
  const std::span<const float> blk(x.data(), 512);
  EXPECT_NEAR(goertzel_power(blk, f, fs), std::norm(dft), 1e-6 * std::norm(dft));
  EXPECT_NEAR(std::abs(goertzel_bin(blk, f, fs) - dft), 0.0, 1e-6 * std::abs(dft));
  // Sine of amplitude A over N samples: power ≈ (A·N/2)².
  EXPECT_NEAR(std::sqrt(goertzel_power(blk, f, fs)), 0.5 * 512 / 2.0, 0.05 * 128);
  SlidingGoertzel s(f, fs, 512, 1.0);
  for (std::size_t i = 0; i < 1024; ++i) s.push(x[i]);
  const std::span<const float> last(x.data() + 512, 512);
  EXPECT_NEAR(s.power(), goertzel_power(last, f, fs), 1e-6 * goertzel_power(last, f, fs));
  GoertzelBank bank({f, 18500.0, 19000.0}, fs);
  double p[3];
  bank.compute(blk, p);
  EXPECT_DOUBLE_EQ(p[0], goertzel_power(blk, f, fs));
  EXPECT_DOUBLE_EQ(p[1], goertzel_power(blk, 18500.0, fs));
  EXPECT_DOUBLE_EQ(p[2], goertzel_power(blk, 19000.0, fs));
}

}  // namespace
}  // namespace locus::dsp
