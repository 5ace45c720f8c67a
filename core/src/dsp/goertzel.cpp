// Goertzel block and sliding single-bin DFT.
#include "locus/dsp/goertzel.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include "locus/numbers.hpp"

namespace locus::dsp {


std::complex<double> goertzel_bin(std::span<const float> x, double freq_hz, double fs) noexcept {
  const double w = 2.0 * kPi * freq_hz / fs;
  const double c = 2.0 * std::cos(w);
  double s1 = 0.0, s2 = 0.0;
  for (float v : x) {
    const double s0 = v + c * s1 - s2;
    s2 = s1;
    s1 = s0;
  }
  // y[N-1] = s1 − e^{−jw}·s2 is Σ x[n]·e^{jw(N−1−n)}; multiply by e^{−jw(N−1)} for X(f).
  const std::complex<double> y = std::complex<double>(s1 - std::cos(w) * s2, std::sin(w) * s2);
  const double n1 = x.empty() ? 0.0 : static_cast<double>(x.size() - 1);
  return y * std::exp(std::complex<double>(0.0, -w * n1));
}

double goertzel_power(std::span<const float> x, double freq_hz, double fs) noexcept {
  const double w = 2.0 * kPi * freq_hz / fs;
  const double c = 2.0 * std::cos(w);
  double s1 = 0.0, s2 = 0.0;
  for (float v : x) {
    const double s0 = v + c * s1 - s2;
    s2 = s1;
    s1 = s0;
  }
  return s1 * s1 + s2 * s2 - c * s1 * s2;
}

SlidingGoertzel::SlidingGoertzel(double freq_hz, double fs, std::size_t window, double r) {
  if (window < 1) throw std::invalid_argument("SlidingGoertzel: window must be >= 1");
  if (!(r > 0.0 && r <= 1.0)) throw std::invalid_argument("SlidingGoertzel: r must be in (0, 1]");
  if (!(fs > 0.0)) throw std::invalid_argument("SlidingGoertzel: sample_rate_hz must be > 0");
  history_.assign(window, 0.0f);
  w_ = r * std::exp(std::complex<double>(0.0, 2.0 * kPi * freq_hz / fs));
  w_n_ = std::pow(w_, static_cast<double>(window));
}

double SlidingGoertzel::push(float x) noexcept {
  // S_n = Σ_{k<N} W^k·x_{n−k} with W = r·e^{jω}: S_n = W·S_{n−1} + x_n − W^N·x_{n−N}.
  // |S_n| is the bin magnitude of the last N samples (phase-rotated), for any ω.
  const float old = history_[pos_];
  history_[pos_] = x;
  pos_ = pos_ + 1 == history_.size() ? 0 : pos_ + 1;
  bin_ = w_ * bin_ + static_cast<double>(x) - w_n_ * static_cast<double>(old);
  return std::norm(bin_);
}

void SlidingGoertzel::reset() noexcept {
  std::fill(history_.begin(), history_.end(), 0.0f);
  pos_ = 0;
  bin_ = {0.0, 0.0};
}

GoertzelBank::GoertzelBank(std::vector<double> freqs_hz, double fs) : freqs_(std::move(freqs_hz)) {
  if (!(fs > 0.0)) throw std::invalid_argument("GoertzelBank: sample_rate_hz must be > 0");
  for (double f : freqs_) {
    if (!(f >= 0.0 && f <= fs / 2.0)) throw std::invalid_argument("GoertzelBank: frequency outside 0..fs/2");
    const double w = 2.0 * kPi * f / fs;
    coeff_.push_back(2.0 * std::cos(w));
    cosw_.push_back(std::cos(w));
    sinw_.push_back(std::sin(w));
  }
}

void GoertzelBank::compute(std::span<const float> x, double* power_out) const noexcept {
  // Tones in chunks of 16 with the sample loop outside: the recursions are independent, so they
  // run side by side (vectorised) instead of one latency-bound chain per tone; per tone the
  // arithmetic is exactly the classic recursion's.
  constexpr std::size_t kChunk = 16;
  for (std::size_t t0 = 0; t0 < coeff_.size(); t0 += kChunk) {
    const std::size_t m = std::min(kChunk, coeff_.size() - t0);
    double c[kChunk] = {}, s1[kChunk] = {}, s2[kChunk] = {};
    for (std::size_t j = 0; j < m; ++j) c[j] = coeff_[t0 + j];
    for (float v : x) {
      for (std::size_t j = 0; j < kChunk; ++j) {
        const double s0 = v + c[j] * s1[j] - s2[j];
        s2[j] = s1[j];
        s1[j] = s0;
      }
    }
    for (std::size_t j = 0; j < m; ++j) power_out[t0 + j] = s1[j] * s1[j] + s2[j] * s2[j] - c[j] * s1[j] * s2[j];
  }
}

}  // namespace locus::dsp
