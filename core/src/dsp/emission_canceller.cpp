// Own-emission canceller (method and real-time contract in emission_canceller.hpp).
#include "locus/dsp/emission_canceller.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "locus/dsp/peak.hpp"
#include "locus/dsp/simd.hpp"
#include "locus/fft.hpp"

namespace locus::dsp {

EmissionCanceller::EmissionCanceller() = default;
EmissionCanceller::~EmissionCanceller() = default;
EmissionCanceller::EmissionCanceller(EmissionCanceller&&) noexcept = default;
EmissionCanceller& EmissionCanceller::operator=(EmissionCanceller&&) noexcept = default;

void EmissionCanceller::configure(const std::vector<float>& h, FftPlanner& planner, const Options& options) {
  if (h.empty()) throw std::invalid_argument("EmissionCanceller: empty template");
  if (options.channels == 0) throw std::invalid_argument("EmissionCanceller: channels must be > 0");
  if (!std::isfinite(options.threshold_db) || !std::isfinite(options.min_coefficient) ||
      !(options.min_coefficient >= 0.0 && options.min_coefficient <= 1.0))
    throw std::invalid_argument("EmissionCanceller: threshold_db must be finite and min_coefficient in [0, 1]");
  if (!std::isfinite(options.regularization) || options.regularization < 0.0)
    throw std::invalid_argument("EmissionCanceller: regularization must be >= 0");
  if (options.taps_before + options.taps_after > 4096)
    throw std::invalid_argument("EmissionCanceller: at most 4096 FIR taps");
  opt_ = options;
  len_ = h.size();
  taps_ = opt_.taps_before + opt_.taps_after + 1;
  padded_ = len_ + taps_ - 1;
  h_.assign(h.begin(), h.end());
  hf_.assign(h.begin(), h.end());
  wd_.assign(len_ + taps_ - 1, 0.0);
  energy_ = 0.0;
  for (double v : h_) energy_ += v * v;
  if (!(energy_ > 0.0) || !std::isfinite(energy_))
    throw std::invalid_argument("EmissionCanceller: the template has no (finite) energy");

  // The padded template: a lag i of its correlation is the start i + P of h, and the whole fit support
  // [i, i + padded) lies in the window for every lag a window produces.
  std::vector<float> hp(padded_, 0.0f);
  std::copy(h.begin(), h.end(), hp.begin() + static_cast<std::ptrdiff_t>(opt_.taps_before));
  Correlator::Options co;
  co.channels = opt_.channels;
  co.fft_size = opt_.fft_size;
  co.analytic = true;
  co.baseband = true;
  corr_.configure({hp}, planner, co);

  // Normal equations of the FIR fit: R_ij = r_hh(|i - j|) + lambda r_hh(0) delta_ij; lower Cholesky.
  std::vector<double> r(taps_, 0.0);
  for (std::size_t d = 0; d < taps_ && d < len_; ++d) {
    double s = 0.0;
    for (std::size_t j = 0; j + d < len_; ++j) s += h_[j] * h_[j + d];
    r[d] = s;
  }
  chol_.assign(taps_ * taps_, 0.0);
  const double ridge = opt_.regularization * energy_;
  for (std::size_t i = 0; i < taps_; ++i) {
    for (std::size_t j = 0; j <= i; ++j) {
      double s = r[i - j] + (i == j ? ridge : 0.0);
      for (std::size_t k = 0; k < j; ++k) s -= chol_[i * taps_ + k] * chol_[j * taps_ + k];
      if (i == j) {
        if (!(s > 1e-12 * energy_))
          throw std::invalid_argument("EmissionCanceller: the FIR fit is singular for this template (raise "
                                      "regularization or use fewer taps)");
        chol_[i * taps_ + i] = std::sqrt(s);
      } else {
        chol_[i * taps_ + j] = s / chol_[j * taps_ + j];
      }
    }
  }
  cholt_.assign(taps_ * taps_, 0.0);
  for (std::size_t i = 0; i < taps_; ++i)
    for (std::size_t j = 0; j <= i; ++j) cholt_[j * taps_ + i] = chol_[i * taps_ + j];
  b_.assign(taps_, 0.0);
  g_.assign(taps_, 0.0);
  threshold_ = std::pow(10.0, opt_.threshold_db / 10.0);
  min_rho2_ = opt_.min_coefficient * opt_.min_coefficient;
  const std::size_t n = corr_.fft_size();
  pow_.assign(n, 0.0f);
  sorted_.assign(n, 0.0f);
  masked_.assign(n, 0);
  count_.assign(opt_.channels, 0);
  history_.assign(opt_.channels * kHistory, Fit{});
}

std::size_t EmissionCanceller::process(std::size_t ch) noexcept {
  corr_.transform(ch);
  search(ch, corr_.hop());
  return corr_.hop();
}

std::size_t EmissionCanceller::flush(std::size_t ch) noexcept {
  const std::size_t lags = corr_.flush(ch);
  if (lags > 0) search(ch, lags);
  return corr_.filled(ch);
}

void EmissionCanceller::reset(std::size_t ch, std::uint64_t next_index) noexcept { corr_.reset(ch, next_index); }

// sorted[n/2] >= v over x[0], x[stride], ... (n values): at least n - n/2 of them are >= v. One pass.
bool EmissionCanceller::median_at_least(const float* x, std::size_t n, std::size_t stride, float v) noexcept {
  std::size_t c = 0;
  for (std::size_t i = 0; i < n; ++i) c += x[i * stride] >= v ? 1 : 0;
  return c >= n - n / 2;
}

// sorted[n/2] of x[0], x[stride], ... (n values), selected in sorted_.
double EmissionCanceller::median(const float* x, std::size_t n, std::size_t stride) noexcept {
  for (std::size_t i = 0; i < n; ++i) sorted_[i] = x[i * stride];
  const auto mid = sorted_.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(sorted_.begin(), mid, sorted_.begin() + static_cast<std::ptrdiff_t>(n));
  return static_cast<double>(*mid);
}

void EmissionCanceller::search(std::size_t ch, std::size_t lags) noexcept {
  float* pw = pow_.data();
  // Decimated baseband screen first (nearly every window holds no emission).
  const std::size_t d = corr_.baseband_decimation(0);
  if (d > 1 && lags == corr_.hop()) {
    corr_.correlate_baseband(0);
    const std::complex<float>* z = corr_.baseband(0);
    const std::size_t nm = (lags + d - 1) / d;
    float pmax = 0.0f;
    for (std::size_t m = 0; m < nm; ++m) {
      pw[m] = std::norm(z[m]);
      pmax = std::max(pmax, pw[m]);
    }
    // -3 dB margin below the worst between-lag loss: a peak between decimated lags is not missed.
    const double margin = 0.5 * corr_.baseband_peak_ratio(0) * threshold_;
    auto quiet = [&](double median) {
      return pmax <= margin * std::max(median / std::numbers::ln2, std::numeric_limits<double>::min());
    };
    // `quiet` grows with the median: when it holds at v and the median is >= v (a count), it holds at
    // the median, which then need not be selected (the usual window: no emission).
    // Likewise below: not quiet at lo and the median <= lo (a window with an emission).
    const float v = static_cast<float>(static_cast<double>(pmax) * std::numbers::ln2 / margin);
    const float lo = v * 0.9999f;
    if (std::isfinite(v) && quiet(v) && median_at_least(pw, nm, 1, v)) return;
    const bool loud = std::isfinite(v) && !quiet(lo) && !median_at_least(pw, nm, 1, std::nextafter(lo, INFINITY));
    if (!loud && quiet(median(pw, nm, 1))) return;
  }
  corr_.correlate(0);
  const float* re = corr_.real(0);
  const float* im = corr_.imag(0);
  for (std::size_t i = 0; i < lags; ++i) pw[i] = re[i] * re[i] + im[i] * im[i];
  // Noise power: median of every 4th lag / ln 2. A candidate must exceed threshold_ x noise; that
  // decision falls with the median, so a count against the boundary value usually settles it without
  // selecting the median (selected once, when a count cannot tell).
  const std::size_t m = (lags + 3) / 4;
  double exact_median = -1.0;
  auto above = [&](float p) {
    auto passes = [&](double median) {
      return p > std::max(median / std::numbers::ln2, std::numeric_limits<double>::min()) * threshold_;
    };
    if (exact_median < 0.0) {
      const float b = static_cast<float>(static_cast<double>(p) * std::numbers::ln2 / threshold_);
      const float lo = b * 0.9999f, hi = b * 1.0001f;
      if (std::isfinite(b) && passes(lo) && !median_at_least(pw, m, 4, std::nextafter(lo, INFINITY))) return true;
      if (std::isfinite(b) && !passes(hi) && median_at_least(pw, m, 4, hi)) return false;
      exact_median = median(pw, m, 4);
    }
    return passes(exact_median);
  };
  std::fill(masked_.begin(), masked_.begin() + static_cast<std::ptrdiff_t>(lags), std::uint8_t{0});
  const float* x = corr_.samples(ch);
  for (std::size_t round = 0; round < opt_.max_per_window; ++round) {
    std::size_t best = lags;
    float pbest = 0.0f;
    for (std::size_t i = 0; i < lags; ++i)
      if (!masked_[i] && pw[i] > pbest) {
        pbest = pw[i];
        best = i;
      }
    if (best == lags || !above(pbest)) break;
    // Correlation values within one padded template of this lag change with the subtraction (or
    // belong to the same event): never candidates again in this window.
    const std::size_t lo = best >= padded_ ? best - padded_ + 1 : 0;
    const std::size_t hi = std::min(lags, best + padded_);
    std::fill(masked_.begin() + static_cast<std::ptrdiff_t>(lo), masked_.begin() + static_cast<std::ptrdiff_t>(hi),
              std::uint8_t{1});
    double ex = 0.0;
    const float* xs = x + best + opt_.taps_before;
    for (std::size_t j = 0; j < len_; ++j) ex += static_cast<double>(xs[j]) * xs[j];
    if (!(ex > 0.0)) continue;
    const double rho2 = static_cast<double>(pbest) / (energy_ * ex);
    if (rho2 < min_rho2_) continue;  // not a clean copy of the template: leave it alone
    fit_and_subtract(ch, best, pbest, std::sqrt(std::min(rho2, 1.0)));
    // Peak position for the record (envelope fit around the integer peak).
    Fit& f = history_[ch * kHistory + (count_[ch] - 1) % kHistory];
    if (best > 0 && best + 1 < lags) {
      const PeakFit pf = gaussian_peak(std::sqrt(pw[best - 1]), std::sqrt(pw[best]), std::sqrt(pw[best + 1]));
      f.peak_lag += pf.offset;
    }
  }
}

void EmissionCanceller::fit_and_subtract(std::size_t ch, std::size_t i0, double pz, double coefficient) noexcept {
  float* w = corr_.samples_mutable(ch) + i0;  // the fit support [i0, i0 + padded)
  // b_t = sum_j w[t + j] h[j]: correlation of the support with h shifted by t - P, in double (an
  // error in b lands in R's weak, out-of-band directions amplified by 1 / lambda), on a double copy
  // of the support with independent lanes (simd::dot_f64: taps x L multiply-adds, the fit's cost).
  double e0 = 0.0;
  for (std::size_t j = 0; j < padded_; ++j) {
    wd_[j] = w[j];
    e0 += wd_[j] * wd_[j];
  }
  for (std::size_t t = 0; t < taps_; ++t) b_[t] = simd::dot_f64(wd_.data() + t, h_.data(), len_);
  // Solve L y = b, then L^T g = y (rows of L and of L^T are contiguous: vector dot products).
  for (std::size_t i = 0; i < taps_; ++i)
    g_[i] = (b_[i] - simd::dot_f64(chol_.data() + i * taps_, g_.data(), i)) / chol_[i * taps_ + i];
  for (std::size_t ii = taps_; ii-- > 0;)
    g_[ii] = (g_[ii] - simd::dot_f64(cholt_.data() + ii * taps_ + ii + 1, g_.data() + ii + 1, taps_ - ii - 1)) / chol_[ii * taps_ + ii];
  for (std::size_t t = 0; t < taps_; ++t) simd::sub1(w + t, hf_.data(), static_cast<float>(g_[t]), len_);
  double e1 = 0.0;
  for (std::size_t j = 0; j < padded_; ++j) e1 += static_cast<double>(w[j]) * w[j];

  Fit& f = history_[ch * kHistory + count_[ch] % kHistory];
  ++count_[ch];
  const std::uint64_t base = corr_.window_start(ch) + i0;
  f.start = base + opt_.taps_before;
  f.peak_lag = static_cast<double>(base + opt_.taps_before);
  f.amplitude = std::sqrt(pz) / energy_;
  f.coefficient = coefficient;
  f.cancelled_db = e1 > 0.0 ? 10.0 * std::log10(e0 / e1) : 300.0;
}

}  // namespace locus::dsp
