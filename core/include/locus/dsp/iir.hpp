// IIR filters of the DSP toolbox: Butterworth design of any order as second-order sections (SOS), a
// streaming SOS filter (direct form II transposed, double state) and zero-phase filtfilt.
//
// Why SOS: high-order band-passes near fs/2 (Montage's ~19 kHz carrier at 44.1 kHz) are numerically
// hopeless as one transfer-function polynomial; cascaded biquads are stable and precise.
//
// Design follows the analog-prototype route of scipy.signal.butter: Butterworth poles on the unit
// circle of the s-plane, frequency transform (lp/hp/bp/bs) with pre-warped edges, bilinear transform,
// pole/zero pairing into sections. The coefficients agree with
// scipy.signal.butter(N, Wn, btype, output='sos', fs=fs) up to section order and rounding
// (tests/core/dsp_filters checks responses against scipy).
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace locus::dsp {

/// One second-order section, a0 = 1:
///   H(z) = (b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)
struct Biquad {
  double b0 = 1.0, b1 = 0.0, b2 = 0.0, a1 = 0.0, a2 = 0.0;
};

/// Butterworth low-pass of `order` >= 1 with -3 dB at `cutoff_hz` (0 < cutoff < fs/2).
/// Returns ceil(order/2) sections (an odd order has one first-order section, b2 = a2 = 0).
/// Throws std::invalid_argument naming the bad parameter.
std::vector<Biquad> butter_lowpass(int order, double cutoff_hz, double sample_rate_hz);

/// Butterworth high-pass, same conventions as butter_lowpass.
std::vector<Biquad> butter_highpass(int order, double cutoff_hz, double sample_rate_hz);

/// Butterworth band-pass from the low-pass prototype of `order` (the filter has order 2·order and
/// `order` sections), -3 dB at low_hz and high_hz (0 < low < high < fs/2).
std::vector<Biquad> butter_bandpass(int order, double low_hz, double high_hz, double sample_rate_hz);

/// Butterworth band-stop, same conventions as butter_bandpass.
std::vector<Biquad> butter_bandstop(int order, double low_hz, double high_hz, double sample_rate_hz);

/// Complex frequency response of a cascade at `freq_hz`.
std::complex<double> sos_response(std::span<const Biquad> sos, double freq_hz, double sample_rate_hz);

/// Streaming cascade of biquads, direct form II transposed with double state.
/// Construction allocates [main]; process/reset never allocate [RT].
class SosFilter {
 public:
  SosFilter() = default;
  explicit SosFilter(std::vector<Biquad> sections);

  /// One sample through the cascade [RT].
  float process(float x) noexcept;
  /// Block; `in` and `out` may be the same buffer [RT].
  void process(const float* in, float* out, std::size_t n) noexcept;
  /// Double-precision one sample (no rounding between calls) [RT].
  double process_double(double x) noexcept;
  /// Zero the state [RT].
  void reset() noexcept;
  /// Set the state to the steady state for a constant input `x` (as scipy's sosfilt_zi · x) [RT].
  void set_steady_state(double x) noexcept;

  const std::vector<Biquad>& sections() const noexcept { return sections_; }
  std::size_t size() const noexcept { return sections_.size(); }

 private:
  std::vector<Biquad> sections_;
  std::vector<double> state_;  // 2 per section: z1, z2
};

/// Zero-phase filtering (offline [main]): forward then backward through `sos` with odd-extension
/// padding of 3·(2·sections+1) samples (scipy's default padlen for sosfiltfilt, clipped to n−1)
/// and steady-state initial conditions, as scipy.signal.sosfiltfilt. Returns a vector of x.size().
std::vector<float> filtfilt(std::span<const Biquad> sos, std::span<const float> x);

}  // namespace locus::dsp
