// Sub-sample peak interpolation (interface and rationale in peak.hpp).
#include "locus/dsp/peak.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace locus::dsp {

PeakFit parabolic_peak(double ym1, double y0, double yp1) noexcept {
  const double denom = ym1 - 2.0 * y0 + yp1;
  if (!(denom < 0.0) || !std::isfinite(denom)) return {0.0, y0};
  const double d = std::clamp(0.5 * (ym1 - yp1) / denom, -1.0, 1.0);
  return {d, y0 - 0.25 * (ym1 - yp1) * d};
}

PeakFit gaussian_peak(double ym1, double y0, double yp1) noexcept {
  if (!(ym1 > 0.0) || !(y0 > 0.0) || !(yp1 > 0.0)) return parabolic_peak(ym1, y0, yp1);
  const PeakFit f = parabolic_peak(std::log(ym1), std::log(y0), std::log(yp1));
  return {f.offset, std::exp(f.value)};
}

double sinc_interpolate(const float* x, std::size_t n, double t, std::size_t half_width) noexcept {
  const double hw = static_cast<double>(std::max<std::size_t>(half_width, 1));
  const auto lo = static_cast<long long>(std::floor(t - hw)) + 1;
  const auto hi = static_cast<long long>(std::floor(t + hw));
  double acc = 0.0;
  for (long long k = std::max<long long>(lo, 0); k <= hi && k < static_cast<long long>(n); ++k) {
    const double u = t - static_cast<double>(k);
    const double w = 0.5 * (1.0 + std::cos(std::numbers::pi * u / hw));
    const double s = std::abs(u) < 1e-12 ? 1.0 : std::sin(std::numbers::pi * u) / (std::numbers::pi * u);
    acc += static_cast<double>(x[k]) * s * w;
  }
  return acc;
}

PeakFit sinc_peak(const float* x, std::size_t n, std::size_t k0, std::size_t half_width) noexcept {
  const double c = static_cast<double>(k0);
  double a = c - 1.0, b = c + 1.0;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double x1 = b - g * (b - a), x2 = a + g * (b - a);
  double f1 = sinc_interpolate(x, n, x1, half_width), f2 = sinc_interpolate(x, n, x2, half_width);
  for (int it = 0; it < 40; ++it) {
    if (f1 > f2) {
      b = x2;
      x2 = x1;
      f2 = f1;
      x1 = b - g * (b - a);
      f1 = sinc_interpolate(x, n, x1, half_width);
    } else {
      a = x1;
      x1 = x2;
      f1 = f2;
      x2 = a + g * (b - a);
      f2 = sinc_interpolate(x, n, x2, half_width);
    }
  }
  const double t = 0.5 * (a + b);
  return {t - c, sinc_interpolate(x, n, t, half_width)};
}

double phase_refine(double re, double im, double omega_c) noexcept {
  if (!(omega_c > 0.0) || (re == 0.0 && im == 0.0)) return 0.0;
  return -std::atan2(im, re) / omega_c;
}

double phase_refine_near(double re, double im, double omega_c, double coarse) noexcept {
  if (!(omega_c > 0.0)) return coarse;
  const double d = phase_refine(re, im, omega_c);
  const double period = 2.0 * std::numbers::pi / omega_c;
  return d + period * std::round((coarse - d) / period);
}

}  // namespace locus::dsp
