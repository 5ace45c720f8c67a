// AMIL positioning: the paper's closed form + direction-majority filter, and the joint
// position + clock-skew least squares (plain and robust). See solver.hpp for the model and why.
//
// Internals work in metres: with q = (x, y, b, g), b = c·tau, g = c·s and the reference beep r (the
// first heard one), the residual of beep k is
//
//     res_k = c·y_k − b − g·(Δe_k + d_k/c) − d_k,   y_k = (a_k − a_r) − (e_k − e_r),  Δe_k = e_k − e_r,
//
// d_k = |x − p_k|, which is exact for the model a_k = tau0 + (1 + s)(e_k + d_k/c). For a fixed x the
// residual is linear in (b, g) (variable projection), which makes a global grid over x cheap; the
// far-field linearisation d_k ≈ R − u·p_k gives the direction without any search.
#include "solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "locus/angles.hpp"
#include "locus/numbers.hpp"

namespace locus::plugins::amil {

namespace {

constexpr double kReliableTimingFactor = 5.0;  // an arrival is reliable when its timing std <= this x the base

/// The heard beeps of one listener, in metres, relative to the first heard beep.
struct Obs {
  std::vector<Eigen::Vector2d> p;  ///< beep positions
  std::vector<double> de;          ///< Δe_k (s)
  std::vector<double> cy;          ///< c·y_k (m)
  std::vector<double> sigma;       ///< residual 1-sigma (m)
  std::vector<int> index;          ///< index into the caller's beeps
  std::vector<double> a, e;        ///< raw times (Paper)
  std::vector<double> pos_var;     ///< the beep position's error variance per axis (m²; 0 without)
  double c = 343.2;
  int n() const { return static_cast<int>(p.size()); }
};

struct Fit {
  Eigen::Vector2d x{kNaN, kNaN};
  double b = 0.0, g = 0.0;
  double cost = std::numeric_limits<double>::infinity();  ///< Σ w_k (res_k/σ_k)²
  bool ok = false;
};


/// Variable projection: best (b, g) for a fixed x, and the weighted cost. W_k = w_k/σ_k².
double varpro_cost(const Obs& o, const double* W, const Eigen::Vector2d& x, double* b_out = nullptr,
                   double* g_out = nullptr) {
  double s11 = 0, s12 = 0, s22 = 0, t1 = 0, t2 = 0, zz = 0;
  const int n = o.n();
  const double ic = 1.0 / o.c;
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double d = (x - o.p[ku]).norm();
    const double wk = W[k];
    const double r2 = o.de[ku] + d * ic;
    const double z = o.cy[ku] - d;
    s11 += wk;
    s12 += wk * r2;
    s22 += wk * r2 * r2;
    t1 += wk * z;
    t2 += wk * r2 * z;
    zz += wk * z * z;
  }
  const double det = s11 * s22 - s12 * s12;
  double b = 0, g = 0;
  if (std::abs(det) > 1e-18 * std::max(1.0, s11 * s22)) {
    b = (s22 * t1 - s12 * t2) / det;
    g = (s11 * t2 - s12 * t1) / det;
  } else if (s11 > 0) {
    b = t1 / s11;
  }
  // Σ W (z − b − g r2)² expanded (exact for the least-squares b, g up to rounding; clamp at 0)
  const double cost = std::max(0.0, zz - 2.0 * b * t1 - 2.0 * g * t2 + b * b * s11 + 2.0 * b * g * s12 + g * g * s22);
  if (b_out) *b_out = b;
  if (g_out) *g_out = g;
  return cost;
}

double varpro_cost(const Obs& o, const std::vector<double>& w, const Eigen::Vector2d& x, double* b_out = nullptr,
                   double* g_out = nullptr) {
  double Wst[64] = {};
  std::vector<double> Wh;
  double* W = Wst;
  if (o.n() > 64) {
    Wh.resize(static_cast<std::size_t>(o.n()));
    W = Wh.data();
  }
  for (int k = 0; k < o.n(); ++k) W[k] = w[static_cast<std::size_t>(k)] / (o.sigma[static_cast<std::size_t>(k)] * o.sigma[static_cast<std::size_t>(k)]);
  return varpro_cost(o, W, x, b_out, g_out);
}

/// Residuals (m) and Jacobian rows for q = (x, y, b, g); with fixed_g the g column is dropped.
void residuals(const Obs& o, const Eigen::Vector4d& q, Eigen::VectorXd& r, Eigen::MatrixXd& J) {
  const int n = o.n();
  r.resize(n);
  J.resize(n, 4);
  const Eigen::Vector2d x = q.head<2>();
  const double b = q[2], g = q[3];
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const Eigen::Vector2d diff = x - o.p[ku];
    const double d = std::max(diff.norm(), 1e-9);
    r[k] = o.cy[ku] - b - g * (o.de[ku] + d / o.c) - d;
    const Eigen::Vector2d dd = diff / d;
    const double f = 1.0 + g / o.c;
    J(k, 0) = -f * dd.x();
    J(k, 1) = -f * dd.y();
    J(k, 2) = -1.0;
    J(k, 3) = -(o.de[ku] + d / o.c);
  }
}

/// Normal equations of the weighted problem at q (weights W_k = w_k/σ_k²): A = JᵀWJ, grad = JᵀWr.
struct Normal {
  Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
  Eigen::Vector4d grad = Eigen::Vector4d::Zero();
  double cost = 0.0;
};

Normal accumulate(const Obs& o, const std::vector<double>& w, const Eigen::Vector4d& q) {
  Normal ne;
  const Eigen::Vector2d x = q.head<2>();
  const double b = q[2], g = q[3];
  const double f = 1.0 + g / o.c;
  for (int k = 0; k < o.n(); ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const Eigen::Vector2d diff = x - o.p[ku];
    const double d = std::max(diff.norm(), 1e-9);
    const double r = o.cy[ku] - b - g * (o.de[ku] + d / o.c) - d;
    const double W = w[ku] / (o.sigma[ku] * o.sigma[ku]);
    const Eigen::Vector4d j(-f * diff.x() / d, -f * diff.y() / d, -1.0, -(o.de[ku] + d / o.c));
    ne.A.noalias() += W * j * j.transpose();
    ne.grad.noalias() += W * r * j;
    ne.cost += W * r * r;
  }
  return ne;
}

double cost_at(const Obs& o, const std::vector<double>& w, const Eigen::Vector4d& q) {
  double cost = 0.0;
  const Eigen::Vector2d x = q.head<2>();
  for (int k = 0; k < o.n(); ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double d = std::max((x - o.p[ku]).norm(), 1e-9);
    const double r = o.cy[ku] - q[2] - q[3] * (o.de[ku] + d / o.c) - d;
    cost += w[ku] * r * r / (o.sigma[ku] * o.sigma[ku]);
  }
  return cost;
}

/// Levenberg-Marquardt from q with weights w (IRLS weights × 1/σ²). free_g = false keeps g fixed.
Fit levenberg_marquardt(const Obs& o, const std::vector<double>& w, Eigen::Vector4d q, bool free_g, int max_iter,
                        double max_range_m) {
  const int np = free_g ? 4 : 3;
  Normal ne = accumulate(o, w, q);
  double lambda = 1e-3;
  for (int it = 0; it < max_iter; ++it) {
    bool improved = false;
    bool converged = false;
    for (int tries = 0; tries < 10; ++tries) {
      Eigen::Matrix4d Ad = ne.A;
      for (int i = 0; i < 4; ++i) Ad(i, i) += lambda * std::max(ne.A(i, i), 1e-12);
      Eigen::Vector4d step = Eigen::Vector4d::Zero();
      if (np == 4) step = Ad.ldlt().solve(-ne.grad);
      else step.head<3>() = Ad.topLeftCorner<3, 3>().ldlt().solve(-ne.grad.head<3>());
      if (!step.allFinite()) {
        lambda *= 10;
        continue;
      }
      const Eigen::Vector4d qn = q + step;
      if (qn.head<2>().norm() > 4.0 * max_range_m) {  // runaway: treat as a rejected step
        lambda *= 10;
        continue;
      }
      const double cn = cost_at(o, w, qn);
      if (cn <= ne.cost) {
        const double drop = ne.cost - cn;
        q = qn;
        ne = accumulate(o, w, q);
        lambda = std::max(lambda / 10.0, 1e-9);
        improved = true;
        converged = drop <= 1e-10 * std::max(ne.cost, 1e-3) || step.head<2>().norm() < 1e-8;
        break;
      }
      lambda *= 10;
    }
    if (!improved || converged) break;
  }
  Fit f;
  f.x = q.head<2>();
  f.b = q[2];
  f.g = q[3];
  f.cost = ne.cost;
  f.ok = q.allFinite();
  return f;
}

/// Covariance of (x, y, b[, g]) at q with a-priori sigmas (weights w); NaN when singular.
Eigen::MatrixXd covariance(const Obs& o, const std::vector<double>& w, const Eigen::Vector4d& q, bool free_g) {
  const Normal ne = accumulate(o, w, q);
  const int np = free_g ? 4 : 3;
  const Eigen::MatrixXd F = ne.A.topLeftCorner(np, np);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(F);
  if (lu.rank() < np) return Eigen::MatrixXd::Constant(np, np, kNaN);
  return lu.inverse();
}

/// Covariance of (x, y, b, g) of the fit with weights w when the beep position errors are not
/// independent but accumulate along the gesture, as the tracker's do (each movement adds its error to
/// every later pause: a random walk, so Cov(δp_k, δp_l) = min(var_k, var_l) per axis for beeps in time
/// order). The estimator weights them as independent; its actual covariance is the sandwich
/// A⁻¹ (Jᵀ W C W J) A⁻¹ with C_kl = δ_kl·σ_k² + (1 − δ_kl)·min(var_k, var_l)·(∂r_k/∂p_k · ∂r_l/∂p_l).
/// Correlated errors mostly move the beeps together, which the curvature (the distance) barely sees:
/// the diagonal model overstated a near listener's distance std about twice
/// (AmilBound.ReportedStdFollowsTheTrackersAccumulatedErrors, docs/amil.md).
Eigen::MatrixXd accumulated_covariance(const Obs& o, const std::vector<double>& w, const Eigen::Vector4d& q) {
  const int n = o.n();
  if (static_cast<int>(o.pos_var.size()) != n) return covariance(o, w, q, true);
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  residuals(o, q, r, J);
  Eigen::VectorXd W(n);
  std::vector<Eigen::Vector2d> g(static_cast<std::size_t>(n));  // ∂r_k/∂p_k = −∂r_k/∂x
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    W[k] = w[ku] / (o.sigma[ku] * o.sigma[ku]);
    g[ku] = -Eigen::Vector2d(J(k, 0), J(k, 1));
  }
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    C(k, k) = o.sigma[ku] * o.sigma[ku];  // timing + this beep's own position variance
    for (int l = 0; l < k; ++l) {
      const auto lu = static_cast<std::size_t>(l);
      C(k, l) = C(l, k) = std::min(o.pos_var[ku], o.pos_var[lu]) * g[ku].dot(g[lu]);
    }
  }
  const Eigen::MatrixXd WJ = W.asDiagonal() * J;
  const Eigen::Matrix4d A = J.transpose() * WJ;
  Eigen::FullPivLU<Eigen::Matrix4d> lu(A);
  if (lu.rank() < 4) return Eigen::MatrixXd::Constant(4, 4, kNaN);
  const Eigen::Matrix4d Ai = lu.inverse();
  return Ai * (WJ.transpose() * C * WJ) * Ai;
}

/// Fills std/direction/distance fields from a 2x2 position covariance.
void fill_uncertainty(Solution& s, const Eigen::Matrix2d& P) {
  const double r = s.position_m.norm();
  s.std_m = std::sqrt(std::max(0.0, P.trace()));
  if (r > 1e-9) {
    const Eigen::Vector2d u = s.position_m / r;
    const Eigen::Vector2d v(-u.y(), u.x());
    s.distance_std_m = std::sqrt(std::max(0.0, u.dot(P * u)));
    s.direction_std_rad = std::sqrt(std::max(0.0, v.dot(P * v))) / r;
  }
}

double geometry_confidence(double rel_std) {
  if (!std::isfinite(rel_std)) return 0.0;
  return 1.0 / (1.0 + (rel_std / 0.2) * (rel_std / 0.2));
}

double fit_confidence(double chi2, int dof) {
  if (dof <= 0 || !std::isfinite(chi2)) return 1.0;
  const double excess = std::max(0.0, chi2 / dof - 1.0);
  return std::exp(-excess / 8.0);
}

/// Far-field linearisation: c·y_k ≈ B + g·Δe_k − u·p_k (u = unit direction to the listener, scaled).
/// Returns the direction, or NaN when the design is degenerate (collinear beeps with Δe, too few).
double far_field_direction(const Obs& o) {
  const int n = o.n();
  if (n < 4) return kNaN;
  Eigen::MatrixXd A(n, 4);
  Eigen::VectorXd z(n);
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    const double wk = 1.0 / o.sigma[ku];
    A(k, 0) = wk;
    A(k, 1) = wk * o.de[ku];
    A(k, 2) = -wk * o.p[ku].x();
    A(k, 3) = -wk * o.p[ku].y();
    z[k] = wk * o.cy[ku];
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 4) return kNaN;
  const Eigen::Vector4d sol = qr.solve(z);
  if (!sol.allFinite() || std::hypot(sol[2], sol[3]) < 1e-6) return kNaN;
  return std::atan2(sol[3], sol[2]);
}

struct GridMin {
  Eigen::Vector2d x;
  double cost;
};

/// Global search of the variable-projection cost on a polar grid (plus a fine fan around the
/// far-field direction); returns up to `keep` local minima, best first, at least 20° apart.
std::vector<GridMin> grid_search(const Obs& o, const std::vector<double>& w, double dir0, double rmin, double rmax,
                                 int keep) {
  // coarse everywhere (24 directions × 12 ranges), fine around the far-field direction (13 × 20)
  std::vector<double> W(static_cast<std::size_t>(o.n()));
  for (int k = 0; k < o.n(); ++k) {
    const auto ku = static_cast<std::size_t>(k);
    W[ku] = w[ku] / (o.sigma[ku] * o.sigma[ku]);
  }
  std::array<double, 12> r12{};
  std::array<double, 20> r20{};
  for (std::size_t i = 0; i < r12.size(); ++i) r12[i] = rmin * std::pow(rmax / rmin, static_cast<double>(i) / (r12.size() - 1));
  for (std::size_t i = 0; i < r20.size(); ++i) r20[i] = rmin * std::pow(rmax / rmin, static_cast<double>(i) / (r20.size() - 1));
  std::vector<GridMin> per_dir;
  auto scan = [&](double th, int nr) {
    const Eigen::Vector2d u(std::cos(th), std::sin(th));
    const double* radii = nr == 12 ? r12.data() : r20.data();
    GridMin best{u * rmin, std::numeric_limits<double>::infinity()};
    for (int i = 0; i < nr; ++i) {
      const double c = varpro_cost(o, W.data(), u * radii[i]);
      if (c < best.cost) best = {u * radii[i], c};
    }
    per_dir.push_back(best);
  };
  for (int i = 0; i < 24; ++i) scan(-kPi + i * (2.0 * kPi / 24), 12);
  if (std::isfinite(dir0))
    for (int i = -6; i <= 6; ++i) scan(wrap_pi(dir0 + i * (3.0 * kPi / 180.0)), 20);
  std::sort(per_dir.begin(), per_dir.end(), [](const GridMin& a, const GridMin& b) { return a.cost < b.cost; });
  std::vector<GridMin> out;
  for (const auto& m : per_dir) {
    bool far_from_all = true;
    const double th = std::atan2(m.x.y(), m.x.x());
    for (const auto& k : out)
      if (std::abs(wrap_pi(th - std::atan2(k.x.y(), k.x.x()))) < 20.0 * kPi / 180.0) far_from_all = false;
    if (far_from_all) out.push_back(m);
    if (static_cast<int>(out.size()) >= keep) break;
  }
  return out;
}

struct JointResult {
  Fit fit;
  std::vector<Fit> others;  ///< other converged local minima (ambiguity check)
  std::vector<double> w;    ///< final weights
  std::vector<int> dropped; ///< indices into Obs that were removed as outliers
  Obs used;                 ///< the observation set of the final fit
  bool ran_to_max = false;
};

Fit best_fit_from(const Obs& o, const std::vector<double>& w, const SolverConfig& cfg, std::vector<Fit>* others) {
  const double dir0 = far_field_direction(o);
  const auto starts = grid_search(o, w, dir0, std::max(cfg.min_range_m, 0.05), cfg.max_range_m, 2);
  Fit best;
  std::vector<Fit> all;
  for (const auto& st : starts) {
    double b = 0, g = 0;
    varpro_cost(o, w, st.x, &b, &g);
    Eigen::Vector4d q(st.x.x(), st.x.y(), b, g);
    Fit f = levenberg_marquardt(o, w, q, true, cfg.max_iterations, cfg.max_range_m);
    if (!f.ok) continue;
    all.push_back(f);
    if (f.cost < best.cost) best = f;
  }
  if (others) {
    for (const auto& f : all) {
      const double dth = std::abs(wrap_pi(std::atan2(f.x.y(), f.x.x()) - std::atan2(best.x.y(), best.x.x())));
      if (dth > 20.0 * kPi / 180.0) others->push_back(f);
    }
  }
  return best;
}

Obs subset(const Obs& o, const std::vector<int>& keep) {
  Obs s;
  s.c = o.c;
  for (int k : keep) {
    const auto ku = static_cast<std::size_t>(k);
    s.p.push_back(o.p[ku]);
    s.de.push_back(o.de[ku]);
    s.cy.push_back(o.cy[ku]);
    s.sigma.push_back(o.sigma[ku]);
    s.index.push_back(o.index[ku]);
    s.a.push_back(o.a[ku]);
    s.e.push_back(o.e[ku]);
    if (ku < o.pos_var.size()) s.pos_var.push_back(o.pos_var[ku]);
  }
  return s;
}

JointResult joint_solve(const Obs& o0, const SolverConfig& cfg, bool robust) {
  JointResult jr;
  jr.used = o0;
  for (int pass = 0;; ++pass) {
    const Obs& o = jr.used;
    const int n = o.n();
    std::vector<double> w(static_cast<std::size_t>(n), 1.0);
    std::vector<Fit> others;
    Fit f = best_fit_from(o, w, cfg, &others);
    if (!f.ok) {
      jr.fit = f;
      jr.w = w;
      return jr;
    }
    if (robust) {  // IRLS with the Huber loss, a-priori sigmas
      for (int it = 0; it < 6; ++it) {
        Eigen::VectorXd r;
        Eigen::MatrixXd J;
        residuals(o, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g), r, J);
        bool changed = false;
        for (int k = 0; k < n; ++k) {
          const auto ku = static_cast<std::size_t>(k);
          const double z = std::abs(r[k]) / o.sigma[ku];
          const double wn = z <= cfg.huber_k ? 1.0 : cfg.huber_k / z;
          if (std::abs(wn - w[ku]) > 1e-3) changed = true;
          w[ku] = wn;
        }
        if (!changed) break;
        f = levenberg_marquardt(o, w, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g), true, cfg.max_iterations,
                                cfg.max_range_m);
      }
    }
    jr.fit = f;
    jr.w = w;
    jr.others = others;
    if (!robust || n - 1 < 5 || static_cast<int>(jr.dropped.size()) >= std::max(1, n / 4)) return jr;
    // studentised residuals: drop the worst one beyond outlier_sigma, re-solve
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    residuals(o, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g), r, J);
    Eigen::MatrixXd Jw = J;
    for (int k = 0; k < n; ++k) Jw.row(k) /= o.sigma[static_cast<std::size_t>(k)];
    const Eigen::MatrixXd F = Jw.transpose() * Jw;
    Eigen::FullPivLU<Eigen::MatrixXd> lu(F);
    if (lu.rank() < 4) return jr;
    const Eigen::MatrixXd Fi = lu.inverse();
    int worst = -1;
    double worst_z = cfg.outlier_sigma;
    for (int k = 0; k < n; ++k) {
      const double h = Jw.row(k) * Fi * Jw.row(k).transpose();
      const double z = std::abs(r[k]) / o.sigma[static_cast<std::size_t>(k)] / std::sqrt(std::max(1e-6, 1.0 - h));
      if (z > worst_z) {
        worst_z = z;
        worst = k;
      }
    }
    if (worst < 0) return jr;
    jr.dropped.push_back(o.index[static_cast<std::size_t>(worst)]);
    std::vector<int> keep;
    for (int k = 0; k < n; ++k)
      if (k != worst) keep.push_back(k);
    jr.used = subset(o, keep);
  }
}

// ------------------------------------------------------------------------------------------ Paper

struct PaperResult {
  std::vector<Eigen::Vector2d> kept;
  std::vector<Eigen::Vector2d> all_points;
  double direction = kNaN;
  bool direction_only = false;
  bool ambiguous = false;
  int votes = 0;
  int subsets_with_points = 0;
};

/// A direction vote of one 3-beep subset: a point (in range) or only a direction.
struct Vote {
  double dir;
  bool point;
  Eigen::Vector2d x;
};

/// The majority window: the window [θ, θ + win] (θ = a vote's direction) holding the most votes; ties
/// go to the one with more points, then the tighter spread. Sets pr.direction, pr.kept and
/// pr.direction_only. Sorts `votes` by direction.
void majority_window(std::vector<Vote>& votes, double win, PaperResult& pr);

PaperResult paper_solve(const Obs& o, double skew, const SolverConfig& cfg) {
  PaperResult pr;
  const int n = o.n();
  // dd_k against the first heard beep, with the given skew
  std::vector<double> dd(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const auto ku = static_cast<std::size_t>(k);
    dd[ku] = o.c * ((o.a[ku] - o.a[0]) / (1.0 + skew) - (o.e[ku] - o.e[0]));
  }
  std::vector<Vote> votes;
  // per subset: its points (in range); two-solution subsets are resolved by the other subsets below
  std::vector<std::vector<Eigen::Vector2d>> subset_points;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k) {
        const auto iu = static_cast<std::size_t>(i), ju = static_cast<std::size_t>(j), kuu = static_cast<std::size_t>(k);
        const double ddj = dd[ju] - dd[iu], ddk = dd[kuu] - dd[iu];
        const auto pts = solve_three(o.p[iu], o.p[ju], o.p[kuu], ddj, ddk);
        std::vector<Eigen::Vector2d> in_range;
        bool any = false;
        for (const auto& x : pts) {
          const double r = x.norm();
          if (!(r >= cfg.min_range_m)) continue;
          any = true;
          if (r > cfg.max_range_m) votes.push_back({std::atan2(x.y(), x.x()), false, x});
          else in_range.push_back(x);
        }
        if (!in_range.empty()) subset_points.push_back(std::move(in_range));
        if (any) {
          ++pr.subsets_with_points;
          continue;
        }
        // triangle inequality broken: the direction along ∓ the movement of the violating pair
        const std::array<std::pair<std::size_t, double>, 2> legs{{{ju, ddj}, {kuu, ddk}}};
        for (const auto& [m, ddm] : legs) {
          const Eigen::Vector2d mv = o.p[m] - o.p[iu];
          const double L = mv.norm();
          if (L < 1e-6 || std::abs(ddm) < L) continue;
          const Eigen::Vector2d u = ddm > 0 ? Eigen::Vector2d(-mv / L) : Eigen::Vector2d(mv / L);
          votes.push_back({std::atan2(u.y(), u.x()), false, u});
        }
      }
  // Two solutions: pick the one the other subsets agree with (smallest summed distance to their
  // nearest candidate); a lone subset with two solutions keeps both (ambiguous).
  const std::size_t S = subset_points.size();
  for (std::size_t a = 0; a < S; ++a) {
    const auto& pa = subset_points[a];
    if (pa.size() == 2 && S > 1) {
      double score[2] = {0.0, 0.0};
      for (int c = 0; c < 2; ++c)
        for (std::size_t b = 0; b < S; ++b) {
          if (b == a) continue;
          double best = std::numeric_limits<double>::infinity();
          for (const auto& q : subset_points[b]) best = std::min(best, (q - pa[static_cast<std::size_t>(c)]).norm());
          score[c] += best;
        }
      const auto& x = pa[score[0] <= score[1] ? 0 : 1];
      votes.push_back({std::atan2(x.y(), x.x()), true, x});
      pr.all_points.push_back(x);
    } else {
      for (const auto& x : pa) {
        votes.push_back({std::atan2(x.y(), x.x()), true, x});
        pr.all_points.push_back(x);
      }
    }
  }
  if (S == 1 && subset_points[0].size() == 2) pr.ambiguous = true;
  pr.votes = static_cast<int>(votes.size());
  if (votes.empty()) return pr;
  majority_window(votes, cfg.direction_window_rad, pr);
  return pr;
}

void majority_window(std::vector<Vote>& votes, double win, PaperResult& pr) {
  std::sort(votes.begin(), votes.end(), [](const Vote& a, const Vote& b) { return a.dir < b.dir; });
  const std::size_t V = votes.size();
  auto ang = [&](std::size_t m) { return m < V ? votes[m].dir : votes[m - V].dir + 2.0 * kPi; };
  auto is_point = [&](std::size_t m) { return votes[m % V].point ? 1 : 0; };
  std::size_t best_i = 0, best_end = 1;  // members: [best_i, best_end) of the doubled list
  int best_count = -1, best_points = -1;
  double best_spread = 0;
  std::size_t end = 0;
  int pts = 0;
  for (std::size_t i = 0; i < V; ++i) {
    if (end < i) {
      end = i;
      pts = 0;
    }
    while (end < i + V && ang(end) - ang(i) <= win + 1e-12) pts += is_point(end++);
    const int cnt = static_cast<int>(end - i);
    const double spread = ang(end - 1) - ang(i);
    if (cnt > best_count || (cnt == best_count && pts > best_points) ||
        (cnt == best_count && pts == best_points && spread < best_spread)) {
      best_count = cnt;
      best_points = pts;
      best_spread = spread;
      best_i = i;
      best_end = end;
    }
    pts -= is_point(i);
  }
  std::vector<std::size_t> best_members;
  for (std::size_t m = best_i; m < best_end; ++m) best_members.push_back(m % V);
  double sx = 0, sy = 0;
  Eigen::Vector2d centroid(0, 0);
  int np = 0;
  for (std::size_t m : best_members) {
    sx += std::cos(votes[m].dir);
    sy += std::sin(votes[m].dir);
    if (votes[m].point) {
      centroid += votes[m].x;
      pr.kept.push_back(votes[m].x);
      ++np;
    }
  }
  pr.direction = std::atan2(sy, sx);
  if (np == 0) {
    pr.direction_only = true;
    return;
  }
  centroid /= np;
  pr.direction = std::atan2(centroid.y(), centroid.x());
}


/// The heard beeps of one listener (beeps with a player time, a position and an arrival). With
/// with_position_std the residual sigma includes the beep position error (per-listener solvers);
/// without, only the timing error (the network solver estimates the position errors).
Obs make_obs(const std::vector<Beep>& beeps, const ListenerArrivals& arr, const SolverConfig& cfg, bool with_position_std) {
  const double c = cfg.speed_of_sound_mps;
  const double tstd = std::isfinite(arr.timing_std_s) ? arr.timing_std_s : cfg.timing_std_s;
  Obs o;
  o.c = c;
  for (std::size_t k = 0; k < beeps.size(); ++k) {
    const Beep& b = beeps[k];
    const double a = arr.arrival_s[k];
    if (!std::isfinite(a) || !std::isfinite(b.player_time_s) || !b.position_m.allFinite()) continue;
    const double pstd = with_position_std ? (std::isfinite(b.position_std_m) ? b.position_std_m : cfg.position_std_m) : 0.0;
    const double tstd_k = k < arr.arrival_std_s.size() && std::isfinite(arr.arrival_std_s[k]) ? arr.arrival_std_s[k] : tstd;
    o.p.push_back(b.position_m);
    o.a.push_back(a);
    o.e.push_back(b.player_time_s);
    o.sigma.push_back(std::max(1e-7, std::sqrt(c * tstd_k * c * tstd_k + pstd * pstd)));
    o.pos_var.push_back(pstd * pstd);
    o.index.push_back(static_cast<int>(k));
  }
  for (int k = 0; k < o.n(); ++k) {
    const auto ku = static_cast<std::size_t>(k);
    o.de.push_back(o.e[ku] - o.e[0]);
    o.cy.push_back(c * ((o.a[ku] - o.a[0]) - (o.e[ku] - o.e[0])));
  }
  return o;
}

/// Distance, direction and the direction-only decision of a solution with a position.
void finish_position(Solution& s, const SolverConfig& cfg) {
  const double r = s.position_m.norm();
  s.distance_m = r;
  s.direction_rad = std::atan2(s.position_m.y(), s.position_m.x());
  const double rel = s.distance_std_m / std::max(r, 1e-9);
  if (r > cfg.max_range_m || !(rel <= cfg.max_relative_distance_std)) {
    s.status = Status::DirectionOnly;
    s.note += r > cfg.max_range_m ? "distance beyond max_range_m: direction only"
                                  : "distance not determined (relative std " + std::to_string(rel) + "): direction only";
    s.position_m = Eigen::Vector2d(kNaN, kNaN);
    s.distance_m = kNaN;
    s.std_m = kNaN;
  } else if (s.status != Status::Ambiguous) {
    s.status = Status::Located;
  }
}

void validate(const std::vector<Beep>& beeps, const ListenerArrivals& arr, const SolverConfig& cfg) {
  auto bad = [](const std::string& what) { throw std::invalid_argument("amil solver: " + what); };
  if (!arr.arrival_std_s.empty() && arr.arrival_std_s.size() != arr.arrival_s.size())
    bad("arrival_std_s has " + std::to_string(arr.arrival_std_s.size()) + " entries, expected 0 or one per arrival");
  if (!(arr.reference_offset_std_m >= 0.0)) bad("reference_offset_std_m must be >= 0");
  if (arr.arrival_s.size() != beeps.size())
    bad("arrivals has " + std::to_string(arr.arrival_s.size()) + " entries, expected one per beep (" +
        std::to_string(beeps.size()) + ")");
  if (!(cfg.speed_of_sound_mps > 100.0 && cfg.speed_of_sound_mps < 1000.0)) bad("speed_of_sound_mps must be in (100, 1000)");
  if (!(cfg.timing_std_s >= 0.0) || !(cfg.position_std_m >= 0.0)) bad("timing_std_s and position_std_m must be >= 0");
  if (!(cfg.timing_std_s > 0.0 || cfg.position_std_m > 0.0)) bad("timing_std_s and position_std_m cannot both be 0");
  if (!(cfg.direction_window_rad > 0.0 && cfg.direction_window_rad < kPi)) bad("direction_window_rad must be in (0, pi)");
  if (!std::isfinite(cfg.known_skew) || std::abs(cfg.known_skew) > 0.01) bad("known_skew must be finite, |skew| <= 0.01");
  if (!(cfg.max_abs_skew > 0.0)) bad("max_abs_skew must be > 0");
  if (!(cfg.huber_k > 0.0) || !(cfg.outlier_sigma > 0.0)) bad("huber_k and outlier_sigma must be > 0");
  if (!(cfg.min_range_m > 0.0 && cfg.max_range_m > cfg.min_range_m)) bad("need 0 < min_range_m < max_range_m");
  if (!(cfg.max_relative_distance_std > 0.0)) bad("max_relative_distance_std must be > 0");
  if (cfg.max_iterations < 1) bad("max_iterations must be >= 1");
}

}  // namespace

int resolve_cycles(const std::vector<Beep>& beeps, ListenerArrivals& arr, const SolverConfig& cfg,
                   const CycleOptions& opt, CycleAlternative* alternative) {
  if (alternative != nullptr) *alternative = CycleAlternative{};
  const double P = arr.carrier_period_s;
  if (!(P > 0.0) || arr.cycle_offset_s.size() != arr.arrival_s.size() || arr.arrival_s.size() != beeps.size())
    return 0;
  const double tstd = std::isfinite(arr.timing_std_s) ? arr.timing_std_s : cfg.timing_std_s;
  if (arr.arrival_std_s.size() != arr.arrival_s.size()) arr.arrival_std_s.assign(arr.arrival_s.size(), tstd);
  std::vector<int> shift(arr.arrival_s.size(), 0);  // applied so far, per caller index
  std::vector<int> doubtful;
  for (int round = 0; round < opt.max_rounds; ++round) {
    const Obs o = make_obs(beeps, arr, cfg, true);
    const int n = o.n();
    const int base = 2 * std::clamp(opt.max_shift, 1, 3) + 1;
    if (n < 5) return 0;  // 1 dof at least
    // Every combination up to 2e5 of them (one gesture: 5 beeps, 625); beyond (three gestures: 13
    // beeps, 5^12) a coordinate descent from no shift, its runner-up the best single change from it.
    const bool exhaustive = std::pow(static_cast<double>(base), n - 1) <= 2e5;
    const std::vector<double> w(static_cast<std::size_t>(n), 1.0);
    const Fit f = best_fit_from(o, w, cfg, nullptr);
    if (!f.ok) return 0;
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    residuals(o, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g), r, J);
    Eigen::VectorXd W(n);
    for (int k = 0; k < n; ++k) W[k] = 1.0 / (o.sigma[static_cast<std::size_t>(k)] * o.sigma[static_cast<std::size_t>(k)]);
    // M = W - W J (Jᵀ W J)⁻¹ Jᵀ W: chi² of the linearised refit for residuals r + c P n
    const Eigen::MatrixXd WJ = W.asDiagonal() * J;
    const Eigen::Matrix4d A = J.transpose() * WJ;
    const Eigen::FullPivLU<Eigen::Matrix4d> lu(A);
    if (lu.rank() < 4) return 0;
    const Eigen::MatrixXd M = Eigen::MatrixXd(W.asDiagonal()) - WJ * lu.solve(WJ.transpose());
    std::vector<double> off(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) off[static_cast<std::size_t>(k)] = arr.cycle_offset_s[static_cast<std::size_t>(o.index[static_cast<std::size_t>(k)])] / P;
    const double env_var = opt.envelope_std_periods * opt.envelope_std_periods;
    const double cP = o.c * P;
    // cy_k is relative to the first heard arrival: shifting arrival k by m_k periods adds c P (m_k - m_0)
    // to it, so m_0 = 0 and m_k in [-max_shift, max_shift].
    struct Score { double chi2; std::vector<int> m; double env; };
    Score best{std::numeric_limits<double>::infinity(), {}, 0.0}, second{std::numeric_limits<double>::infinity(), {}, 0.0};
    std::vector<int> m(static_cast<std::size_t>(n), 0);
    Eigen::VectorXd rn(n);
    const int half = base / 2;
    auto score = [&](const std::vector<int>& mm, double& env) {
      for (int k = 0; k < n; ++k) rn[k] = r[k] + cP * mm[static_cast<std::size_t>(k)];
      const double geo = rn.dot(M * rn);
      double mean = 0.0;
      for (int k = 0; k < n; ++k) mean += off[static_cast<std::size_t>(k)] + mm[static_cast<std::size_t>(k)];
      mean /= n;
      env = 0.0;
      for (int k = 0; k < n; ++k) {
        const double d = off[static_cast<std::size_t>(k)] + mm[static_cast<std::size_t>(k)] - mean;
        env += d * d / env_var;
      }
      return std::max(0.0, geo) + env;
    };
    auto consider = [&](const std::vector<int>& mm) {
      double env = 0.0;
      const double chi2 = score(mm, env);
      if (chi2 < best.chi2) {
        second = std::move(best);
        best = {chi2, mm, env};
      } else if (chi2 < second.chi2 && mm != best.m) {
        second = {chi2, mm, env};
      }
    };
    if (exhaustive) {
      const int combos = static_cast<int>(std::lround(std::pow(static_cast<double>(base), n - 1)));
      for (int code = 0; code < combos; ++code) {
        int c3 = code;
        for (int k = 1; k < n; ++k) {
          m[static_cast<std::size_t>(k)] = c3 % base - half;
          c3 /= base;
        }
        consider(m);
      }
    } else {
      // Start from the rounded real-valued minimiser of the same quadratic form (m_0 = 0): a descent
      // from no shift stalls in the integer lattice's local minima.
      {
        Eigen::MatrixXd Cc = Eigen::MatrixXd::Identity(n, n) - Eigen::MatrixXd::Constant(n, n, 1.0 / n);
        Eigen::VectorXd offv(n);
        for (int k = 0; k < n; ++k) offv[k] = off[static_cast<std::size_t>(k)];
        const Eigen::MatrixXd H = (cP * cP) * M + Cc / env_var;
        const Eigen::VectorXd gvec = cP * (M * r) + Cc * offv / env_var;
        const Eigen::VectorXd u = H.bottomRightCorner(n - 1, n - 1).ldlt().solve(-gvec.tail(n - 1));
        if (u.allFinite())
          for (int k = 1; k < n; ++k)
            m[static_cast<std::size_t>(k)] = std::clamp(static_cast<int>(std::lround(u[k - 1])), -half, half);
      }
      double env = 0.0;
      double cur = score(m, env);
      for (int pass = 0; pass < 10; ++pass) {
        bool moved = false;
        for (int k = 1; k < n; ++k) {
          const int keep = m[static_cast<std::size_t>(k)];
          int best_v = keep;
          for (int v = -half; v <= half; ++v) {
            if (v == keep) continue;
            m[static_cast<std::size_t>(k)] = v;
            const double c = score(m, env);
            if (c < cur - 1e-9) cur = c, best_v = v;
          }
          m[static_cast<std::size_t>(k)] = best_v;
          moved = moved || best_v != keep;
        }
        if (!moved) break;
      }
      consider(m);
      std::vector<int> alt = m;
      for (int k = 1; k < n; ++k) {
        for (int v = -half; v <= half; ++v) {
          if (v == m[static_cast<std::size_t>(k)]) continue;
          alt[static_cast<std::size_t>(k)] = v;
          consider(alt);
        }
        alt[static_cast<std::size_t>(k)] = m[static_cast<std::size_t>(k)];
      }
    }
    doubtful.clear();
    if (alternative != nullptr) *alternative = CycleAlternative{};
    if (second.chi2 - best.chi2 < opt.decisive_chi2) {
      for (int k = 0; k < n; ++k)
        if (best.m[static_cast<std::size_t>(k)] != second.m[static_cast<std::size_t>(k)]) doubtful.push_back(o.index[static_cast<std::size_t>(k)]);
      if (alternative != nullptr && !doubtful.empty()) {
        // relative to the arrivals once the best shifts are applied (below)
        alternative->valid = true;
        alternative->delta_chi2 = second.chi2 - best.chi2;
        alternative->delta_envelope_chi2 = second.env - best.env;
        alternative->shift_s.assign(arr.arrival_s.size(), 0.0);
        for (int k = 0; k < n; ++k)
          alternative->shift_s[static_cast<std::size_t>(o.index[static_cast<std::size_t>(k)])] =
              (second.m[static_cast<std::size_t>(k)] - best.m[static_cast<std::size_t>(k)]) * P;
      }
    }
    bool changed = false;
    for (int k = 1; k < n; ++k) {
      const int mk = best.m[static_cast<std::size_t>(k)];
      if (mk == 0) continue;
      const auto i = static_cast<std::size_t>(o.index[static_cast<std::size_t>(k)]);
      arr.arrival_s[i] += mk * P;
      arr.cycle_offset_s[i] += mk * P;
      shift[i] += mk;
      changed = true;
    }
    if (!changed) break;
  }
  if (alternative == nullptr) {
    for (int i : doubtful) {
      const auto iu = static_cast<std::size_t>(i);
      arr.arrival_std_s[iu] = std::max(arr.arrival_std_s[iu], std::hypot(tstd, 0.5 * P));
    }
  }
  int moved = 0;
  for (int s : shift) moved += s != 0 ? 1 : 0;
  return moved;
}

void cycle_mixture(const std::vector<Beep>& beeps, const ListenerArrivals& arrivals, const CycleAlternative& alt,
                   const SolverConfig& cfg, Solution& best) {
  if (!alt.valid || alt.shift_s.size() != arrivals.arrival_s.size()) return;
  if (!best.fit_position_m.allFinite() || !best.fit_covariance_m2.allFinite()) return;
  ListenerArrivals other = arrivals;
  for (std::size_t k = 0; k < other.arrival_s.size(); ++k) {
    other.arrival_s[k] += alt.shift_s[k];
    if (k < other.cycle_offset_s.size()) other.cycle_offset_s[k] += alt.shift_s[k];
  }
  const Solution s2 = solve(beeps, other, cfg);
  if (!s2.fit_position_m.allFinite() || !s2.fit_covariance_m2.allFinite()) return;
  if (s2.fit_position_m.norm() > cfg.max_range_m) {
    best.note += "cycle runner-up beyond max_range_m: ignored; ";
    return;
  }
  const double delta = std::isfinite(s2.chi2) && std::isfinite(best.chi2)
                           ? s2.chi2 - best.chi2 + alt.delta_envelope_chi2
                           : alt.delta_chi2;
  const double w = 1.0 / (1.0 + std::exp(std::clamp(0.5 * delta, -50.0, 50.0)));
  const Eigen::Vector2d d = s2.fit_position_m - best.fit_position_m;
  best.fit_covariance_m2 = (1.0 - w) * best.fit_covariance_m2 + w * (s2.fit_covariance_m2 + d * d.transpose());
  best.note += "cycle runner-up " + std::to_string(d.norm()) + " m away (weight " + std::to_string(w) + "); ";
}

const char* to_string(Method m) noexcept {
  switch (m) {
    case Method::Paper: return "paper";
    case Method::PaperJointSkew: return "paper_joint_skew";
    case Method::Joint: return "joint";
    case Method::Robust: return "robust";
    case Method::Network: return "network";
  }
  return "?";
}

std::optional<Method> parse_method(std::string_view name) noexcept {
  for (Method m : {Method::Paper, Method::PaperJointSkew, Method::Joint, Method::Robust, Method::Network})
    if (name == to_string(m)) return m;
  return std::nullopt;
}

const char* to_string(Status s) noexcept {
  switch (s) {
    case Status::Located: return "located";
    case Status::DirectionOnly: return "direction_only";
    case Status::Ambiguous: return "ambiguous";
    case Status::Failed: return "failed";
  }
  return "?";
}

std::vector<Eigen::Vector2d> solve_three(const Eigen::Vector2d& p_i, const Eigen::Vector2d& p_j,
                                         const Eigen::Vector2d& p_k, double dd_j, double dd_k) {
  // With x' = x − p_i, q = p − p_i, r = |x'|:  |x' − q|² = (r + dd)²  ⇒  q·x' + dd·r = (|q|² − dd²)/2.
  // Two such linear equations give x' = m + n·r; then |m + n·r|² = r².
  std::vector<Eigen::Vector2d> out;
  const Eigen::Vector2d qj = p_j - p_i, qk = p_k - p_i;
  Eigen::Matrix2d M;
  M << qj.x(), qj.y(), qk.x(), qk.y();
  const double det = M.determinant();
  if (std::abs(det) < 1e-12 * std::max(1e-12, qj.squaredNorm() * qk.squaredNorm())) return out;  // collinear beeps
  const Eigen::Vector2d rhs((qj.squaredNorm() - dd_j * dd_j) / 2.0, (qk.squaredNorm() - dd_k * dd_k) / 2.0);
  const Eigen::Vector2d ddv(dd_j, dd_k);
  const Eigen::Matrix2d Mi = M.inverse();
  const Eigen::Vector2d m = Mi * rhs, nv = -(Mi * ddv);
  const double A = nv.squaredNorm() - 1.0, B = 2.0 * m.dot(nv), C = m.squaredNorm();
  std::vector<double> roots;
  if (std::abs(A) < 1e-12) {
    if (std::abs(B) > 1e-15) roots.push_back(-C / B);
  } else {
    double disc = B * B - 4.0 * A * C;
    // a listener on a symmetry axis of the subset is a double root: rounding may push the
    // discriminant slightly negative (the residual check below rejects anything not a solution)
    if (disc < 0 && disc > -1e-9 * (B * B + std::abs(4.0 * A * C))) disc = 0;
    if (disc >= 0) {
      const double sq = std::sqrt(disc);
      const double qv = -0.5 * (B + (B >= 0 ? sq : -sq));
      roots.push_back(qv / A);
      if (std::abs(qv) > 0) roots.push_back(C / qv);
    }
  }
  for (double r : roots) {
    if (!(r >= 0.0) || r + dd_j < 0.0 || r + dd_k < 0.0) continue;
    const Eigen::Vector2d x = p_i + m + nv * r;
    // check (guards against the spurious root of the squared equations)
    const double e1 = (x - p_j).norm() - (x - p_i).norm() - dd_j, e2 = (x - p_k).norm() - (x - p_i).norm() - dd_k;
    const double tol = 1e-6 * std::max(1.0, r);
    if (std::abs(e1) > tol || std::abs(e2) > tol) continue;
    bool dup = false;
    for (const auto& o : out) dup = dup || (o - x).norm() < 1e-6 * std::max(1.0, r);
    if (!dup) out.push_back(x);
  }
  return out;
}

std::vector<double> exact_arrivals(const std::vector<Beep>& beeps, const Eigen::Vector2d& listener_m, double skew,
                                   double tau_s, double speed_of_sound_mps) {
  std::vector<double> a;
  a.reserve(beeps.size());
  for (const auto& b : beeps)
    a.push_back(tau_s + (1.0 + skew) * (b.player_time_s + (listener_m - b.position_m).norm() / speed_of_sound_mps));
  return a;
}

Bound cramer_rao(const std::vector<Eigen::Vector2d>& positions_m, const std::vector<double>& player_times_s,
                 const Eigen::Vector2d& listener_m, double skew, double timing_std_s, double position_std_m,
                 double speed_of_sound_mps) {
  if (positions_m.size() != player_times_s.size())
    throw std::invalid_argument("cramer_rao: positions and times differ in length");
  Bound bd;
  const double c = speed_of_sound_mps;
  Obs o;
  o.c = c;
  const double sig = std::sqrt(c * timing_std_s * c * timing_std_s + position_std_m * position_std_m);
  for (std::size_t k = 0; k < positions_m.size(); ++k) {
    o.p.push_back(positions_m[k]);
    o.de.push_back(player_times_s[k] - player_times_s[0]);
    o.cy.push_back(0.0);
    o.sigma.push_back(sig);
    o.index.push_back(static_cast<int>(k));
    o.a.push_back(0.0);
    o.e.push_back(0.0);
  }
  if (o.n() < 4) return bd;
  std::vector<double> w(positions_m.size(), 1.0);
  const Eigen::MatrixXd P = covariance(o, w, Eigen::Vector4d(listener_m.x(), listener_m.y(), 0.0, skew * c), true);
  if (!P.allFinite()) return bd;
  Solution s;
  s.position_m = listener_m;
  fill_uncertainty(s, P.topLeftCorner<2, 2>());
  bd.std_x_m = std::sqrt(P(0, 0));
  bd.std_y_m = std::sqrt(P(1, 1));
  bd.std_m = s.std_m;
  bd.direction_std_rad = s.direction_std_rad;
  bd.distance_std_m = s.distance_std_m;
  bd.skew_std = std::sqrt(P(3, 3)) / c;
  return bd;
}

namespace {

/// solve() with Method::Paper or PaperJointSkew: the closed form of every 3-beep subset with the
/// given skew (or the joint fit's), the direction majority and the candidates' centroid.
Solution paper_solution(const Obs& o, Method method, double given_skew, const SolverConfig& cfg, Solution sol) {
  const int n = o.n();
  const double c = cfg.speed_of_sound_mps;
  double skew = given_skew;
  if (method == Method::PaperJointSkew) {
    const JointResult jr = joint_solve(o, cfg, true);
    if (jr.fit.ok && std::abs(jr.fit.g / c) <= cfg.max_abs_skew) skew = jr.fit.g / c;
    else sol.note += "joint skew unavailable, given skew used; ";
  }
  sol.skew = skew;
  const PaperResult pr = paper_solve(o, skew, cfg);
  sol.candidates = pr.kept;
  if (pr.votes == 0) {
    sol.note += "no 3-beep subset gives a point or a direction";
    return sol;
  }
  sol.direction_rad = pr.direction;
  if (pr.direction_only) {
    sol.status = Status::DirectionOnly;
    sol.note += "no subset solution in the majority direction (triangle inequality broken or out of range): direction only";
    sol.confidence = 0.2;
    return sol;
  }
  Eigen::Vector2d centroid(0, 0);
  for (const auto& x : pr.kept) centroid += x;
  centroid /= static_cast<double>(pr.kept.size());
  if (pr.ambiguous) centroid = pr.kept.front();  // a lone two-solution subset: one of the two, not their mean
  sol.position_m = centroid;
  sol.beeps_used = n;
  // uncertainty: linearised at the centroid with the skew fixed, inflated by the candidates' spread
  std::vector<double> w(static_cast<std::size_t>(n), 1.0);
  // (the Jacobian does not depend on the offset b)
  const Eigen::MatrixXd P = covariance(o, w, Eigen::Vector4d(centroid.x(), centroid.y(), 0.0, skew * c), false);
  Eigen::Matrix2d P2 = P.allFinite() ? Eigen::Matrix2d(P.topLeftCorner<2, 2>()) : Eigen::Matrix2d::Zero();
  if (pr.kept.size() >= 2 && !pr.ambiguous) {
    Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
    for (const auto& x : pr.kept) S += (x - centroid) * (x - centroid).transpose();
    S /= static_cast<double>(pr.kept.size() - 1);
    if (S.trace() > P2.trace()) P2 = S;
  }
  fill_uncertainty(sol, P2);
  if (pr.ambiguous) {
    sol.status = Status::Ambiguous;
    for (const auto& x : pr.all_points)
      if ((x - centroid).norm() > 1e-9) sol.alternatives.push_back(x);
    sol.note += "two solutions, nothing to choose by: both reported";
  }
  finish_position(sol, cfg);
  sol.confidence = sol.located() ? geometry_confidence(sol.std_m / std::max(sol.distance_m, 0.1)) *
                                       (sol.status == Status::Ambiguous ? 0.5 : 1.0)
                                 : 0.2;
  return sol;
}

/// solve() with Method::Joint, Robust (or Network for a lone listener): position and skew jointly.
Solution joint_solution(const Obs& o, const ListenerArrivals& arr, Method method, const SolverConfig& cfg, Solution sol) {
  const double c = cfg.speed_of_sound_mps;
  const bool robust = method == Method::Robust || method == Method::Network;
  const JointResult jr = joint_solve(o, cfg, robust);
  if (!jr.fit.ok) {
    sol.note += "joint least squares did not converge";
    return sol;
  }
  const Fit& f = jr.fit;
  sol.skew = f.g / c;
  sol.beeps_used = jr.used.n();
  for (int idx : jr.dropped) sol.note += "beep " + std::to_string(idx) + " dropped as an outlier; ";
  const Eigen::MatrixXd P = accumulated_covariance(jr.used, jr.w, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g));
  const int dof = jr.used.n() - 4;
  {
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    residuals(jr.used, Eigen::Vector4d(f.x.x(), f.x.y(), f.b, f.g), r, J);
    sol.rms_residual_s = std::sqrt(r.squaredNorm() / std::max(1, jr.used.n())) / c;
  }
  const double chi2 = f.cost;
  // Reliable arrivals: timing error within kReliableTimingFactor x the base (not a doubtful carrier cycle).
  {
    const double tstd = std::isfinite(arr.timing_std_s) ? arr.timing_std_s : cfg.timing_std_s;
    for (int k = 0; k < jr.used.n(); ++k) {
      const auto i = static_cast<std::size_t>(jr.used.index[static_cast<std::size_t>(k)]);
      const double sk = i < arr.arrival_std_s.size() && std::isfinite(arr.arrival_std_s[i]) ? arr.arrival_std_s[i] : tstd;
      const double doubt = i < arr.path_doubt_s.size() && std::isfinite(arr.path_doubt_s[i]) ? arr.path_doubt_s[i] : 0.0;
      if (std::hypot(sk, doubt) <= kReliableTimingFactor * tstd) ++sol.reliable_beeps;
    }
    sol.weak = sol.reliable_beeps < 4;  // fewer reliable equations than unknowns (x, y, skew, offset)
  }
  sol.fit_position_m = f.x;
  sol.fit_covariance_m2 = P.allFinite() ? Eigen::Matrix2d(P.topLeftCorner<2, 2>()) : Eigen::Matrix2d::Constant(kNaN);
  sol.chi2 = chi2;
  sol.dof = dof;
  // inflate the a-priori covariance when the residuals say the sigmas were optimistic
  const double inflate = dof > 0 ? std::max(1.0, chi2 / dof) : 1.0;
  Eigen::Matrix2d P2 = P.allFinite() ? Eigen::Matrix2d(P.topLeftCorner<2, 2>() * inflate)
                                     : Eigen::Matrix2d::Constant(kNaN);
  sol.skew_std = P.allFinite() ? std::sqrt(P(3, 3) * inflate) / c : kNaN;
  sol.position_m = f.x;
  if (std::abs(sol.skew) > cfg.max_abs_skew) {
    sol.direction_rad = std::atan2(f.x.y(), f.x.x());
    sol.status = Status::DirectionOnly;
    sol.note += "estimated skew " + std::to_string(sol.skew * 1e6) + " ppm beyond max_abs_skew: direction only";
    sol.position_m = Eigen::Vector2d(kNaN, kNaN);
    sol.confidence = 0.1;
    sol.inconsistent = true;  // no clock does that: the arrivals do not follow the direct-path model
    return sol;
  }
  if (P2.allFinite()) fill_uncertainty(sol, P2);
  else sol.distance_std_m = kNaN;
  // ambiguity: another local minimum (>20° away) fitting as well (Δχ² < 1)
  for (const auto& other : jr.others) {
    if (other.cost - f.cost < 1.0 && other.x.norm() <= cfg.max_range_m) {
      sol.status = Status::Ambiguous;
      sol.alternatives.push_back(other.x);
    }
  }
  if (sol.status == Status::Ambiguous) sol.note += "another position fits as well: both reported; ";
  finish_position(sol, cfg);
  const double geo = sol.located() ? geometry_confidence(sol.std_m / std::max(sol.distance_m, 0.1))
                                   : 0.5 * geometry_confidence(sol.direction_std_rad);
  sol.confidence = geo * fit_confidence(chi2, dof) * (sol.status == Status::Ambiguous ? 0.5 : 1.0);
  return sol;
}

}  // namespace

Solution solve(const std::vector<Beep>& beeps, const ListenerArrivals& arr, const SolverConfig& cfg) {
  validate(beeps, arr, cfg);
  Solution sol;
  sol.method = cfg.method;
  sol.reference_offset_std_m = arr.reference_offset_std_m;
  const double given_skew = std::isfinite(arr.known_skew) ? arr.known_skew : cfg.known_skew;
  // ---- the heard beeps
  const Obs o = make_obs(beeps, arr, cfg, true);
  const int n = o.n();
  sol.beeps_heard = n;
  if (n < 3) {
    sol.note = "only " + std::to_string(n) + " beeps heard (3 needed)";
    return sol;
  }
  Method method = cfg.method;
  if ((method != Method::Paper) && n < 4) {
    sol.note = "3 beeps heard: the skew cannot be estimated, paper method with the given skew; ";
    method = Method::Paper;
  }

  if (method == Method::Paper || method == Method::PaperJointSkew) {
    Solution p = paper_solution(o, method, given_skew, cfg, std::move(sol));
    if (method != cfg.method) {
      // Forced here by too few beeps: the skew is assumed, not measured; fewer equations than
      // unknowns (x, y, skew, offset), so the answer may be far off (calibrate_session() skips it).
      p.weak = true;
      p.confidence *= 0.2;
      p.note += "3 beeps: weak; ";
    }
    return p;
  }
  return joint_solution(o, arr, method, cfg, std::move(sol));
}


// ---------------------------------------------------------------------------------------- Network

namespace {

/// A listener taking part in the network solve: its timing-only observations (the robust pass's
/// outliers removed) and its start q = (x, y, b, g).
struct NetworkMember {
  std::size_t listener;
  Obs o;
  Eigen::Vector4d q;
};

/// Step 1: every listener on its own (robust joint): the start, and the answer (out.listeners) for
/// those left out. Returns the listeners with a usable joint fit.
std::vector<NetworkMember> network_members(const std::vector<Beep>& beeps, const std::vector<ListenerArrivals>& arrivals,
                                           const SolverConfig& cfg, NetworkSolution& out) {
  std::vector<NetworkMember> members;
  for (std::size_t l = 0; l < arrivals.size(); ++l) {
    out.listeners.push_back(solve(beeps, arrivals[l], cfg));
    Obs o = make_obs(beeps, arrivals[l], cfg, true);
    if (o.n() < 4) continue;
    const JointResult jr = joint_solve(o, cfg, true);
    if (!jr.fit.ok || !jr.fit.x.allFinite() || std::abs(jr.fit.g / cfg.speed_of_sound_mps) > cfg.max_abs_skew) continue;
    // a fit that ran away (distance not determined on its own) joins from half the range limit
    Eigen::Vector2d x0 = jr.fit.x;
    if (x0.norm() > 0.5 * cfg.max_range_m) x0 *= 0.5 * cfg.max_range_m / x0.norm();
    Obs ot = make_obs(beeps, arrivals[l], cfg, false);  // timing error only: positions are unknowns now
    // keep the robust pass's outlier decisions
    std::vector<int> keep;
    for (int k = 0; k < ot.n(); ++k)
      if (std::find(jr.dropped.begin(), jr.dropped.end(), ot.index[static_cast<std::size_t>(k)]) == jr.dropped.end()) keep.push_back(k);
    Obs used = subset(ot, keep);
    // re-reference b to this observation set (the first heard beep is the same unless it was dropped)
    double b = 0, g = 0;
    std::vector<double> w1(static_cast<std::size_t>(used.n()), 1.0);
    varpro_cost(used, w1, x0, &b, &g);
    members.push_back({l, std::move(used), Eigen::Vector4d(x0.x(), x0.y(), b, g)});
  }
  return members;
}

/// The network problem of one pass: θ = (δ_0 .. δ_{K−1}, then (x, y, b, g) per member), the Huber
/// weights w and the normal equations N θ = −grad of the last build().
struct NetworkProblem {
  NetworkProblem(const std::vector<NetworkMember>& members_in, const std::vector<double>& prior_sd_in, std::size_t beeps,
                 double speed_of_sound_mps)
      : members(members_in), prior_sd(prior_sd_in), K(beeps), c(speed_of_sound_mps) {}

  const std::vector<NetworkMember>& members;
  const std::vector<double>& prior_sd;  ///< prior 1-sigma of each beep correction (m, per axis)
  std::size_t K = 0;                    ///< beeps
  std::size_t M = 0;                    ///< members in this pass
  std::size_t P = 0;                    ///< unknowns: 2K + 4M
  double c = 0.0;
  std::vector<std::vector<double>> w;
  Eigen::MatrixXd N;
  Eigen::VectorXd grad;

  /// Starts a pass over the current members: returns the start θ (zero corrections), unit weights.
  Eigen::VectorXd start_pass() {
    M = members.size();
    P = 2 * K + 4 * M;
    Eigen::VectorXd theta = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(P));
    for (std::size_t m = 0; m < M; ++m) theta.segment<4>(static_cast<Eigen::Index>(2 * K + 4 * m)) = members[m].q;
    w.assign(M, {});
    for (std::size_t m = 0; m < M; ++m) w[m].assign(static_cast<std::size_t>(members[m].o.n()), 1.0);
    return theta;
  }

  /// Timing residual (m) of heard beep ku of member m at θ.
  double residual(const Eigen::VectorXd& theta, std::size_t m, std::size_t ku) const {
    const Obs& o = members[m].o;
    const auto base = static_cast<Eigen::Index>(2 * K + 4 * m);
    const auto bk = static_cast<Eigen::Index>(2 * static_cast<std::size_t>(o.index[ku]));
    const double d = (theta.segment<2>(base) - o.p[ku] - theta.segment<2>(bk)).norm();
    return o.cy[ku] - theta[base + 2] - theta[base + 3] * (o.de[ku] + d / c) - d;
  }

  /// The weighted cost at th (priors + Huber-weighted timing residuals); with_matrix also builds N
  /// and grad there.
  double build(const Eigen::VectorXd& th, bool with_matrix) {
    if (with_matrix) {
      N.setZero(static_cast<Eigen::Index>(P), static_cast<Eigen::Index>(P));
      grad.setZero(static_cast<Eigen::Index>(P));
    }
    double cost = 0;
    for (std::size_t k = 0; k < K; ++k)
      for (int a = 0; a < 2; ++a) {
        const auto i = static_cast<Eigen::Index>(2 * k + static_cast<std::size_t>(a));
        const double W = 1.0 / (prior_sd[k] * prior_sd[k]);
        cost += W * th[i] * th[i];
        if (with_matrix) {
          N(i, i) += W;
          grad[i] += W * th[i];
        }
      }
    for (std::size_t m = 0; m < M; ++m) {
      const Obs& o = members[m].o;
      const auto base = static_cast<Eigen::Index>(2 * K + 4 * m);
      const Eigen::Vector2d x = th.segment<2>(base);
      const double b = th[base + 2], g = th[base + 3];
      for (int k = 0; k < o.n(); ++k) {
        const auto ku = static_cast<std::size_t>(k);
        const auto bk = static_cast<Eigen::Index>(2 * static_cast<std::size_t>(o.index[ku]));
        const Eigen::Vector2d pk = o.p[ku] + th.segment<2>(bk);
        const Eigen::Vector2d diff = x - pk;
        const double d = std::max(diff.norm(), 1e-9);
        const double r = o.cy[ku] - b - g * (o.de[ku] + d / c) - d;
        const double W = w[m][ku] / (o.sigma[ku] * o.sigma[ku]);
        cost += W * r * r;
        if (!with_matrix) continue;
        const double f = 1.0 + g / c;
        const Eigen::Vector2d jx = -f * diff / d;  // ∂r/∂x; ∂r/∂δ_k = −∂r/∂x
        const Eigen::Index idx[6] = {base, base + 1, base + 2, base + 3, bk, bk + 1};
        const double jv[6] = {jx.x(), jx.y(), -1.0, -(o.de[ku] + d / c), -jx.x(), -jx.y()};
        for (int i = 0; i < 6; ++i) {
          grad[idx[i]] += W * r * jv[i];
          for (int j = 0; j < 6; ++j) N(idx[i], idx[j]) += W * jv[i] * jv[j];
        }
      }
    }
    return cost;
  }

  /// Huber weights from the residuals at θ; true when any weight moved by more than 1e-3.
  bool reweight(const Eigen::VectorXd& theta, double huber_k) {
    bool changed = false;
    for (std::size_t m = 0; m < M; ++m) {
      const Obs& o = members[m].o;
      for (int k = 0; k < o.n(); ++k) {
        const auto ku = static_cast<std::size_t>(k);
        const double r = residual(theta, m, ku);
        const double z = std::abs(r) / o.sigma[ku];
        const double wn = z <= huber_k ? 1.0 : huber_k / z;
        if (std::abs(wn - w[m][ku]) > 1e-3) changed = true;
        w[m][ku] = wn;
      }
    }
    return changed;
  }

  /// RMS normalised residual of every member at θ (the gate against inconsistent listeners).
  std::vector<double> member_rms(const Eigen::VectorXd& theta) const {
    std::vector<double> rms(M);
    for (std::size_t m = 0; m < M; ++m) {
      const Obs& o = members[m].o;
      double ss = 0;
      for (int k = 0; k < o.n(); ++k) {
        const auto ku = static_cast<std::size_t>(k);
        const double r = residual(theta, m, ku);
        ss += (r / o.sigma[ku]) * (r / o.sigma[ku]);
      }
      rms[m] = std::sqrt(ss / std::max(1, o.n()));
    }
    return rms;
  }
};

/// Step 2: Gauss-Newton (Levenberg-Marquardt damped) over all beep corrections δ_k (prior N(0, σ_p²)
/// per axis) and every member's (x, y, b, g); Huber IRLS on the timing residuals. Updates theta and
/// cost (pb.N, pb.grad hold the last normal equations); returns the iterations.
int network_gauss_newton(NetworkProblem& pb, Eigen::VectorXd& theta, double& cost, double huber_k) {
  int it = 0;
  cost = pb.build(theta, true);
  double lambda = 1e-4;
  for (int outer = 0; outer < 4; ++outer) {
    for (int inner = 0; inner < 20; ++inner, ++it) {
      bool improved = false;
      for (int tries = 0; tries < 8 && !improved; ++tries) {
        Eigen::MatrixXd A = pb.N;
        for (Eigen::Index i = 0; i < A.rows(); ++i) A(i, i) += lambda * std::max(pb.N(i, i), 1e-12);
        const Eigen::VectorXd step = A.ldlt().solve(-pb.grad);
        if (!step.allFinite()) {
          lambda *= 10;
          continue;
        }
        const Eigen::VectorXd tn = theta + step;
        const double cn = pb.build(tn, false);
        if (cn <= cost) {
          const double drop = cost - cn;
          theta = tn;
          cost = pb.build(theta, true);
          lambda = std::max(lambda / 10, 1e-10);
          improved = true;
          if (drop < 1e-9 * std::max(cost, 1.0)) inner = 1000;
        } else {
          lambda *= 10;
        }
      }
      if (!improved) break;
    }
    if (!pb.reweight(theta, huber_k)) break;
    cost = pb.build(theta, true);
  }
  return it;
}

/// Step 3: the members' solutions from θ, with the covariance of the a-priori sigmas, inflated by
/// the fit when it is worse than they say.
void network_solutions(const NetworkProblem& pb, const Eigen::VectorXd& theta, double cost, const SolverConfig& cfg,
                       NetworkSolution& out) {
  const std::size_t K = pb.K, M = pb.M, P = pb.P;
  const double c = pb.c;
  int nres = 0;
  for (const auto& mb : pb.members) nres += mb.o.n();
  const int dof = nres + static_cast<int>(2 * K) - static_cast<int>(P);
  const double inflate = dof > 0 ? std::max(1.0, cost / dof) : 1.0;
  Eigen::LDLT<Eigen::MatrixXd> ldlt(pb.N);
  const Eigen::MatrixXd cov = ldlt.solve(Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(P), static_cast<Eigen::Index>(P)));
  for (std::size_t k = 0; k < K; ++k) out.beep_correction_m[k] = theta.segment<2>(static_cast<Eigen::Index>(2 * k));
  for (std::size_t m = 0; m < M; ++m) {
    const auto base = static_cast<Eigen::Index>(2 * K + 4 * m);
    Solution& s = out.listeners[pb.members[m].listener];
    const Solution before = s;
    s = Solution{};
    s.method = Method::Robust;
    s.beeps_heard = before.beeps_heard;
    s.beeps_used = pb.members[m].o.n();
    s.position_m = theta.segment<2>(base);
    s.skew = theta[base + 3] / c;
    s.skew_std = std::sqrt(std::max(0.0, cov(base + 3, base + 3) * inflate)) / c;
    const Eigen::Matrix2d P2 = cov.block<2, 2>(base, base) * inflate;
    if (P2.allFinite()) fill_uncertainty(s, P2);
    s.note = "network solution (" + std::to_string(M) + " listeners, beep positions refined); ";
    if (!before.alternatives.empty()) {
      s.status = Status::Ambiguous;
      s.alternatives = before.alternatives;
    }
    finish_position(s, cfg);
    const double geo = s.located() ? geometry_confidence(s.std_m / std::max(s.distance_m, 0.1))
                                   : 0.5 * geometry_confidence(s.direction_std_rad);
    s.confidence = geo * fit_confidence(cost, dof) * (s.status == Status::Ambiguous ? 0.5 : 1.0);
  }
}

}  // namespace

NetworkSolution solve_network(const std::vector<Beep>& beeps, const std::vector<ListenerArrivals>& arrivals,
                              const SolverConfig& cfg_in) {
  SolverConfig cfg = cfg_in;
  cfg.method = Method::Robust;
  NetworkSolution out;
  out.beep_correction_m.assign(beeps.size(), Eigen::Vector2d::Zero());
  std::vector<NetworkMember> members = network_members(beeps, arrivals, cfg, out);
  const std::size_t K = beeps.size();
  out.listeners_in_network = static_cast<int>(members.size());
  if (members.size() < 3) {
    out.note = "fewer than 3 listeners with a joint fit: per-listener solutions";
    return out;
  }
  // A listener whose arrivals disagree with everyone's beep corrections (an obstructed listener whose
  // first path is a reflection) would corrupt the shared corrections: after a pass, listeners whose
  // RMS normalised residual is above max(5, 3 × the median) are left out (they keep their own
  // solution) and the network is solved again without them.
  std::vector<double> prior_sd(K);
  for (std::size_t k = 0; k < K; ++k)
    prior_sd[k] = std::max(1e-5, std::isfinite(beeps[k].position_std_m) ? beeps[k].position_std_m : cfg.position_std_m);
  NetworkProblem pb(members, prior_sd, K, cfg.speed_of_sound_mps);
  Eigen::VectorXd theta;
  double cost = 0;
  int it = 0;
  for (int pass = 0; pass < 3; ++pass) {
    theta = pb.start_pass();
    it = network_gauss_newton(pb, theta, cost, cfg.huber_k);
    // gate: leave out listeners that disagree with the network
    const std::vector<double> rms = pb.member_rms(theta);
    std::vector<double> sorted = rms;
    std::sort(sorted.begin(), sorted.end());
    const double limit = std::max(5.0, 3.0 * sorted[sorted.size() / 2]);
    std::vector<NetworkMember> kept;
    std::vector<int> dropped;
    for (std::size_t m = 0; m < pb.M; ++m)
      if (rms[m] <= limit) kept.push_back(members[m]);
      else dropped.push_back(static_cast<int>(members[m].listener));
    if (kept.size() == pb.M || kept.size() < 3 || pass == 2) break;  // the last pass is always solved
    out.excluded.insert(out.excluded.end(), dropped.begin(), dropped.end());
    members = std::move(kept);
  }
  out.listeners_in_network = static_cast<int>(pb.M);
  out.iterations = it;
  network_solutions(pb, theta, cost, cfg, out);
  return out;
}

}  // namespace locus::plugins::amil

namespace locus::plugins::amil {

namespace {

/// 99.9 % quantile of chi²(dof) (exact table to 10, Wilson-Hilferty beyond).
double chi2_q999(int dof) {
  static constexpr double kTable[] = {10.828, 13.816, 16.266, 18.467, 20.515, 22.458, 24.322, 26.124, 27.877, 29.588};
  if (dof >= 1 && dof <= 10) return kTable[dof - 1];
  const double k = dof, z = 3.0902;
  const double t = 1.0 - 2.0 / (9.0 * k) + z * std::sqrt(2.0 / (9.0 * k));
  return k * t * t * t;
}

}  // namespace

double calibrate_session(std::vector<Solution>& listeners, const SolverConfig& cfg) {
  // Robust pooled factor: listeners whose chi²/dof is beyond the 99.9 % quantile do not vote.
  double sum_chi2 = 0.0;
  int sum_dof = 0;
  for (const Solution& s : listeners) {
    if (s.dof <= 0 || !std::isfinite(s.chi2) || !s.fit_covariance_m2.allFinite()) continue;
    if (s.chi2 > chi2_q999(s.dof)) continue;
    sum_chi2 += s.chi2;
    sum_dof += s.dof;
  }
  const double factor = sum_dof >= 3 ? std::max(cfg.min_session_factor, sum_chi2 / sum_dof) : 1.0;
  for (Solution& s : listeners) {
    if (s.dof <= 0 || !std::isfinite(s.chi2) || !s.fit_covariance_m2.allFinite() || !s.fit_position_m.allFinite()) continue;
    if (s.status == Status::Failed) continue;
    if (std::isfinite(s.skew) && std::abs(s.skew) > cfg.max_abs_skew) continue;  // already direction-only for its skew
    // Inconsistent: residuals far beyond the session's noise.
    s.inconsistent = s.chi2 > factor * chi2_q999(s.dof);
    // An inconsistent listener's own residuals say its noise is larger than the session's: its
    // covariance takes its own chi²/dof (a wrong path or cycle is not in the noise model).
    const double own = s.inconsistent ? s.chi2 / std::max(1, s.dof) : factor;
    const Eigen::Matrix2d P = s.fit_covariance_m2 * std::max(factor, own) +
                              Eigen::Matrix2d::Identity() * (s.reference_offset_std_m * s.reference_offset_std_m);
    // Recompute from the fitted point: position, stds, the direction-only decision.
    const Status before = s.status;
    s.status = before == Status::Ambiguous ? Status::Ambiguous : Status::Located;
    s.position_m = s.fit_position_m;
    fill_uncertainty(s, P);
    const std::string::size_type cut = s.note.find("distance not determined");
    if (cut != std::string::npos) s.note.erase(cut);
    finish_position(s, cfg);
    const double geo = s.located() ? geometry_confidence(s.std_m / std::max(s.distance_m, 0.1))
                                   : 0.5 * geometry_confidence(s.direction_std_rad);
    s.confidence = geo * (s.status == Status::Ambiguous ? 0.5 : 1.0) * (s.inconsistent ? 0.1 : 1.0) * (s.weak ? 0.2 : 1.0);
    if (s.weak) s.note += std::to_string(s.reliable_beeps) + " reliable arrivals (4 needed): weak; ";
    if (s.inconsistent) {
      s.note += "residuals " + std::to_string(std::sqrt(s.chi2 / std::max(1, s.dof) / factor)) +
                " sigma beyond the session's noise: inconsistent; ";
    }
  }
  return factor;
}

double widen_by_jackknife(const std::vector<Beep>& beeps, const ListenerArrivals& arrivals, const SolverConfig& cfg,
                          Solution& s) {
  if (!std::isfinite(s.direction_rad)) return kNaN;
  std::vector<double> dirs;
  for (std::size_t k = 0; k < arrivals.arrival_s.size() && k < beeps.size(); ++k) {
    if (!std::isfinite(arrivals.arrival_s[k])) continue;
    ListenerArrivals drop = arrivals;
    drop.arrival_s[k] = kNaN;
    const Solution j = solve(beeps, drop, cfg);
    if (std::isfinite(j.direction_rad)) dirs.push_back(j.direction_rad);
  }
  // Exactly determined leave-one-out fits can land on the mirror solution (4 equations, 4 unknowns):
  // a flip says nothing about the size of a small error, so fits beyond 90° of the full one are left out.
  std::vector<double> near;
  for (double d : dirs)
    if (std::fabs(std::remainder(d - s.direction_rad, 2.0 * M_PI)) < 0.5 * M_PI) near.push_back(d);
  const auto n = static_cast<double>(near.size());
  if (near.size() < 3) return kNaN;
  double sc = 0.0, ss = 0.0;
  for (double d : near) sc += std::cos(d), ss += std::sin(d);
  const double mean = std::atan2(ss, sc);
  double sum2 = 0.0;
  for (double d : near) {
    const double e = std::remainder(d - mean, 2.0 * M_PI);
    sum2 += e * e;
  }
  const double jk_std = std::sqrt((n - 1.0) / n * sum2);
  if (jk_std > s.direction_std_rad || !std::isfinite(s.direction_std_rad)) {
    s.direction_std_rad = jk_std;
    if (s.located() && std::isfinite(s.distance_std_m))
      s.std_m = std::hypot(s.distance_std_m, s.distance_m * jk_std);
    s.note += "direction std from the leave-one-out spread; ";
  }
  return jk_std;
}

}  // namespace locus::plugins::amil
