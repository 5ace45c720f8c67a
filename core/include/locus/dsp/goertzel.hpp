// Goertzel single-bin power for tone banks (SpyLoc's 10-tone beeps, presence tests of a few known
// frequencies) where a full FFT would compute hundreds of unused bins.
//
// Two forms:
//  - goertzel_power(): one block, any (non-integer-bin) frequency; returns |X(f)|² of the block with
//    the same scaling as a DFT: a sine of amplitude A filling N samples gives ≈ (A·N/2)².
//  - SlidingGoertzel: the bin over the last N samples, updated every sample in O(1) (a recursive
//    sliding DFT with a damping factor r slightly below 1 for numerical stability). Power is scaled as
//    the block form for r → 1.
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace locus::dsp {

/// |X(f)|² of the block (Goertzel recurrence, double accumulation) [RT].
double goertzel_power(std::span<const float> x, double freq_hz, double sample_rate_hz) noexcept;

/// Complex DFT value X(f) = Σ x[n]·e^{−j2πfn/fs} of the block (Goertzel with the phase term) [RT].
std::complex<double> goertzel_bin(std::span<const float> x, double freq_hz, double sample_rate_hz) noexcept;

/// Sliding single-bin DFT over the last `window` samples. Construction allocates [main].
class SlidingGoertzel {
 public:
  SlidingGoertzel() = default;
  /// r: damping (0 < r <= 1); 0.99999 keeps rounding errors from accumulating over hours.
  SlidingGoertzel(double freq_hz, double sample_rate_hz, std::size_t window, double r = 0.999999);

  /// Push one sample, return the bin power over the last `window` samples [RT].
  double push(float x) noexcept;
  double power() const noexcept { return std::norm(bin_); }
  std::complex<double> bin() const noexcept { return bin_; }
  void reset() noexcept;  ///< [RT]
  std::size_t window() const noexcept { return history_.size(); }

 private:
  std::vector<float> history_;
  std::size_t pos_ = 0;
  std::complex<double> w_{1.0, 0.0};  // r·e^{j2πf/fs}
  std::complex<double> w_n_{1.0, 0.0};  // (r·e^{jω})^N
  std::complex<double> bin_{0.0, 0.0};
};

/// Bank of Goertzel bins over the same block (one pass over the data per tone) [RT for compute()].
class GoertzelBank {
 public:
  GoertzelBank() = default;
  GoertzelBank(std::vector<double> freqs_hz, double sample_rate_hz);
  /// Writes powers (size() values) of the block `x` to `power_out` [RT].
  void compute(std::span<const float> x, double* power_out) const noexcept;
  std::size_t size() const noexcept { return coeff_.size(); }
  const std::vector<double>& freqs_hz() const noexcept { return freqs_; }

 private:
  std::vector<double> freqs_;
  std::vector<double> coeff_;  // 2·cos(ω)
  std::vector<double> cosw_, sinw_;
};

}  // namespace locus::dsp
