// Analytic-signal envelope of a block (Hilbert transform via FFT).
//
// Why: passband signals (chirps at 2-8 kHz or 18-22 kHz sampled at 44.1 kHz) have a correlation that
// oscillates at the carrier; its envelope |x + j H{x}| is smooth and peaks where the signal is, so
// peaks are found and interpolated on the envelope, not on the raw oscillation.
//
// The block is transformed as one frame (no streaming): zero padding to the FFT size makes the
// transform linear rather than circular; the first and last few samples of a block carry the usual
// edge effects of a finite Hilbert transformer. For streams, Correlator produces the analytic
// correlation directly (no separate envelope pass).
#pragma once

#include <complex>
#include <cstddef>
#include <memory>
#include <vector>

#include "locus/fft.hpp"

namespace locus::dsp {

class EnvelopeFft {
 public:
  EnvelopeFft();
  ~EnvelopeFft();
  EnvelopeFft(EnvelopeFft&&) noexcept;
  EnvelopeFft& operator=(EnvelopeFft&&) noexcept;

  /// [main] Blocks of up to max_frames samples; plans one FFT of size bit_ceil(2 * max_frames)
  /// (zero padding against circular wrap). Throws std::invalid_argument for max_frames == 0.
  void configure(std::size_t max_frames, FftPlanner& planner);
  std::size_t max_frames() const noexcept { return max_frames_; }

  /// [RT] Hilbert transform H{x} of x[0..n-1] into `hilbert` (n <= max_frames).
  void hilbert(const float* x, std::size_t n, float* hilbert) noexcept;
  /// [RT] Envelope |x + j H{x}| of x[0..n-1] into `env` (n <= max_frames; env may alias x).
  void envelope(const float* x, std::size_t n, float* env) noexcept;

 private:
  std::size_t max_frames_ = 0, n_ = 0;
  std::unique_ptr<RealFft> fft_;
  std::vector<float> time_, hil_;
  std::vector<std::complex<float>> spec_;
};

/// [RT] env[i] = sqrt(re[i]^2 + im[i]^2) (the envelope of an analytic pair, e.g. Correlator output).
void magnitude(const float* re, const float* im, std::size_t n, float* env) noexcept;
/// [RT] pow[i] = re[i]^2 + im[i]^2.
void magnitude_squared(const float* re, const float* im, std::size_t n, float* pow) noexcept;

}  // namespace locus::dsp
