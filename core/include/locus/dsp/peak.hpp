// Sub-sample peak interpolation.
//
// Why: a detection is worth its timing. Sampled at 44.1 kHz, one sample is 7.8 mm of sound travel;
// ranging needs a fraction of that. Which interpolator fits depends on the shape around the peak:
//   - parabolic_peak(): 3-point parabola; fine on a smooth, broad peak (envelopes, baseband).
//   - gaussian_peak(): parabola through the LOGARITHMS of 3 positive samples; exact for a Gaussian
//     peak and less biased than the parabola on envelope-like (bell-shaped) peaks.
//   - sinc_peak(): band-limited (windowed-sinc) reconstruction of a real, Nyquist-sampled sequence,
//     maximised by golden-section search; for baseband peaks that are narrow (a few samples wide).
//   - phase_refine(): for ANALYTIC correlations of passband signals. The analytic autocorrelation
//     z(tau) = sum_{f>0} 2|H(f)|^2 e^{j 2 pi f tau} is real and positive at tau = 0 and its phase turns
//     at the spectral centroid f_c of |H|^2; so the delay is where arg z crosses zero:
//     tau = k0 - arg z[k0] / omega_c (omega_c = 2 pi f_c / fs). The envelope peak picks the carrier
//     cycle; the phase gives the fraction (its noise is ~1/(omega_c * sqrt(SNR)), far below the
//     envelope's).
// Never interpolate the RAW correlation of a passband signal with a parabola: above ~15 kHz the
// carrier period is 2-3 samples, the three samples straddle a carrier cycle and the estimate jumps by
// whole cycles with noise. Interpolate the envelope, then refine with the phase.
#pragma once

#include <complex>
#include <cstddef>

namespace locus::dsp {

/// Offset (in samples, within [-0.5, 0.5] for a true local maximum y0 >= ym1, yp1) and value of
/// the vertex of the parabola through (-1, ym1), (0, y0), (1, yp1). A flat or degenerate triple
/// gives offset 0 and value y0.
struct PeakFit {
  double offset = 0.0;
  double value = 0.0;
};
PeakFit parabolic_peak(double ym1, double y0, double yp1) noexcept;

/// Gaussian (log-parabolic) fit of three POSITIVE samples; falls back to parabolic_peak() when a
/// sample is <= 0.
PeakFit gaussian_peak(double ym1, double y0, double yp1) noexcept;

/// Band-limited peak of x[0..n-1] near integer index k0 (a local maximum): reconstructs x(t) with
/// a Hann-windowed sinc of `half_width` taps each side and maximises it in [k0 - 1, k0 + 1] by
/// golden-section search (~40 evaluations). Returns PeakFit{t_max - k0, x(t_max)}. Samples outside
/// [0, n) count as 0.
PeakFit sinc_peak(const float* x, std::size_t n, std::size_t k0, std::size_t half_width = 16) noexcept;

/// Value of the windowed-sinc reconstruction of x[0..n-1] at fractional position t.
double sinc_interpolate(const float* x, std::size_t n, double t, std::size_t half_width = 16) noexcept;

/// Phase refinement of an analytic correlation around integer lag k0: returns the offset d (samples)
/// such that the delay is k0 + d, d = -arg(z[k0]) / omega_c, with z[k0] = re + j im and
/// omega_c = 2 pi f_c / fs (radians per sample, > 0) the centroid of the template's energy spectrum.
/// Pick k0 as the sample nearest the envelope estimate so that |d| < half a carrier period.
double phase_refine(double re, double im, double omega_c) noexcept;

/// Envelope peak and carrier-phase delay of an analytic correlation, with no shape assumption.
/// z[0..n-1] are consecutive lags around the integer envelope maximum z[k0]; the carrier-free
/// baseband z[i] e^{-j omega_c (i - k0)} is smooth (its bandwidth is the signal's, far below fs for
/// an ultrasonic chirp), so a degree-6 Lagrange polynomial through the 7 lags k0-3..k0+3 reconstructs it
/// to ~1e-4 and |.| is maximised over [k0 - 1, k0 + 1] (golden section). Unlike a 3-point fit, the
/// envelope offset found is the same for every arrival through one channel whatever its fractional
/// delay (a transducer or multipath that skews the envelope biases it by a constant), so the carrier
/// cycle chosen from it is too. Needs k0 >= 3 and k0 + 3 < n; otherwise falls back to a 3-point
/// Gaussian fit of |z| with phase_refine_near().
struct AnalyticPeak {
  double envelope = 0.0;   ///< envelope maximum (offset from k0, samples)
  double delay = 0.0;      ///< delay: the zero of the carrier phase nearest the envelope maximum (offset from k0)
  double magnitude = 0.0;  ///< |z| at the envelope maximum
};
AnalyticPeak analytic_peak(const std::complex<float>* z, std::size_t n, std::size_t k0, double omega_c) noexcept;

/// Chooses among the phase candidates d + m * 2 pi / omega_c (m integer) the one nearest the
/// coarse (envelope) offset `coarse` (both relative to k0): resolves the carrier-cycle ambiguity
/// when k0 is not the nearest sample.
double phase_refine_near(double re, double im, double omega_c, double coarse) noexcept;

// ---- Multipath-robust delay of an analytic correlation --------------------------------------------
//
// Why: phase refinement trusts the envelope peak to pick the carrier cycle (one cycle = fs/f_c
// samples, 2.2 at 20 kHz). A reflection arriving within about two envelope mainlobe widths (its
// mainlobe skirt or first range sidelobes overlap the direct path's peak) biases the composite
// envelope maximum by more than half a cycle, and the phase then snaps to the wrong cycle (seen in a
// shoebox room: side-wall and floor reflections 15-30 samples after the direct path at 18-22 kHz).
// MultipathFit models the correlation around the peak as a sum of delayed copies of the template's
// own analytic autocorrelation R (tabulated exactly from the template spectrum), z[j] =
// sum_p a_p R(j - tau_p) + noise. When the single-path fit explains z to within the noise (and a small
// model tolerance) nothing changes; otherwise up to kMaxPaths paths are extracted (CLEAN then SAGE
// style coordinate refinement), the earliest significant one is the direct path, the other paths
// are subtracted and the carrier phase of the cleaned correlation gives the fine delay with the cycle
// chosen by the direct path's fitted delay. Two paths closer than ~fs/B (one mainlobe) are not
// fully separable; `margin` then reports how firmly the cycle was chosen.
}  // namespace locus::dsp

#include <array>
#include <complex>
#include <vector>

namespace locus {
class FftPlanner;
}

namespace locus::dsp {

class MultipathFit {
 public:
  static constexpr std::size_t kMaxPaths = 6;
  static constexpr double kModelTolerance = 5e-3;  ///< single-path residual tolerated beyond the noise

  /// [main] Tabulates the analytic autocorrelation of template h (as produced by a Correlator with
  /// FFT size n >= 2 * h.size(), analytic) for |lag| <= max_lag samples, and reserves room for
  /// windows of up to max_window lags. omega_c: the template's spectral centroid (rad/sample).
  /// Throws std::invalid_argument on an empty template, n not a power of two >= 2 * h.size(), or
  /// max_window > max_lag.
  void configure(const std::vector<float>& h, std::size_t n, FftPlanner& fft, double omega_c, std::size_t max_lag,
                 std::size_t max_window);

  /// The tabulated R(tau) (linear interpolation of its carrier-free part); 0 beyond max_lag.
  std::complex<double> model(double tau) const noexcept;

  struct Result {
    bool multipath = false;      ///< the single-path model did not explain the window
    std::size_t paths = 1;       ///< paths fitted
    double delay = 0.0;          ///< direct-path delay (window index units): carrier-phase refined
    double envelope_delay = 0.0; ///< direct-path delay from the multipath envelope fit alone
    double residual = 0.0;       ///< single-path residual energy / window energy
    double fit_residual = 0.0;   ///< multipath-model residual energy / window energy
    bool converged = false;      ///< the multipath model explains the window (to the single-path tolerance)
    double margin = 1.0;         ///< 1 - |delay - envelope_delay| / (half a carrier period), in [0, 1]
  };

  /// [RT] Fits window z[0..count-1] (count <= max_window; lag of z[i] = first + i, the caller adds
  /// `first`). hint: index of the envelope peak chosen by the caller; noise: noise power of |z|^2 per
  /// lag; min_power: smallest |z| peak power a path may have; ratio2: a path earlier than the
  /// strongest must have at least this fraction of its power. When the single-path model fits
  /// (Result::multipath false), delay is the caller's to compute (nothing is changed).
  Result fit(const std::complex<float>* z, std::size_t count, std::size_t hint, double noise, double min_power,
             double ratio2) noexcept;

 private:
  std::complex<double> base(double tau) const noexcept;  // R(tau) e^{-j omega_c tau}
  double score(const std::complex<double>* y, std::size_t n, double tau, std::complex<double>& b) const noexcept;
  double refine(const std::complex<double>* y, std::size_t n, double tau, std::complex<double>& b) const noexcept;

  double omega_ = 0.0;
  double max_lag_ = 0.0;
  std::size_t steps_ = 16;               // table points per sample
  std::vector<std::complex<double>> table_;  // base(tau) at tau = -max_lag + i / steps_
  std::vector<std::complex<double>> y_, r_, work_, proj_, bint_;
  std::vector<double> norm_;
};

}  // namespace locus::dsp
