// LocBLE maths (see solver.hpp for the model, the frame and why each piece exists).
#include "solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <stdexcept>

#include "locus/dsp/dtw.hpp"

namespace locus::plugins::locble {

namespace {

/// log10 for positive normal floats, |error| < 2e-5 (a degree-5 fit of log2 on the mantissa); the
/// posterior evaluates it cells x bins times, and the model's own noise is dB, so this is plenty.
__attribute__((always_inline)) inline float fast_log10(float x) noexcept {
  std::uint32_t bits;
  std::memcpy(&bits, &x, sizeof bits);
  const float e = static_cast<float>(static_cast<int>((bits >> 23) & 0xFFu) - 127);
  bits = (bits & 0x007FFFFFu) | 0x3F800000u;  // mantissa in [1, 2)
  float m;
  std::memcpy(&m, &bits, sizeof m);
  const float t = m - 1.0f;
  // log2(1 + t) on [0, 1)
  const float p = t * (1.4425449f + t * (-0.7181452f + t * (0.4575485f + t * (-0.2779042f + t * (0.1217970f + t * -0.0258411f)))));
  return (e + p) * 0.30102999566f;
}

/// One grid row's sums for one bin: for every cell i, L = −10·log10(max(d, d_min)) with
/// d² = (xs + i·step)² + dy2, then sl += w·L, sll += w·L², srl += w·r·L. The hot loop of the
/// posterior (cells x bins per tag and update): kept branch-free and compiled for vectorisation
/// (-O2 alone does not vectorise it; docs/locble.md "Speed").
__attribute__((optimize("O3", "no-trapping-math"))) void accumulate_row(float xs, float step, float dy2, float dmin2,
                                                                      float w, float r, int nx, float* __restrict sl,
                                                                      float* __restrict sll,
                                                                      float* __restrict srl) noexcept {
  for (int i = 0; i < nx; ++i) {
    const float dx = xs + static_cast<float>(i) * step;
    const float e2 = dx * dx + dy2;
    const float d2 = e2 > dmin2 ? e2 : dmin2;  // not std::max: it is not inlined under this attribute
    const float l = -5.0f * fast_log10(d2);
    const float wl = w * l;
    sl[i] += wl;
    sll[i] += wl * l;
    srl[i] += wl * r;
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// Bins

std::vector<Bin> make_bins(std::span<const Reading> readings, std::span<const Vec2> positions,
                           std::span<const double> path_m, double bin_m) {
  if (readings.size() != positions.size() || readings.size() != path_m.size())
    throw std::invalid_argument("make_bins: readings, positions and path lengths must have the same size");
  if (!(bin_m > 0.0)) throw std::invalid_argument("make_bins: bin_m must be > 0");
  std::map<long, Bin> acc;
  for (std::size_t i = 0; i < readings.size(); ++i) {
    const long k = static_cast<long>(std::floor(path_m[i] / bin_m));
    Bin& b = acc[k];
    b.observer_m += positions[i];
    b.rssi_dbm += readings[i].rssi_dbm;
    b.t_s += readings[i].t_s;
    ++b.count;
  }
  std::vector<Bin> out;
  out.reserve(acc.size());
  for (auto& [k, b] : acc) {
    const double c = static_cast<double>(b.count);
    b.observer_m /= c;
    b.rssi_dbm /= c;
    b.t_s /= c;
    out.push_back(b);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------
// Eq. 2-5

RegressionFit elliptical_regression(std::span<const Vec2> o, std::span<const double> rss, const RegressionOptions& opt) {
  if (o.size() != rss.size()) throw std::invalid_argument("elliptical_regression: positions and RSS differ in size");
  const std::size_t m = o.size();
  const int k = opt.straight ? 3 : 4;  // unknowns: x, [h,] G, ε
  if (m < static_cast<std::size_t>(k + 1))
    throw std::invalid_argument("elliptical_regression: need at least " + std::to_string(k + 1) + " readings, got " +
                                std::to_string(m));
  if (!(opt.n_min > 0.0) || !(opt.n_max >= opt.n_min) || !(opt.n_step > 0.0))
    throw std::invalid_argument("elliptical_regression: need 0 < n_min <= n_max and n_step > 0");
  double rss_max = -std::numeric_limits<double>::infinity();
  for (double r : rss) rss_max = std::max(rss_max, r);
  RegressionFit best;
  best.why = "no fading coefficient gave a positive scale (ε <= 0): the RSS does not fall with distance along this walk";
  Eigen::MatrixXd a(m, k);
  Eigen::VectorXd b(m), rho(m), w(m);
  for (double n = opt.n_min; n <= opt.n_max + 1e-9; n += opt.n_step) {
    // ρ_i = η^RSS_i with η = 10^(−1/(5n)), scaled by η^(−RSS_max) for conditioning (ε absorbs it).
    for (std::size_t i = 0; i < m; ++i) rho[static_cast<Eigen::Index>(i)] = std::pow(10.0, -(rss[i] - rss_max) / (5.0 * n));
    for (std::size_t i = 0; i < m; ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      a(r, 0) = -2.0 * o[i].x();
      if (!opt.straight) a(r, 1) = -2.0 * o[i].y();
      a(r, k - 2) = 1.0;
      a(r, k - 1) = -rho[r];
      b[r] = -(opt.straight ? o[i].x() * o[i].x() : o[i].squaredNorm());
    }
    w.setOnes();
    Eigen::VectorXd sol;
    bool positive = false;
    for (int it = 0; it <= opt.reweight_iterations; ++it) {
      sol = (w.asDiagonal() * a).colPivHouseholderQr().solve(w.asDiagonal() * b);
      const double eps = sol[k - 1];
      positive = std::isfinite(eps) && eps > 0.0;
      if (!positive) break;
      for (Eigen::Index r = 0; r < static_cast<Eigen::Index>(m); ++r) w[r] = 1.0 / std::max(eps * rho[r], 0.25);
    }
    if (!positive || !sol.allFinite()) continue;
    const double cost = (w.asDiagonal() * (a * sol - b)).squaredNorm() / static_cast<double>(m);
    if (best.ok && cost >= best.cost) continue;
    best.ok = true;
    best.why.clear();
    best.cost = cost;
    best.n = n;
    const double x = sol[0];
    double h = 0.0;
    if (opt.straight) {
      h = std::sqrt(std::max(sol[1] - x * x, 0.0));
    } else {
      h = sol[1];
    }
    best.position_m = {x, h};
    // ε_scaled = ε · η^(−RSS_max)... l² = ε_scaled·ρ_scaled = 10^((Γ − RSS)/(5n)) ⇒ Γ = RSS_max + 5n·log10(ε_scaled).
    best.gamma_dbm = rss_max + 5.0 * n * std::log10(sol[k - 1]);
  }
  return best;
}

std::optional<Vec2> l_shape(std::span<const Bin> bins, std::span<const std::size_t> leg1, std::span<const std::size_t> leg2,
                            const RegressionOptions& opt) {
  std::vector<Vec2> cand[2];
  const std::span<const std::size_t> legs[2] = {leg1, leg2};
  for (int l = 0; l < 2; ++l) {
    const auto& idx = legs[l];
    if (idx.size() < 4) return std::nullopt;
    // The leg's line: principal axis of its bins (a bin straddling the corner barely tilts it), and
    // only the bins on that line (within 0.25 m): the straight fit sees the along-leg coordinate only.
    Vec2 origin{0.0, 0.0};
    for (std::size_t i : idx) origin += bins[i].observer_m;
    origin /= static_cast<double>(idx.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (std::size_t i : idx) {
      const Vec2 d = bins[i].observer_m - origin;
      scatter += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(scatter);
    Vec2 dir = eig.eigenvectors().col(1);
    if (eig.eigenvalues()[1] < 0.25 * 0.25 * static_cast<double>(idx.size()) / 12.0) return std::nullopt;  // no extent
    const Vec2 left{-dir.y(), dir.x()};
    std::vector<Vec2> local;
    std::vector<double> rss;
    for (std::size_t i : idx) {
      const Vec2 d = bins[i].observer_m - origin;
      if (std::abs(d.dot(left)) > 0.25) continue;
      local.emplace_back(d.dot(dir), 0.0);
      rss.push_back(bins[i].rssi_dbm);
    }
    if (local.size() < 4) return std::nullopt;
    RegressionOptions o = opt;
    o.straight = true;
    const RegressionFit f = elliptical_regression(local, rss, o);
    if (!f.ok) return std::nullopt;
    // Leg-local (x along the leg, |h| across it), mirrored: origin + x·dir ± h·left.
    cand[l].push_back(origin + f.position_m.x() * dir + f.position_m.y() * left);
    cand[l].push_back(origin + f.position_m.x() * dir - f.position_m.y() * left);
  }
  double best = std::numeric_limits<double>::infinity();
  Vec2 out{0.0, 0.0};
  for (const Vec2& p : cand[0])
    for (const Vec2& q : cand[1])
      if ((p - q).norm() < best) {
        best = (p - q).norm();
        out = 0.5 * (p + q);
      }
  return out;
}

// ---------------------------------------------------------------------------------------------------
// Posterior

PositionPosterior::PositionPosterior(const PosteriorOptions& opt) : opt_(opt) {
  if (!(opt.gamma_sd_db > 0.0) || !(opt.n_sd > 0.0) || !(opt.shadowing_sd_db >= 0.0) || !(opt.fading_sd_db >= 0.0) ||
      !(opt.shadowing_sd_db + opt.fading_sd_db > 0.0))
    throw std::invalid_argument("PositionPosterior: the prior and noise standard deviations must be positive");
  if (!(opt.search_radius_m > 0.0) || !(opt.grid_step_m > 0.0) || opt.grid_step_m > opt.search_radius_m)
    throw std::invalid_argument("PositionPosterior: need 0 < grid_step_m <= search_radius_m");
  if (!(opt.min_distance_m > 0.0)) throw std::invalid_argument("PositionPosterior: min_distance_m must be > 0");
}

namespace {

struct Moments {
  double sum = 0.0, mx = 0.0, my = 0.0, sxx = 0.0, syy = 0.0, sxy = 0.0;
  double max_log = -std::numeric_limits<double>::infinity();
  double map_x = 0.0, map_y = 0.0;
};

}  // namespace

TagEstimate PositionPosterior::solve(std::span<const Bin> bins, const Vec2& leg_axis, const TagEstimate* wider) {
  TagEstimate est;
  est.bins = static_cast<int>(bins.size());
  if (bins.size() < 2) {
    est.why = "fewer than 2 positions along the walk with readings";
    return est;
  }
  const std::size_t nb = bins.size();
  // Per-bin weights and constants of the (Γ, n) problem: r_k = Γ + n·L_k + e_k, L_k = −10·log10(d_k).
  double sw = 0.0, sr = 0.0, srr = 0.0;
  std::vector<float> bx(nb), by(nb), bw(nb), br(nb);
  Vec2 centre{0.0, 0.0};
  const double sh2 = opt_.shadowing_sd_db * opt_.shadowing_sd_db, f2 = opt_.fading_sd_db * opt_.fading_sd_db;
  for (std::size_t k = 0; k < nb; ++k) {
    const double w = 1.0 / (sh2 + f2 / std::max(bins[k].count, 1));
    bx[k] = static_cast<float>(bins[k].observer_m.x());
    by[k] = static_cast<float>(bins[k].observer_m.y());
    bw[k] = static_cast<float>(w);
    br[k] = static_cast<float>(bins[k].rssi_dbm);
    sw += w;
    sr += w * bins[k].rssi_dbm;
    srr += w * bins[k].rssi_dbm * bins[k].rssi_dbm;
    centre += bins[k].observer_m;
  }
  centre /= static_cast<double>(nb);
  const double ig = 1.0 / (opt_.gamma_sd_db * opt_.gamma_sd_db), in = 1.0 / (opt_.n_sd * opt_.n_sd);
  const double g0 = opt_.gamma_mean_dbm, n0 = opt_.n_mean;
  const double a = sw + ig;
  const double konst = srr + g0 * g0 * ig + n0 * n0 * in;
  const float dmin2 = static_cast<float>(opt_.min_distance_m * opt_.min_distance_m);

  // Log marginal likelihood of one cell (closed form over Γ, n).
  auto cell_logml = [&](double sl, double sll, double srl) {
    const double b = sl, c = sll + in;
    const double bg = sr + g0 * ig, bn = srl + n0 * in;
    const double det = a * c - b * b;
    const double quad = (c * bg * bg - 2.0 * b * bg * bn + a * bn * bn) / det;
    return -0.5 * (konst - quad) - 0.5 * 2.302585093 * static_cast<double>(fast_log10(static_cast<float>(det)));
  };

  // Evaluates a grid (x0 + i·step, y0 + j·step), i < nx, j < ny, into logml_ and returns its moments.
  auto evaluate = [&](double x0, double y0, double step, int nx, int ny) {
    const std::size_t cells = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
    if (logml_.size() < 3 * cells) logml_.resize(3 * cells);
    float* sl = logml_.data();
    float* sll = sl + cells;
    float* srl = sll + cells;
    std::fill(logml_.begin(), logml_.begin() + static_cast<std::ptrdiff_t>(3 * cells), 0.0f);
    for (std::size_t k = 0; k < nb; ++k) {
      const float w = bw[k], r = br[k];
      for (int j = 0; j < ny; ++j) {
        const float dy = static_cast<float>(y0 + j * step) - by[k];
        const float dy2 = dy * dy;
        float* psl = sl + static_cast<std::size_t>(j) * static_cast<std::size_t>(nx);
        float* psll = sll + static_cast<std::size_t>(j) * static_cast<std::size_t>(nx);
        float* psrl = srl + static_cast<std::size_t>(j) * static_cast<std::size_t>(nx);
        accumulate_row(static_cast<float>(x0) - bx[k], static_cast<float>(step), dy2, dmin2, w, r, nx, psl, psll, psrl);
      }
    }
    Moments mo;
    // First pass: log-likelihoods (in place of sl) and the maximum.
    for (std::size_t c = 0; c < cells; ++c) {
      const double v = cell_logml(sl[c], sll[c], srl[c]);
      sl[c] = static_cast<float>(v);
      if (v > mo.max_log) {
        mo.max_log = v;
        mo.map_x = x0 + static_cast<double>(c % static_cast<std::size_t>(nx)) * step;
        mo.map_y = y0 + static_cast<double>(c / static_cast<std::size_t>(nx)) * step;
      }
    }
    // Second pass: the cell probabilities (stored in place for the mirror statistic) and moments.
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        float& cell = sl[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i)];
        const double p = std::exp(static_cast<float>(static_cast<double>(cell) - mo.max_log));
        cell = static_cast<float>(p);
        const double x = x0 + i * step, y = y0 + j * step;
        mo.sum += p;
        mo.mx += p * x;
        mo.my += p * y;
        mo.sxx += p * x * x;
        mo.syy += p * y * y;
        mo.sxy += p * x * y;
      }
    return mo;
  };

  const double step = opt_.grid_step_m;
  int half = static_cast<int>(std::ceil(opt_.search_radius_m / step));
  if (wider != nullptr && wider->ok && 3.0 * wider->std_m + step < opt_.search_radius_m) {
    centre = wider->position_m;
    half = static_cast<int>(std::ceil((3.0 * wider->std_m + step) / step));
  }
  Moments mo = evaluate(centre.x() - half * step, centre.y() - half * step, step, 2 * half + 1, 2 * half + 1);
  auto finish_moments = [&](const Moments& m, double cell) {
    est.position_m = {m.mx / m.sum, m.my / m.sum};
    est.cov_m2(0, 0) = m.sxx / m.sum - est.position_m.x() * est.position_m.x() + cell * cell / 12.0;
    est.cov_m2(1, 1) = m.syy / m.sum - est.position_m.y() * est.position_m.y() + cell * cell / 12.0;
    est.cov_m2(0, 1) = est.cov_m2(1, 0) = m.sxy / m.sum - est.position_m.x() * est.position_m.y();
    est.std_m = std::sqrt(std::max(est.cov_m2.trace(), 0.0));
    est.map_m = {m.map_x, m.map_y};
  };
  finish_moments(mo, step);
  // Mirror statistic on the coarse grid (its cell probabilities are still in logml_): mass on the other side of the first leg's
  // line (through the origin) from the mean.
  if (leg_axis.norm() > 0.5) {
    const Vec2 ax = leg_axis.normalized();
    const double side_mean = ax.x() * est.position_m.y() - ax.y() * est.position_m.x();
    const int n = 2 * half + 1;
    double other = 0.0, total = 0.0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const double x = centre.x() + (i - half) * step, y = centre.y() + (j - half) * step;
        const double p = logml_[static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)];
        total += p;
        if ((ax.x() * y - ax.y() * x) * side_mean < 0.0) other += p;
      }
    est.mirror_mass = total > 0.0 ? other / total : 0.0;
  }
  // The whole-square posterior, for the clustering's co-location test.
  if (wider == nullptr) {
    const int n = 2 * half + 1;
    est.grid.x0_m = centre.x() - half * step;
    est.grid.y0_m = centre.y() - half * step;
    est.grid.step_m = step;
    est.grid.n = n;
    est.grid.p.assign(logml_.begin(), logml_.begin() + static_cast<std::ptrdiff_t>(n) * n);
    const double inv = mo.sum > 0.0 ? 1.0 / mo.sum : 0.0;
    for (float& v : est.grid.p) v = static_cast<float>(v * inv);
  }
  // A concentrated posterior (std under 2 cells): again on a finer grid of 25 x 25 cells spanning
  // ±3 std around the most probable cell (cell = std/4), so that the mean and covariance of a peak
  // narrower than the coarse grid are not quantised.
  if (est.std_m < 2.0 * step) {
    const double fine = std::max(est.std_m / 4.0, 0.02);
    const int fh = 12;
    mo = evaluate(est.map_m.x() - fh * fine, est.map_m.y() - fh * fine, fine, 2 * fh + 1, 2 * fh + 1);
    finish_moments(mo, fine);
  }

  // (Γ, n) at the estimate and the paper's δ_RS statistics there.
  double sl = 0.0, sll = 0.0, srl = 0.0;
  std::vector<double> lk(nb);
  for (std::size_t k = 0; k < nb; ++k) {
    const double d = std::max((bins[k].observer_m - est.position_m).norm(), opt_.min_distance_m);
    lk[k] = -10.0 * std::log10(d);
    sl += bw[k] * lk[k];
    sll += bw[k] * lk[k] * lk[k];
    srl += bw[k] * lk[k] * bins[k].rssi_dbm;
  }
  Eigen::Matrix2d lam;
  lam << a, sl, sl, sll + in;
  const Eigen::Vector2d rhs(sr + g0 * ig, srl + n0 * in);
  const Eigen::Vector2d theta = lam.ldlt().solve(rhs);
  est.gamma_dbm = theta[0];
  est.n = theta[1];
  double mu = 0.0, var = 0.0;
  for (std::size_t k = 0; k < nb; ++k) mu += bw[k] * (bins[k].rssi_dbm - theta[0] - theta[1] * lk[k]);
  mu /= sw;
  for (std::size_t k = 0; k < nb; ++k) {
    const double e = bins[k].rssi_dbm - theta[0] - theta[1] * lk[k] - mu;
    var += bw[k] * e * e;
  }
  var /= sw;
  double chi2 = 0.0;
  for (std::size_t k = 0; k < nb; ++k) {
    const double e = bins[k].rssi_dbm - theta[0] - theta[1] * lk[k];
    chi2 += bw[k] * e * e;
  }
  est.noise_ratio = nb > 4 ? std::sqrt(chi2 / static_cast<double>(nb - 4)) : 1.0;  // 4 fitted: x, y, Γ, n
  est.residual_mean_db = mu;
  est.residual_sd_db = std::sqrt(var);
  const double sigma = std::max(est.residual_sd_db, 0.5);
  // P(μ) with P ~ N(0, σ) (Sec. 5), scaled to 1 at μ = 0, times how concentrated the posterior is
  // (1 at a point, 1/2 at a 1 m std): the weight Algo. 2 fuses a cluster's estimates with.
  est.confidence = std::exp(-0.5 * (mu / sigma) * (mu / sigma)) / (1.0 + est.std_m * est.std_m);
  est.ok = std::isfinite(est.position_m.x()) && std::isfinite(est.position_m.y()) && std::isfinite(est.std_m);
  if (!est.ok) est.why = "the posterior is not finite (degenerate readings)";
  return est;
}

TagEstimate PositionPosterior::solve_coarse_to_fine(std::span<const Bin> bins, const Vec2& leg_axis,
                                                    bool adaptive_noise, double min_noise_ratio) {
  const PosteriorOptions saved = opt_;
  opt_.grid_step_m = std::min(2.0 * saved.grid_step_m, saved.search_radius_m);
  const TagEstimate coarse = solve(bins, leg_axis);
  opt_ = saved;
  if (!coarse.ok) return coarse;
  if (adaptive_noise && coarse.noise_ratio < 0.9) {
    const double r = std::max(coarse.noise_ratio, min_noise_ratio);
    opt_.shadowing_sd_db *= r;
    opt_.fading_sd_db *= r;
  }
  // A wide posterior needs no finer cells than the coarse ones; a narrow one is refined inside
  // solve() (std under 2 cells: 25 x 25 cells of std/4).
  if (coarse.std_m > 4.0 * saved.grid_step_m) opt_.grid_step_m = std::min(2.0 * saved.grid_step_m, saved.search_radius_m);
  TagEstimate fine = solve(bins, leg_axis, &coarse);
  opt_ = saved;
  if (!fine.ok) return coarse;
  fine.mirror_mass = coarse.mirror_mass;
  fine.grid = coarse.grid;
  return fine;
}

double PosteriorGrid::at(double x_m, double y_m) const noexcept {
  if (p.empty() || !(step_m > 0.0)) return 0.0;
  const long i = std::lround((x_m - x0_m) / step_m), j = std::lround((y_m - y0_m) / step_m);
  if (i < 0 || j < 0 || i >= n || j >= n) return 0.0;
  return p[static_cast<std::size_t>(j) * static_cast<std::size_t>(n) + static_cast<std::size_t>(i)];
}

double colocation_bayes_factor(const PosteriorGrid& a, const PosteriorGrid& b) {
  if (a.empty() || b.empty()) return 0.0;
  const double area = (a.step_m * a.step_m) / (b.step_m * b.step_m);  // b's cell probabilities per a-cell
  double s = 0.0;
  for (int j = 0; j < a.n; ++j)
    for (int i = 0; i < a.n; ++i) {
      const double pa = a.p[static_cast<std::size_t>(j) * static_cast<std::size_t>(a.n) + static_cast<std::size_t>(i)];
      if (pa > 0.0) s += pa * b.at(a.x0_m + i * a.step_m, a.y0_m + j * a.step_m) * area;
    }
  return static_cast<double>(a.n) * static_cast<double>(a.n) * s;
}

// ---------------------------------------------------------------------------------------------------
// Sec. 6

std::vector<std::size_t> cluster_members(std::span<const float> target, const std::vector<std::vector<float>>& others,
                                         const ClusterOptions& opt) {
  if (opt.segment < 2) throw std::invalid_argument("cluster_members: segment must be >= 2");
  std::vector<std::size_t> members;
  if (target.size() < opt.segment + 1) return members;
  std::vector<float> dt(target.size() - 1);
  for (std::size_t i = 0; i + 1 < target.size(); ++i) dt[i] = target[i + 1] - target[i];
  const std::size_t segs = dt.size() / opt.segment;
  dsp::Dtw dtw(opt.segment);
  std::vector<float> up(opt.segment), lo(opt.segment), ds(opt.segment);
  for (std::size_t o = 0; o < others.size(); ++o) {
    const auto& s = others[o];
    if (s.size() != target.size())
      throw std::invalid_argument("cluster_members: every trace must be on the target's grid (same length)");
    std::size_t comparable = 0, matched = 0;
    for (std::size_t g = 0; g < segs; ++g) {
      const std::size_t i0 = g * opt.segment;
      bool ok = true;
      for (std::size_t i = 0; i < opt.segment && ok; ++i) {
        const float v = s[i0 + i + 1] - s[i0 + i];
        ok = std::isfinite(v) && std::isfinite(dt[i0 + i]);
        ds[i] = v;
      }
      if (!ok) continue;
      ++comparable;
      const std::span<const float> ts(dt.data() + i0, opt.segment);
      dsp::lb_keogh_envelope(ts, opt.window, up, lo);
      if (dsp::lb_keogh(ds, up, lo, dsp::DtwCost::Squared, opt.threshold) > opt.threshold) continue;
      if (dtw.distance(ts, ds, opt.window, opt.threshold) <= opt.threshold) ++matched;
    }
    if (comparable > 0 && 2 * matched > comparable) members.push_back(o);
  }
  return members;
}

std::vector<std::vector<bool>> cluster_matrix(const std::vector<std::vector<float>>& traces, const ClusterOptions& opt) {
  if (opt.segment < 2) throw std::invalid_argument("cluster_matrix: segment must be >= 2");
  const std::size_t n = traces.size();
  std::vector<std::vector<bool>> m(n, std::vector<bool>(n, false));
  if (n == 0) return m;
  const std::size_t len = traces[0].size();
  for (const auto& t : traces)
    if (t.size() != len) throw std::invalid_argument("cluster_matrix: every trace must be on one grid (same length)");
  if (len < opt.segment + 1) return m;
  const std::size_t segs = (len - 1) / opt.segment, seg = opt.segment;
  // Differences, a finite flag and the LB_Keogh envelope per trace and segment, once.
  std::vector<std::vector<float>> d(n, std::vector<float>(segs * seg)), up(n, std::vector<float>(segs * seg)),
      lo(n, std::vector<float>(segs * seg));
  std::vector<std::vector<char>> finite(n, std::vector<char>(segs, 1));
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t g = 0; g < segs; ++g) {
      for (std::size_t i = 0; i < seg; ++i) {
        const float v = traces[k][g * seg + i + 1] - traces[k][g * seg + i];
        d[k][g * seg + i] = v;
        if (!std::isfinite(v)) finite[k][g] = 0;
      }
      if (finite[k][g])
        dsp::lb_keogh_envelope(std::span<const float>(d[k].data() + g * seg, seg), opt.window,
                               std::span<float>(up[k].data() + g * seg, seg), std::span<float>(lo[k].data() + g * seg, seg));
    }
  dsp::Dtw dtw(seg);
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n; ++b) {
      std::size_t comparable = 0, matched = 0;
      for (std::size_t g = 0; g < segs; ++g) {
        if (!finite[a][g] || !finite[b][g]) continue;
        ++comparable;
        const std::span<const float> sa(d[a].data() + g * seg, seg), sb(d[b].data() + g * seg, seg);
        if (dsp::lb_keogh(sb, std::span<const float>(up[a].data() + g * seg, seg), std::span<const float>(lo[a].data() + g * seg, seg),
                          dsp::DtwCost::Squared, opt.threshold) > opt.threshold)
          continue;
        if (dtw.distance(sa, sb, opt.window, opt.threshold) <= opt.threshold) ++matched;
      }
      if (comparable > 0 && 2 * matched > comparable) m[a][b] = m[b][a] = true;
    }
  return m;
}

Vec2 fuse(std::span<const Vec2> positions, std::span<const double> weights) {
  if (positions.size() != weights.size()) throw std::invalid_argument("fuse: positions and weights differ in size");
  double sw = 0.0;
  Vec2 acc{0.0, 0.0};
  for (std::size_t i = 0; i < positions.size(); ++i) {
    if (!(weights[i] > 0.0) || !std::isfinite(weights[i])) continue;
    sw += weights[i];
    acc += weights[i] * positions[i];
  }
  if (!(sw > 0.0)) throw std::invalid_argument("fuse: no positive weight");
  return acc / sw;
}

}  // namespace locus::plugins::locble
