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

/// Chooses among the phase candidates d + m * 2 pi / omega_c (m integer) the one nearest the
/// coarse (envelope) offset `coarse` (both relative to k0): resolves the carrier-cycle ambiguity
/// when k0 is not the nearest sample.
double phase_refine_near(double re, double im, double omega_c, double coarse) noexcept;

}  // namespace locus::dsp
