// DTW (see dtw.hpp): two rolling rows of the cumulative-cost matrix, band limits per row.
#include "locus/dsp/dtw.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include "locus/numbers.hpp"

namespace locus::dsp {


Dtw::Dtw(std::size_t max_length, DtwCost cost) : max_length_(max_length), cost_(cost) {
  if (max_length == 0) throw std::invalid_argument("Dtw: max_length must be >= 1");
  prev_.assign(max_length + 1, kInf);
  cur_.assign(max_length + 1, kInf);
}

double Dtw::distance(std::span<const float> a, std::span<const float> b, std::size_t window,
                     double abandon_above) noexcept {
  const std::size_t n = a.size(), m = b.size();
  if (n == 0 || m == 0 || n > max_length_ || m > max_length_) return kInf;
  // Row i of `a` (1-based) may use columns j with |i - j·n/m| <= window (in rows), i.e. j within
  // [(i - w)·m/n, (i + w)·m/n]; always at least the diagonal cell so that a path exists when
  // window >= |n - m| scaled.
  const double ratio = static_cast<double>(m) / static_cast<double>(n);
  std::fill(prev_.begin(), prev_.begin() + static_cast<std::ptrdiff_t>(m + 1), kInf);
  prev_[0] = 0.0;
  for (std::size_t i = 1; i <= n; ++i) {
    const double lo_f = (static_cast<double>(i) - static_cast<double>(window)) * ratio;
    const double hi_f = (static_cast<double>(i) + static_cast<double>(window)) * ratio;
    const std::size_t jlo = static_cast<std::size_t>(std::max(1.0, std::floor(lo_f)));
    const std::size_t jhi = static_cast<std::size_t>(std::min(static_cast<double>(m), std::ceil(hi_f)));
    std::fill(cur_.begin(), cur_.begin() + static_cast<std::ptrdiff_t>(m + 1), kInf);
    double row_min = kInf;
    for (std::size_t j = jlo; j <= jhi; ++j) {
      const double best = std::min({prev_[j], cur_[j - 1], prev_[j - 1]});
      if (best == kInf) continue;
      const double c = best + local(a[i - 1], b[j - 1]);
      cur_[j] = c;
      row_min = std::min(row_min, c);
    }
    if (row_min > abandon_above || row_min == kInf) return kInf;
    std::swap(prev_, cur_);
  }
  return prev_[m];
}

DtwOpenEndMatch Dtw::open_end(std::span<const float> templ, std::span<const float> x, std::size_t min_length,
                              std::size_t max_length, std::size_t window) noexcept {
  DtwOpenEndMatch best;
  const std::size_t n = templ.size();
  const std::size_t m = std::min({x.size(), max_length, max_length_});
  if (n == 0 || n > max_length_ || m == 0 || min_length > m) return best;
  min_length = std::max<std::size_t>(min_length, 1);
  const double slope_lo = static_cast<double>(min_length) / static_cast<double>(n);
  const double slope_hi = static_cast<double>(max_length) / static_cast<double>(n);
  std::fill(prev_.begin(), prev_.begin() + static_cast<std::ptrdiff_t>(m + 1), kInf);
  prev_[0] = 0.0;
  for (std::size_t i = 1; i <= n; ++i) {
    const double lo_f = static_cast<double>(i) * slope_lo - static_cast<double>(window);
    const double hi_f = static_cast<double>(i) * slope_hi + static_cast<double>(window);
    const std::size_t jlo = static_cast<std::size_t>(std::max(1.0, std::floor(lo_f)));
    const std::size_t jhi = static_cast<std::size_t>(std::min(static_cast<double>(m), std::ceil(hi_f)));
    std::fill(cur_.begin(), cur_.begin() + static_cast<std::ptrdiff_t>(m + 1), kInf);
    bool any = false;
    for (std::size_t j = jlo; j <= jhi; ++j) {
      const double b = std::min({prev_[j], cur_[j - 1], prev_[j - 1]});
      if (b == kInf) continue;
      cur_[j] = b + local(templ[i - 1], x[j - 1]);
      any = true;
    }
    if (!any) return best;
    std::swap(prev_, cur_);
  }
  for (std::size_t j = min_length; j <= m; ++j) {
    if (prev_[j] == kInf) continue;
    const double norm = prev_[j] / static_cast<double>(n + j);
    if (norm < best.normalized_cost) {
      best.length = j;
      best.cost = prev_[j];
      best.normalized_cost = norm;
    }
  }
  return best;
}

void lb_keogh_envelope(std::span<const float> query, std::size_t window, std::span<float> upper,
                       std::span<float> lower) noexcept {
  const std::size_t n = query.size();
  if (upper.size() < n || lower.size() < n) return;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t lo = i >= window ? i - window : 0;
    const std::size_t hi = std::min(n - 1, i + window);
    float u = query[lo], l = query[lo];
    for (std::size_t k = lo + 1; k <= hi; ++k) {
      u = std::max(u, query[k]);
      l = std::min(l, query[k]);
    }
    upper[i] = u;
    lower[i] = l;
  }
}

double lb_keogh(std::span<const float> candidate, std::span<const float> upper, std::span<const float> lower,
                DtwCost cost, double abandon_above) noexcept {
  const std::size_t n = candidate.size();
  if (upper.size() != n || lower.size() != n) return kInf;
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double c = candidate[i];
    double d = 0.0;
    if (c > upper[i]) d = c - upper[i];
    else if (c < lower[i]) d = lower[i] - c;
    sum += cost == DtwCost::Squared ? d * d : d;
    if (sum > abandon_above) return sum;
  }
  return sum;
}

}  // namespace locus::dsp
