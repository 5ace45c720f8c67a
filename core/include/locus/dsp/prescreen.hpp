// FFT band-energy pre-screen (AMIL, Sec. "FFT-based acceleration for beep detection", Table II).
//
// Why: most audio windows hold no beep. AMIL transforms each block, checks whether the chirp's band
// carries high energy, and only then runs the cross-correlation; Table II reports a >90 % cut in
// computing time. With overlap-save the forward FFT of the window is computed anyway (Correlator::
// transform), so the pre-screen costs one pass over the bins and saves the per-template multiply and
// inverse FFT(s) of windows whose band is empty.
//
// Statistic: the band's mean power per bin relative to the mean power per bin outside the band (bins
// below `min_hz` excluded: DC offset and rumble are not evidence against a beep),
//     r_dB = 10 log10( mean_{f in band} |X(f)|^2 / mean_{f out of band, f >= min_hz} |X(f)|^2 ).
// Coloured noise gives a non-zero r_dB without any beep, so the decision is taken against a BASELINE
// learnt from windows that held no detection: pass  <=>  r_dB - baseline_dB >= threshold_dB. The
// baseline starts at 0 dB (white noise), follows quiet windows with an exponential average and drops
// at once to a lower quiet value (see note_quiet()). A window fully containing a chirp of in-window energy share q and
// band share b = bandwidth / (fs/2) raises r_dB by about 10 log10(1 + q * SNR / b); choose the
// threshold well below that for the weakest chirp that must be found (docs/detectors.md).
#pragma once

#include <complex>
#include <cstddef>

namespace locus::dsp {

class BandPrescreen {
 public:
  /// [main] An FFT of fft_size at sample_rate_hz; band [band_lo_hz, band_hi_hz]; out-of-band bins
  /// from min_hz up to Nyquist. Throws std::invalid_argument when the band or the out-of-band region
  /// holds no bin.
  void configure(std::size_t fft_size, double sample_rate_hz, double band_lo_hz, double band_hi_hz,
                 double threshold_db, double min_hz = 100.0, double baseline_alpha = 0.1);

  /// [RT] r_dB of a spectrum of fft_size/2 + 1 bins (see above).
  double ratio_db(const std::complex<float>* spectrum) const noexcept;
  /// [RT] ratio_db(spectrum) - baseline_db() >= threshold_db. Stores the ratio for note_quiet().
  bool pass(const std::complex<float>* spectrum) noexcept;
  /// [RT] The window last given to pass() held no detection: learn its ratio into the baseline.
  /// A lower ratio is taken at once; a higher one is approached with `baseline_alpha` when the window
  /// was skipped (skipped = true) and 10x more slowly when it was correlated, so windows holding only
  /// part of a chirp (no detection, but some band energy) cannot drag the baseline up quickly.
  void note_quiet(bool skipped) noexcept;
  /// [RT] Back to the initial baseline (0 dB).
  void reset() noexcept;

  double baseline_db() const noexcept { return baseline_db_; }
  double last_ratio_db() const noexcept { return last_db_; }
  double threshold_db() const noexcept { return threshold_db_; }

 private:
  std::size_t lo_bin_ = 0, hi_bin_ = 0, min_bin_ = 1, bins_ = 0;
  double threshold_db_ = 0.0, alpha_ = 0.1, baseline_db_ = 0.0, last_db_ = 0.0;
};

}  // namespace locus::dsp
