// Ranges from a rigid body to known points, with one unknown clock offset: every root.
//
// The unknowns are a point X (3D) and a range bias rho (a clock offset times the speed of sound).
// Equation i says: the distance from X + offset_i (a part of the body, e.g. a microphone, whose
// offset from X is known) to the known point target_i, plus sign_i * rho, is y_i:
//
//   r_i(X, rho) = |X + offset_i - target_i| + sign_i * rho - y_i,   weight w_i = 1 / sigma_i^2.
//
// Acoustic localization without clock sync reduces to this shape: TUM (a device's speaker and its
// microphones against another's; a monitoring device against two speakers), AMIL-like listeners,
// any TDoA problem (sign 0 and one range subtracted = rho). solve_ranges() runs Levenberg-Marquardt
// from many starting points and keeps every distinct local minimum (the roots: a system of quadratic
// equations has several), best first, each with its covariance (J^T W J)^-1. No allocation beyond
// the returned vector; a few hundred microseconds for 4-8 equations.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <vector>

namespace locus::dsp {

struct RangeEquation {
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();  ///< the measured body point is X + offset
  Eigen::Vector3d target = Eigen::Vector3d::Zero();  ///< the known point
  double sign = 0.0;                                 ///< coefficient of rho: -1, 0 or +1
  double y = 0.0;                                    ///< measured distance (+ sign*rho), metres
  double sigma = 0.001;                              ///< 1-sigma of y, metres (> 0)
};

struct RangeRoot {
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  double rho = 0.0;
  double cost = 0.0;            ///< sum of squared whitened residuals
  double rms_m = 0.0;           ///< RMS residual, metres
  Eigen::Matrix4d cov = Eigen::Matrix4d::Zero();  ///< of (x, rho); Inf on the diagonal when singular
};

struct RangeSolveOptions {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  ///< starting points are around this point
  std::vector<double> radii{0.3, 1.0, 2.5};          ///< ... at these distances from it
  int directions = 26;                               ///< ... in this many directions (Fibonacci sphere)
  bool solve_rho = true;                             ///< false: rho fixed at rho0
  double rho0 = 0.0;
  int max_iterations = 100;
  double distinct_m = 0.02;                          ///< roots closer than this are one
  double max_cost_ratio = 1e6;                       ///< drop roots costing this many times the best
};

namespace range_solver_detail {

inline double evaluate(const std::vector<RangeEquation>& eqs, const Eigen::Vector3d& x, double rho,
                       Eigen::Matrix4d* jtj, Eigen::Vector4d* jtr) {
  double cost = 0.0;
  if (jtj) jtj->setZero();
  if (jtr) jtr->setZero();
  for (const RangeEquation& e : eqs) {
    const Eigen::Vector3d d = x + e.offset - e.target;
    const double n = d.norm();
    const double w = 1.0 / (e.sigma * e.sigma);
    const double r = n + e.sign * rho - e.y;
    cost += w * r * r;
    if (jtj) {
      Eigen::Vector4d g;
      g.head<3>() = n > 1e-12 ? Eigen::Vector3d(d / n) : Eigen::Vector3d::Zero();
      g[3] = e.sign;
      *jtj += w * g * g.transpose();
      *jtr += w * g * r;
    }
  }
  return cost;
}

}  // namespace range_solver_detail

/// Levenberg-Marquardt from (x0, rho0); the converged point, cost and covariance.
inline RangeRoot refine_range_root(const std::vector<RangeEquation>& eqs, Eigen::Vector3d x, double rho, bool solve_rho,
                                   int max_iterations) {
  using range_solver_detail::evaluate;
  Eigen::Matrix4d jtj;
  Eigen::Vector4d jtr;
  double lambda = 1e-3;
  double cost = evaluate(eqs, x, rho, &jtj, &jtr);
  for (int it = 0; it < max_iterations; ++it) {
    Eigen::Matrix4d a = jtj;
    if (!solve_rho) {
      a.row(3).setZero();
      a.col(3).setZero();
      a(3, 3) = 1.0;
    }
    bool improved = false;
    for (int tries = 0; tries < 8 && !improved; ++tries) {
      Eigen::Matrix4d damped = a;
      for (int k = 0; k < 4; ++k) damped(k, k) += lambda * std::max(a(k, k), 1e-9);
      Eigen::Vector4d g = jtr;
      if (!solve_rho) g[3] = 0.0;
      const Eigen::Vector4d step = damped.ldlt().solve(-g);
      if (!step.allFinite()) break;
      const Eigen::Vector3d xn = x + step.head<3>();
      const double rn = rho + step[3];
      Eigen::Matrix4d jn;
      Eigen::Vector4d rnv;
      const double cn = evaluate(eqs, xn, rn, &jn, &rnv);
      if (cn < cost) {
        const bool small = step.norm() < 1e-7;
        x = xn, rho = rn, cost = cn, jtj = jn, jtr = rnv;
        lambda = std::max(lambda * 0.3, 1e-9);
        improved = true;
        if (small) it = max_iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  RangeRoot root;
  root.x = x;
  root.rho = rho;
  root.cost = cost;
  double sum2 = 0.0;
  for (const RangeEquation& e : eqs) {
    const double r = (x + e.offset - e.target).norm() + e.sign * rho - e.y;
    sum2 += r * r;
  }
  root.rms_m = eqs.empty() ? 0.0 : std::sqrt(sum2 / static_cast<double>(eqs.size()));
  Eigen::Matrix4d info = jtj;
  if (!solve_rho) {
    info.row(3).setZero();
    info.col(3).setZero();
    info(3, 3) = 1e18;
  }
  Eigen::FullPivLU<Eigen::Matrix4d> lu(info);
  if (lu.rank() == 4) root.cov = lu.inverse();
  else root.cov = Eigen::Matrix4d::Identity() * std::numeric_limits<double>::infinity();
  return root;
}

/// Every distinct root of the equations, lowest cost first.
inline std::vector<RangeRoot> solve_ranges(const std::vector<RangeEquation>& eqs, const RangeSolveOptions& opt = {}) {
  std::vector<RangeRoot> roots;
  if (eqs.empty()) return roots;
  const int n = std::max(1, opt.directions);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (double radius : opt.radii) {
    for (int i = 0; i < n; ++i) {
      const double z = n == 1 ? 0.0 : 1.0 - 2.0 * (i + 0.5) / n;
      const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
      const Eigen::Vector3d dir(r * std::cos(golden * i), r * std::sin(golden * i), z);
      const Eigen::Vector3d x0 = opt.centre + radius * dir;
      double rho0 = opt.rho0;
      if (opt.solve_rho) {  // the rho that best fits x0
        double num = 0.0, den = 0.0;
        for (const RangeEquation& e : eqs) {
          if (e.sign == 0.0) continue;
          num += e.sign * (e.y - (x0 + e.offset - e.target).norm()) / (e.sigma * e.sigma);
          den += 1.0 / (e.sigma * e.sigma);
        }
        if (den > 0) rho0 = num / den;
      }
      RangeRoot root = refine_range_root(eqs, x0, rho0, opt.solve_rho, opt.max_iterations);
      if (!root.x.allFinite() || !std::isfinite(root.cost)) continue;
      bool dup = false;
      for (RangeRoot& o : roots) {
        if ((o.x - root.x).norm() < opt.distinct_m) {
          if (root.cost < o.cost) o = root;
          dup = true;
          break;
        }
      }
      if (!dup) roots.push_back(root);
    }
  }
  std::sort(roots.begin(), roots.end(), [](const RangeRoot& a, const RangeRoot& b) { return a.cost < b.cost; });
  if (!roots.empty()) {
    const double limit = std::max(roots.front().cost, 1.0) * opt.max_cost_ratio;
    roots.erase(std::remove_if(roots.begin(), roots.end(), [&](const RangeRoot& r) { return r.cost > limit; }), roots.end());
  }
  return roots;
}

}  // namespace locus::dsp
