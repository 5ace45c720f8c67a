// Multipath onset fit; design in locus/dsp/onset_fit.hpp.
#include "locus/dsp/onset_fit.hpp"

#include <algorithm>
#include <cmath>

#include "locus/dsp/peak.hpp"
#include "locus/numbers.hpp"

namespace locus::dsp {

namespace {
constexpr std::size_t kMaxDim = 2 * OnsetPathsFit::kMaxPaths;

// Solves G x = r (G symmetric positive semi-definite, d <= kMaxDim) by Cholesky with a relative
// ridge; returns x·r (the explained energy) and x.
double solve_explained(std::array<double, kMaxDim * kMaxDim>& g, std::array<double, kMaxDim>& r, std::size_t d,
                       double* x) noexcept {
  double tr = 0.0;
  for (std::size_t i = 0; i < d; ++i) tr += g[i * kMaxDim + i];
  if (!(tr > 0.0)) return 0.0;
  const double ridge = 1e-9 * tr;
  std::array<double, kMaxDim * kMaxDim> l{};
  for (std::size_t i = 0; i < d; ++i) {
    for (std::size_t j = 0; j <= i; ++j) {
      double v = g[i * kMaxDim + j] + (i == j ? ridge : 0.0);
      for (std::size_t k = 0; k < j; ++k) v -= l[i * kMaxDim + k] * l[j * kMaxDim + k];
      if (i == j) {
        if (!(v > 0.0)) return 0.0;
        l[i * kMaxDim + i] = std::sqrt(v);
      } else {
        l[i * kMaxDim + j] = v / l[j * kMaxDim + j];
      }
    }
  }
  std::array<double, kMaxDim> z{};
  for (std::size_t i = 0; i < d; ++i) {
    double v = r[i];
    for (std::size_t k = 0; k < i; ++k) v -= l[i * kMaxDim + k] * z[k];
    z[i] = v / l[i * kMaxDim + i];
  }
  double e = 0.0;
  for (std::size_t i = d; i-- > 0;) {
    double v = z[i];
    for (std::size_t k = i + 1; k < d; ++k) v -= l[k * kMaxDim + i] * x[k];
    x[i] = v / l[i * kMaxDim + i];
  }
  for (std::size_t i = 0; i < d; ++i) e += x[i] * r[i];
  return std::max(e, 0.0);
}
}  // namespace

void OnsetPathsFit::reserve(std::size_t max_window) {
  y_.assign(max_window, 0.0);
  fixed_.assign(max_window * kMaxDim, 0.0);
}

// Inlined into the per-sample loops of scan_add() and explained() (a call per sample was 5 % of the
// multitone detector's time).
[[gnu::always_inline]] inline std::size_t OnsetPathsFit::columns(const std::int64_t* tau8, std::size_t p, std::size_t n, double* v,
                                   bool* any) const noexcept {
  const auto os = static_cast<std::int64_t>(os_);
  std::size_t col = 0;
  for (std::size_t q = 0; q < p; ++q) {
    std::int64_t u = static_cast<std::int64_t>(n) * os - tau8[q];
    if (scaled_) u = scaled(u);  // Doppler: the waveform's time axis
    const bool in = u >= 0 && static_cast<std::size_t>(u) < fine_n_;
    if (any != nullptr) *any |= in;
    if (q == kp_) {
      v[col++] = in ? kp_cos_ * s_[u] - kp_sin_ * c_[u] : 0.0;
    } else if (known_) {
      v[col++] = in ? s_[u] : 0.0;
    } else {
      v[col++] = in ? c_[u] : 0.0;
      v[col++] = in ? s_[u] : 0.0;
    }
  }
  return col;
}

// The best delay for one more path (scan lo8..hi8 by step8, sep8 from the others): the fixed paths'
// basis, Gram block and projections are computed once; per candidate only its own terms (over the
// samples after its start).
std::int64_t OnsetPathsFit::scan_add(const std::int64_t* tau8, std::size_t p, std::int64_t lo8, std::int64_t hi8,
                                     std::int64_t step8, std::int64_t sep8, double& best_e) noexcept {
  const std::size_t m = known_ ? 1 : 2;
  std::size_t df = 0;
  const auto os = static_cast<std::int64_t>(os_);
  std::array<double, kMaxDim * kMaxDim> gf{};
  std::array<double, kMaxDim> rf{};
  for (std::size_t n = 0; n < n_; ++n) {
    double* v = &fixed_[n * kMaxDim];
    df = columns(tau8, p, n, v, nullptr);
    for (std::size_t i = 0; i < df; ++i) {
      rf[i] += y_[n] * v[i];
      for (std::size_t j = 0; j <= i; ++j) gf[i * kMaxDim + j] += v[i] * v[j];
    }
  }
  const std::size_t d = df + m;
  std::int64_t best = -1;
  best_e = -1.0;
  for (std::int64_t t = lo8; t <= hi8; t += step8) {
    bool near = false;
    for (std::size_t q = 0; q < p; ++q) near |= std::llabs(t - tau8[q]) < sep8;
    if (near) continue;
    std::array<double, kMaxDim * kMaxDim> g = gf;
    std::array<double, kMaxDim> r = rf;
    std::array<double, 2> rt{}, gt{};  // new path: projections; Gram cc, ss
    double gcs = 0.0;
    std::array<double, 2 * kMaxDim> cross{};  // new path's cos (j) and sin (kMaxDim + j) with fixed basis j
    const std::size_t n0 = t <= 0 ? 0 : static_cast<std::size_t>((t + os - 1) / os);
    for (std::size_t n = n0; n < n_; ++n) {
      std::int64_t u = static_cast<std::int64_t>(n) * os - t;
      if (scaled_) u = scaled(u);
      if (static_cast<std::size_t>(u) >= fine_n_) break;
      const double vs = s_[u], yn = y_[n];
      const double* v = &fixed_[n * kMaxDim];
      if (known_) {
        rt[1] += yn * vs;
        gt[1] += vs * vs;
        for (std::size_t j = 0; j < df; ++j) cross[kMaxDim + j] += vs * v[j];
      } else {
        const double vc = c_[u];
        rt[0] += yn * vc;
        rt[1] += yn * vs;
        gt[0] += vc * vc;
        gt[1] += vs * vs;
        gcs += vc * vs;
        for (std::size_t j = 0; j < df; ++j) {
          cross[j] += vc * v[j];
          cross[kMaxDim + j] += vs * v[j];
        }
      }
    }
    if (known_) {
      r[df] = rt[1];
      g[df * kMaxDim + df] = gt[1];
      for (std::size_t j = 0; j < df; ++j) g[df * kMaxDim + j] = cross[kMaxDim + j];
    } else {
      r[df] = rt[0];
      r[df + 1] = rt[1];
      g[df * kMaxDim + df] = gt[0];
      g[(df + 1) * kMaxDim + df] = gcs;
      g[(df + 1) * kMaxDim + df + 1] = gt[1];
      for (std::size_t j = 0; j < df; ++j) {
        g[df * kMaxDim + j] = cross[j];
        g[(df + 1) * kMaxDim + j] = cross[kMaxDim + j];
      }
    }
    std::array<double, kMaxDim> x{};
    const double e = solve_explained(g, r, d, x.data());
    if (e > best_e) best_e = e, best = t;
  }
  return best;
}

double OnsetPathsFit::explained(const std::int64_t* tau8, std::size_t p, double* coef) const noexcept {
  // Columns: one per path with a known phase (the sine part; the path kp_ rotated by its sub-grid
  // delay), two (cos, sin) per free path.
  std::size_t d = 0;
  for (std::size_t q = 0; q < p; ++q) d += (known_ || q == kp_) ? 1 : 2;
  std::array<double, kMaxDim * kMaxDim> g{};
  std::array<double, kMaxDim> r{};
  std::array<double, kMaxDim> v{};
  const auto os = static_cast<std::int64_t>(os_);
  std::int64_t lo = tau8[0];
  for (std::size_t q = 1; q < p; ++q) lo = std::min(lo, tau8[q]);
  const std::size_t n0 = lo <= 0 ? 0 : static_cast<std::size_t>(lo / os);
  for (std::size_t n = n0; n < n_; ++n) {
    bool any = false;
    columns(tau8, p, n, v.data(), &any);
    if (!any) continue;
    const double yn = y_[n];
    for (std::size_t i = 0; i < d; ++i) {
      r[i] += yn * v[i];
      for (std::size_t j = 0; j <= i; ++j) g[i * kMaxDim + j] += v[i] * v[j];
    }
  }
  std::array<double, kMaxDim> x{};
  const double e = solve_explained(g, r, d, x.data());
  if (coef != nullptr) std::copy(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(d), coef);
  return e;
}

double OnsetPathsFit::choose_cycle(std::int64_t* tau8, std::size_t p, std::size_t first, double delay,
                                   double carrier_rad) noexcept {
  const double os = static_cast<double>(os_), period = 2.0 * kPi / carrier_rad;
  const std::int64_t keep = tau8[first];
  double best_e = -1.0, best = delay;
  for (int m = -2; m <= 2; ++m) {
    const double cand = delay + m * period;
    if (cand < 0.0 || cand >= static_cast<double>(n_)) continue;
    // The candidate on the 1/os grid, its remainder as a carrier rotation of the templates: a copy
    // delayed by e more is ≈ cos(ω e)·s − sin(ω e)·c (the envelope moves by < 1/os sample).
    tau8[first] = std::llround(cand * os);
    const double rem = cand - static_cast<double>(tau8[first]) / os;
    kp_ = first;
    kp_cos_ = std::cos(carrier_rad * rem);
    kp_sin_ = std::sin(carrier_rad * rem);
    const double e = explained(tau8, p, nullptr);
    if (e > best_e) best_e = e, best = cand;
  }
  kp_ = kMaxPaths;
  tau8[first] = keep;
  return best;
}

std::int64_t OnsetPathsFit::refine(std::int64_t* tau8, std::size_t p, std::size_t which, std::int64_t range8,
                                   std::int64_t step8, double& best_e) noexcept {
  // The other paths fixed: a scan of this one over ±range8 (scan_add's incremental Gram terms).
  std::array<std::int64_t, kMaxPaths> others{};
  std::size_t k = 0;
  for (std::size_t q = 0; q < p; ++q)
    if (q != which) others[k++] = tau8[q];
  double e = -1.0;
  const std::int64_t t = scan_add(others.data(), k, tau8[which] - range8, tau8[which] + range8, step8, sep8_, e);
  if (t >= 0 && e > best_e) {
    best_e = e;
    tau8[which] = t;
  }
  return tau8[which];
}

void OnsetPathsFit::bind(const float* y, std::size_t n, const float* c, const float* s, std::size_t fine_n,
                         const Options& o, double time_scale) noexcept {
  n_ = std::min(n, y_.size());
  c_ = c;
  s_ = s;
  fine_n_ = fine_n;
  os_ = std::max<std::size_t>(1, o.oversample);
  known_ = o.known_phase;
  scale_ = time_scale;
  scaled_ = scale_ != 1.0;
  for (std::size_t i = 0; i < n_; ++i) y_[i] = y[i];
}

double OnsetPathsFit::noise_power(const float* y, std::size_t n, const float* c, const float* s, std::size_t fine_n,
                                  const Options& o) noexcept {
  bind(y, n, c, s, fine_n, o, 1.0);
  // Short template stretches (a fifth of the reference) at many starts: the projections of one
  // long template at nearby starts are nearly the same numbers (the tone grid's envelope repeats),
  // so few of them would average to a noisy estimate.
  const std::size_t len = std::min(fine_n_ / os_, std::max<std::size_t>(64, n_ / 5));
  if (n_ < len + 8) return 0.0;
  const std::size_t full = fine_n_;
  fine_n_ = len * os_;
  double sum = 0.0;
  std::size_t count = 0;
  for (std::size_t start = 0; start + len <= n_; start += 16, ++count) {
    const auto t8 = static_cast<std::int64_t>(start * os_);
    sum += explained(&t8, 1, nullptr);
  }
  fine_n_ = full;
  return count > 0 ? sum / static_cast<double>(count) / (known_ ? 1.0 : 2.0) : 0.0;
}

OnsetPathsFit::Result OnsetPathsFit::fit(const float* y, std::size_t n, const float* c, const float* s,
                                         std::size_t fine_n, double tau0, double noise_var, const Options& o) noexcept {
  Result res;
  bind(y, n, c, s, fine_n, o, o.time_scale > 0.0 ? o.time_scale : 1.0);
  if (n_ < 8 || fine_n_ == 0 || !(tau0 >= 0.0) || tau0 >= static_cast<double>(n_)) return res;
  for (std::size_t i = 0; i < n_; ++i) res.energy += y_[i] * y_[i];
  const auto os = static_cast<std::int64_t>(os_);
  const std::size_t max_p = std::clamp<std::size_t>(o.max_paths, 1, kMaxPaths);
  const double thr = o.threshold * std::max(noise_var, 0.0) + o.tolerance * res.energy;
  std::array<std::int64_t, kMaxPaths> tau{};
  tau[0] = std::llround(tau0 * static_cast<double>(os));
  std::size_t p = 1;
  double e = explained(tau.data(), 1, nullptr);
  const std::int64_t sep8 = std::llround(o.min_separation * static_cast<double>(os));
  sep8_ = sep8;
  const std::int64_t step8 = std::max<std::int64_t>(1, std::llround(o.scan_step * static_cast<double>(os)));
  const std::int64_t lo8 = std::max<std::int64_t>(0, tau[0] - std::llround(o.back * static_cast<double>(os)));
  const std::int64_t hi8 = std::min<std::int64_t>(static_cast<std::int64_t>(n_ - 1) * os,
                                                  tau[0] + std::llround(o.ahead * static_cast<double>(os)));
  auto polish = [&](std::size_t rounds) {
    for (std::size_t round = 0; round < rounds; ++round)
      for (std::size_t q = 0; q < p; ++q) {
        refine(tau.data(), p, q, 4 * os, std::max<std::int64_t>(1, os / 2), e);
        refine(tau.data(), p, q, std::max<std::int64_t>(1, os / 2), std::max<std::int64_t>(1, os / 4), e);
        refine(tau.data(), p, q, std::max<std::int64_t>(1, os / 4), 1, e);
      }
  };
  while (p < max_p) {
    double best_e = -1.0;
    const std::int64_t best_t = scan_add(tau.data(), p, lo8, hi8, step8, sep8, best_e);
    if (best_t < 0 || best_e - e < thr) break;
    tau[p++] = best_t;
    e = best_e;
    polish(1);
  }
  polish(1);
  for (std::size_t i = 1; i < p; ++i)  // ascending delays (insertion sort of <= kMaxPaths)
    for (std::size_t j = i; j > 0 && tau[j] < tau[j - 1]; --j) std::swap(tau[j], tau[j - 1]);
  // The first needed path: removing it (the others re-fitted, delays kept) loses more than thr.
  std::size_t first = p;
  double need = 0.0;
  for (std::size_t q = 0; q < p && first == p; ++q) {
    std::array<std::int64_t, kMaxPaths> rest{};
    std::size_t k = 0;
    for (std::size_t j = 0; j < p; ++j)
      if (j != q) rest[k++] = tau[j];
    const double without = k > 0 ? explained(rest.data(), k, nullptr) : 0.0;
    if (e - without > thr) first = q, need = e - without;
  }
  std::array<double, kMaxDim> coef{};
  std::array<double, kMaxPaths> amp{};
  res.explained = explained(tau.data(), p, coef.data());
  for (std::size_t q = 0; q < p; ++q) amp[q] = known_ ? std::fabs(coef[q]) : std::hypot(coef[2 * q], coef[2 * q + 1]);
  res.paths = p;
  for (std::size_t q = 0; q < p; ++q) {
    res.delay[q] = static_cast<double>(tau[q]) / static_cast<double>(os);
    res.amplitude[q] = amp[q];
  }
  if (first == p) {  // nothing clears the threshold: the strongest path, no confidence
    first = static_cast<std::size_t>(std::max_element(amp.begin(), amp.begin() + static_cast<std::ptrdiff_t>(p)) - amp.begin());
    need = 0.0;
  }
  // Parabolic vertex of the explained energy around the first path's delay (1/os grid).
  const std::int64_t tf = tau[first];
  tau[first] = tf - 1;
  const double em = explained(tau.data(), p, nullptr);
  tau[first] = tf + 1;
  const double ep = explained(tau.data(), p, nullptr);
  tau[first] = tf;
  double off = 0.0;
  const double den = em - 2.0 * res.explained + ep;
  if (den < 0.0) off = std::clamp(0.5 * (em - ep) / den, -0.5, 0.5);
  res.first = (static_cast<double>(tf) + off) / static_cast<double>(os);
  res.envelope_first = res.first;
  if (!known_ && o.carrier_rad > 0.0) {
    // Carrier phase of the first path at its fitted delay: a copy delayed by δ more has (cos, sin)
    // amplitudes ≈ g·(−sin ω_c δ, cos ω_c δ); the δ nearest 0 (within half a carrier period).
    explained(tau.data(), p, coef.data());
    res.first = static_cast<double>(tf) / static_cast<double>(os) +
                phase_refine_near(coef[2 * first + 1], coef[2 * first], o.carrier_rad, off / static_cast<double>(os));
    if (o.known_phase_cycle) {
      // The echoes of the fit, and more found on the noise threshold alone: an echo left out of the
      // model leans on the first path's envelope, which is what picks the cycle.
      std::array<std::int64_t, kMaxPaths> more = tau;
      std::size_t pm = p;
      double em = res.explained;
      const double thr_noise = o.threshold * std::max(noise_var, 0.0);
      while (pm < std::min(kMaxPaths, o.cycle_paths)) {  // echoes come after the first path
        double be = -1.0;
        const std::int64_t t = scan_add(more.data(), pm, tau[first] + sep8, hi8, step8, sep8, be);
        if (t < 0 || be - em < thr_noise) break;
        more[pm++] = t;
        em = be;
      }
      res.first = choose_cycle(more.data(), pm, first, res.first, o.carrier_rad);
    }
  }
  res.first_amplitude = amp[first];
  res.confidence = need > 0.0 ? std::clamp(1.0 - thr / need, 0.0, 1.0) : 0.0;
  return res;
}

}  // namespace locus::dsp
