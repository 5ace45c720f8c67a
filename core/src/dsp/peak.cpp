// Sub-sample peak interpolation (interface and rationale in peak.hpp).
#include "locus/dsp/peak.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "locus/fft.hpp"

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

AnalyticPeak analytic_peak(const std::complex<float>* z, std::size_t n, std::size_t k0, double omega_c) noexcept {
  AnalyticPeak out;
  if (k0 >= n) return out;
  if (k0 < 3 || k0 + 3 >= n || !(omega_c > 0.0)) {
    const double am = k0 > 0 ? std::abs(z[k0 - 1]) : 0.0, a0 = std::abs(z[k0]), ap = k0 + 1 < n ? std::abs(z[k0 + 1]) : 0.0;
    const PeakFit f = gaussian_peak(am, a0, ap);
    out.envelope = f.offset;
    out.magnitude = f.value;
    out.delay = phase_refine_near(z[k0].real(), z[k0].imag(), omega_c, f.offset);
    return out;
  }
  constexpr int kHalf = 3;
  std::array<std::complex<double>, 2 * kHalf + 1> bb{};
  for (int i = -kHalf; i <= kHalf; ++i) {
    const std::complex<double> v(z[static_cast<std::size_t>(static_cast<std::ptrdiff_t>(k0) + i)]);
    bb[static_cast<std::size_t>(i + kHalf)] = v * std::polar(1.0, -omega_c * i);
  }
  // Lagrange basis on the nodes -3..3
  auto at = [&](double t) {
    std::complex<double> sum = 0.0;
    for (int i = -kHalf; i <= kHalf; ++i) {
      double w = 1.0;
      for (int j = -kHalf; j <= kHalf; ++j)
        if (j != i) w *= (t - j) / static_cast<double>(i - j);
      sum += w * bb[static_cast<std::size_t>(i + kHalf)];
    }
    return sum;
  };
  double a = -1.0, b = 1.0;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double x1 = b - g * (b - a), x2 = a + g * (b - a);
  double f1 = std::norm(at(x1)), f2 = std::norm(at(x2));
  for (int it = 0; it < 40; ++it) {
    if (f1 > f2) {
      b = x2, x2 = x1, f2 = f1, x1 = b - g * (b - a), f1 = std::norm(at(x1));
    } else {
      a = x1, x1 = x2, f1 = f2, x2 = a + g * (b - a), f2 = std::norm(at(x2));
    }
  }
  const double t = 0.5 * (a + b);
  const std::complex<double> v = at(t);
  out.envelope = t;
  out.magnitude = std::abs(v);
  // the carrier phase at t (baseband times the carrier) is omega_c (t - delay)
  const double phase = std::arg(v * std::polar(1.0, omega_c * t));
  out.delay = t - phase / omega_c;
  return out;
}

double phase_refine_near(double re, double im, double omega_c, double coarse) noexcept {
  if (!(omega_c > 0.0)) return coarse;
  const double d = phase_refine(re, im, omega_c);
  const double period = 2.0 * std::numbers::pi / omega_c;
  return d + period * std::round((coarse - d) / period);
}


// ---- MultipathFit -------------------------------------------------------------------------------

void MultipathFit::configure(const std::vector<float>& h, std::size_t n, FftPlanner& fft, double omega_c,
                             std::size_t max_lag, std::size_t max_window) {
  if (h.empty()) throw std::invalid_argument("MultipathFit: empty template");
  if (n < 2 * h.size() || (n & (n - 1)) != 0)
    throw std::invalid_argument("MultipathFit: FFT size must be a power of two >= twice the template length");
  if (max_window > max_lag) throw std::invalid_argument("MultipathFit: max_window must be <= max_lag");
  omega_ = omega_c;
  max_lag_ = static_cast<double>(max_lag);
  std::vector<float> in(n, 0.0f);
  std::copy(h.begin(), h.end(), in.begin());
  std::vector<std::complex<float>> spec(n / 2 + 1);
  fft.plan_real(n)->forward(in.data(), spec.data());
  // Analytic autocorrelation: R(tau) = (1/n) [sum_{0<k<n/2} 2 |H_k|^2 e^{j 2 pi k tau / n} + |H_{n/2}|^2 e^{j pi tau}]
  // (the DC bin is dropped as by the analytic correlator); only bins carrying energy are summed.
  std::vector<std::size_t> bins;
  std::vector<double> w;
  double peak = 0.0;
  for (std::size_t k = 1; k <= n / 2; ++k) peak = std::max(peak, static_cast<double>(std::norm(spec[k])));
  for (std::size_t k = 1; k <= n / 2; ++k) {
    const double e = std::norm(spec[k]);
    if (e > 1e-12 * peak) {
      bins.push_back(k);
      w.push_back((k == n / 2 ? 1.0 : 2.0) * e / static_cast<double>(n));
    }
  }
  const std::size_t count = 2 * max_lag * steps_ + 1;
  table_.assign(count, {});
  // Phasors e^{j (2 pi k / n - omega_c) tau} per bin, advanced by one table step at a time.
  const double two_pi_n = 2.0 * std::numbers::pi / static_cast<double>(n);
  std::vector<std::complex<double>> cur(bins.size()), step(bins.size());
  for (std::size_t b = 0; b < bins.size(); ++b) {
    const double rate = two_pi_n * static_cast<double>(bins[b]) - omega_;
    cur[b] = std::polar(1.0, -rate * max_lag_);
    step[b] = std::polar(1.0, rate / static_cast<double>(steps_));
  }
  for (std::size_t i = 0; i < count; ++i) {
    std::complex<double> acc = 0.0;
    for (std::size_t b = 0; b < bins.size(); ++b) {
      acc += w[b] * cur[b];
      cur[b] *= step[b];
    }
    table_[i] = acc;
  }
  y_.assign(max_window, {});
  r_.assign(max_window, {});
  proj_.assign(max_window, {});
  norm_.assign(max_window, 0.0);
  bint_.assign(2 * max_window, {});
  work_.assign(max_window, {});
}

std::complex<double> MultipathFit::base(double tau) const noexcept {
  const double u = (tau + max_lag_) * static_cast<double>(steps_);
  if (!(u >= 0.0) || u >= static_cast<double>(table_.size() - 1)) return 0.0;
  const auto i = static_cast<std::size_t>(u);
  const double f = u - static_cast<double>(i);
  return table_[i] + f * (table_[i + 1] - table_[i]);
}

std::complex<double> MultipathFit::model(double tau) const noexcept { return base(tau) * std::polar(1.0, omega_ * tau); }

// |<B_tau, y>|^2 / ||B_tau||^2 (the energy a path at tau explains) and its amplitude b.
double MultipathFit::score(const std::complex<double>* y, std::size_t n, double tau, std::complex<double>& b) const noexcept {
  std::complex<double> dot = 0.0;
  double nn = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    const std::complex<double> m = base(static_cast<double>(j) - tau);
    dot += std::conj(m) * y[j];
    nn += std::norm(m);
  }
  if (!(nn > 0.0)) {
    b = 0.0;
    return 0.0;
  }
  b = dot / nn;
  return std::norm(dot) / nn;
}

// Golden-section maximisation of score() over [tau - 1, tau + 1].
double MultipathFit::refine(const std::complex<double>* y, std::size_t n, double tau, std::complex<double>& b) const noexcept {
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = tau - 1.0, c = tau + 1.0;
  double x1 = c - g * (c - a), x2 = a + g * (c - a);
  std::complex<double> tmp;
  double f1 = score(y, n, x1, tmp), f2 = score(y, n, x2, tmp);
  for (int it = 0; it < 16; ++it) {
    if (f1 > f2) {
      c = x2; x2 = x1; f2 = f1; x1 = c - g * (c - a); f1 = score(y, n, x1, tmp);
    } else {
      a = x1; x1 = x2; f1 = f2; x2 = a + g * (c - a); f2 = score(y, n, x2, tmp);
    }
  }
  const double t = 0.5 * (a + c);
  score(y, n, t, b);
  return t;
}

MultipathFit::Result MultipathFit::fit(const std::complex<float>* z, std::size_t count, std::size_t hint, double noise,
                                       double min_power, double ratio2) noexcept {
  Result res;
  const std::size_t n = std::min(count, y_.size());
  if (n < 3 || hint >= n || table_.empty()) return res;
  // Carrier-free (demodulated) window: y_j = z_j e^{-j omega_c j}; a path a R(j - tau) becomes
  // b B(j - tau) with b = a e^{-j omega_c tau}.
  double energy = 0.0;
  for (std::size_t j = 0; j < n; ++j) {
    y_[j] = std::complex<double>(z[j]) * std::polar(1.0, -omega_ * static_cast<double>(j));
    energy += std::norm(y_[j]);
  }
  if (!(energy > 0.0)) return res;
  // Single path near the hint.
  std::complex<double> b;
  double best_tau = static_cast<double>(hint), best = -1.0;
  for (int d = -3; d <= 3; ++d) {
    const double t = static_cast<double>(hint) + d;
    const double s = score(y_.data(), n, t, b);
    if (s > best) best = s, best_tau = t;
  }
  best_tau = refine(y_.data(), n, best_tau, b);
  const double single = std::max(0.0, energy - score(y_.data(), n, best_tau, b));
  res.residual = single / energy;
  // Residual allowed: the noise (per-lag power `noise`, neighbouring lags correlated; 4x margin) plus
  // a model tolerance (device responses, Doppler) of 1e-3 of the window energy.
  const double allowed = 4.0 * static_cast<double>(n) * noise + kModelTolerance * energy;
  if (single <= allowed) return res;

  res.multipath = true;
  std::array<double, kMaxPaths> tau{};
  std::array<std::complex<double>, kMaxPaths> amp{};
  std::size_t paths = 0;
  double resid = energy;
  // Two paths first, jointly, by exhaustive search on the integer grid (least-squares amplitudes): a
  // greedy start at the composite peak misplaces both when the paths overlap, above all when the
  // reflection has the opposite sign and eats into the direct path's mainlobe.
  {
    for (std::size_t d = 0; d < 2 * n - 1; ++d) bint_[d] = base(static_cast<double>(d) - static_cast<double>(n - 1));
    auto bat = [&](std::size_t j, std::size_t t) { return bint_[j + n - 1 - t]; };  // B(j - t)
    for (std::size_t t = 0; t < n; ++t) {
      std::complex<double> c = 0.0;
      double e = 0.0;
      for (std::size_t j = 0; j < n; ++j) {
        c += std::conj(bat(j, t)) * y_[j];
        e += std::norm(bat(j, t));
      }
      proj_[t] = c;
      norm_[t] = e;
    }
    double best2 = -1.0;
    std::size_t t1b = 0, t2b = 1;
    std::complex<double> a1b = 0.0, a2b = 0.0;
    for (std::size_t t1 = 0; t1 < n; ++t1) {
      for (std::size_t t2 = t1 + 1; t2 < n; ++t2) {
        std::complex<double> g = 0.0;
        for (std::size_t j = 0; j < n; ++j) g += std::conj(bat(j, t1)) * bat(j, t2);
        const double det = norm_[t1] * norm_[t2] - std::norm(g);
        if (!(det > 1e-9 * norm_[t1] * norm_[t2])) continue;
        const std::complex<double> b1 = (norm_[t2] * proj_[t1] - g * proj_[t2]) / det;
        const std::complex<double> b2 = (norm_[t1] * proj_[t2] - std::conj(g) * proj_[t1]) / det;
        const double explained = (std::conj(b1) * proj_[t1] + std::conj(b2) * proj_[t2]).real();
        if (explained > best2) best2 = explained, t1b = t1, t2b = t2, a1b = b1, a2b = b2;
      }
    }
    tau[0] = static_cast<double>(t1b);
    tau[1] = static_cast<double>(t2b);
    paths = 2;
    for (std::size_t j = 0; j < n; ++j) r_[j] = y_[j];
    amp[0] = a1b;
    amp[1] = a2b;
  }
  bool first = true;
  while (paths <= kMaxPaths) {
    if (!first) {
      if (paths == kMaxPaths) break;
      // CLEAN: the strongest remaining path on the integer grid, refined.
      double bt = 0.0, bs = -1.0;
      for (std::size_t j = 0; j < n; ++j) {
        const double s = score(r_.data(), n, static_cast<double>(j), b);
        if (s > bs) bs = s, bt = static_cast<double>(j);
      }
      tau[paths] = refine(r_.data(), n, bt, amp[paths]);
      ++paths;
    }
    first = false;
    // SAGE-style sweeps: each path re-fitted to the window minus all the others.
    for (int sweep = 0; sweep < 2; ++sweep) {
      for (std::size_t p = 0; p < paths; ++p) {
        for (std::size_t j = 0; j < n; ++j) {
          std::complex<double> v = y_[j];
          for (std::size_t q = 0; q < paths; ++q)
            if (q != p) v -= amp[q] * base(static_cast<double>(j) - tau[q]);
          work_[j] = v;
        }
        tau[p] = refine(work_.data(), n, tau[p], amp[p]);
      }
    }
    resid = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      std::complex<double> v = y_[j];
      for (std::size_t q = 0; q < paths; ++q) v -= amp[q] * base(static_cast<double>(j) - tau[q]);
      r_[j] = v;
      resid += std::norm(v);
    }
    if (resid <= allowed) break;
  }
  res.paths = paths;
  res.fit_residual = resid / energy;
  res.converged = resid <= allowed;
  // Direct path: the earliest with enough power of its own and >= ratio2 of the strongest.
  const double b0 = std::norm(base(0.0));
  double strongest = 0.0;
  for (std::size_t p = 0; p < paths; ++p) strongest = std::max(strongest, std::norm(amp[p]) * b0);
  std::size_t d = paths;
  for (std::size_t p = 0; p < paths; ++p) {
    const double pw = std::norm(amp[p]) * b0;
    if (pw < min_power || pw < ratio2 * strongest) continue;
    if (d == paths || tau[p] < tau[d]) d = p;
  }
  if (d == paths) {
    res.multipath = false;  // nothing trustworthy: leave the caller's estimate
    return res;
  }
  res.envelope_delay = tau[d];
  // Cleaned correlation at the lag nearest the direct path: z minus every other path.
  const double k1 = std::clamp(std::round(tau[d]), 0.0, static_cast<double>(n - 1));
  std::complex<double> v = y_[static_cast<std::size_t>(k1)];
  for (std::size_t q = 0; q < paths; ++q)
    if (q != d) v -= amp[q] * base(k1 - tau[q]);
  v *= std::polar(1.0, omega_ * k1);  // back to the carrier
  res.delay = k1 + phase_refine_near(v.real(), v.imag(), omega_, tau[d] - k1);
  const double half = std::numbers::pi / omega_;
  res.margin = std::clamp(1.0 - std::fabs(res.delay - res.envelope_delay) / half, 0.0, 1.0);
  return res;
}

}  // namespace locus::dsp

