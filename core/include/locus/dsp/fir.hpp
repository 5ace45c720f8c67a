// FIR filters of the DSP toolbox: windowed-sinc design (low/high/band-pass/band-stop with Hamming,
// Blackman or Kaiser windows), a streaming FIR filter and a streaming decimating FIR.
//
// Why FIR next to the Butterworth IIRs: linear phase (a constant group delay of (taps−1)/2 samples
// that time-of-arrival code can subtract exactly) and safe decimation (anti-alias before dropping).
// Design matches scipy.signal.firwin(numtaps, cutoff, window=..., pass_zero=..., fs=...) with
// scale=True (unit gain at DC for low-pass/band-stop, at fs/2 for high-pass, at the band centre
// for band-pass).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace locus::dsp {

enum class FirWindow { hamming, blackman, kaiser };

struct FirWindowSpec {
  FirWindow type = FirWindow::hamming;
  double kaiser_beta = 8.6;  ///< only for kaiser
};

/// Window of `n` points (symmetric, as scipy.signal.get_window(..., fftbins=False)).
std::vector<double> fir_window(std::size_t n, FirWindowSpec w);

/// Kaiser beta for a stop-band attenuation of `atten_db` (Kaiser's formula, as scipy.signal.kaiser_beta).
double kaiser_beta(double atten_db) noexcept;

/// Windowed-sinc designs. `taps` >= 1; high-pass and band-stop need an odd `taps`.
/// Throws std::invalid_argument naming the bad parameter.
std::vector<double> fir_lowpass(std::size_t taps, double cutoff_hz, double sample_rate_hz, FirWindowSpec w = {});
std::vector<double> fir_highpass(std::size_t taps, double cutoff_hz, double sample_rate_hz, FirWindowSpec w = {});
std::vector<double> fir_bandpass(std::size_t taps, double low_hz, double high_hz, double sample_rate_hz,
                                 FirWindowSpec w = {});
std::vector<double> fir_bandstop(std::size_t taps, double low_hz, double high_hz, double sample_rate_hz,
                                 FirWindowSpec w = {});

/// Streaming FIR filter y[n] = Σ h[k]·x[n−k]. Construction allocates [main]; process/reset [RT].
/// The history is kept twice (a mirrored delay line) so that every output is one contiguous dot
/// product.
class FirFilter {
 public:
  FirFilter() = default;
  explicit FirFilter(std::vector<double> taps);

  float process(float x) noexcept;                                   ///< [RT]
  void process(const float* in, float* out, std::size_t n) noexcept; ///< [RT], in == out allowed
  void reset() noexcept;                                              ///< [RT]
  /// Group delay in samples ((taps−1)/2 for the symmetric designs above).
  double group_delay_samples() const noexcept { return (static_cast<double>(taps_.size()) - 1.0) / 2.0; }
  const std::vector<float>& taps() const noexcept { return taps_; }

 private:
  std::vector<float> taps_;     // reversed for a forward dot product
  std::vector<float> history_;  // 2·taps, mirrored
  std::size_t pos_ = 0;
};

/// Streaming decimator: FIR anti-alias filter evaluated only at every `factor`-th input sample.
/// Output k corresponds to input sample k·factor + phase (phase = 0 at construction/reset).
class FirDecimator {
 public:
  FirDecimator() = default;
  FirDecimator(std::vector<double> taps, std::size_t factor);

  /// Consumes `n` input samples, writes at most n/factor + 1 outputs to `out`, returns how many [RT].
  std::size_t process(const float* in, std::size_t n, float* out) noexcept;
  void reset() noexcept;  ///< [RT]
  /// The next output is produced on the `k`-th next input sample (0 = the very next one) [RT].
  /// Lets a caller align outputs to an absolute frame grid (frame ≡ 0 mod factor).
  void set_next_output(std::size_t k) noexcept { phase_ = (factor_ - k % factor_) % factor_; }
  std::size_t factor() const noexcept { return factor_; }
  double group_delay_samples() const noexcept { return (static_cast<double>(taps_.size()) - 1.0) / 2.0; }

 private:
  std::vector<float> taps_;
  std::vector<float> history_;
  std::size_t pos_ = 0;
  std::size_t factor_ = 1;
  std::size_t phase_ = 0;  // input samples since the last output
};

}  // namespace locus::dsp
