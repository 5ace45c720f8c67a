// TUM network solve over a window of exchanges: see network.hpp.
#include "network.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include "locus/numbers.hpp"

namespace locus::plugins::tum {

namespace {

Eigen::Matrix3d rot_z(double psi) {
  return Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

enum class Kind { OneHearsN, HearsM, HearsN };

struct Eq {
  Kind kind;
  int k;       ///< exchange in the window
  int dev;     ///< device index (problem numbering), -1 for device 1
  Eigen::Vector3d point;  ///< device 1's mic (OneHearsN) or the hearing device's mic, body frame
  double y;
  double sigma;
  double dt_rx_s = 0.0;   ///< the hearing device's arrival minus its reference instant (its hearing of M)
};

/// The problem over the window: parameter layout, equations, residuals.
struct Problem {
  int n_dev = 0;
  int dev2 = -1;  ///< index of working device 2
  std::vector<std::string> ids;
  std::vector<bool> still;
  std::vector<int> psi_index;
  std::vector<std::vector<int>> x_index;    ///< [dev][k] (same for every k when still); -1 = absent
  std::vector<std::vector<int>> rho_index;  ///< [dev][k]; -1 = absent
  std::vector<std::vector<Eigen::Matrix3d>> r1t;   ///< [dev][k] R1_k^T
  std::vector<std::vector<Eigen::Matrix3d>> rd;    ///< [dev][k] R_d,k
  std::vector<std::optional<Eigen::Vector3d>> speaker;  ///< body frame
  std::vector<Eigen::Vector3d> m_k;                 ///< device 1's speaker (body), per exchange
  std::vector<Eigen::Vector3d> up_k;                ///< world up in device 1's body frame, per exchange
  std::vector<double> t_k;
  std::vector<Eq> eqs;
  int n_params = 0;
  NetworkConfig net;
  std::vector<double> psi_anchor;  ///< prior centre of each heading offset
  /// Per device: centre and 1-sigma of its height prior (0 and height_prior_m; the height sigma point
  /// of the results pins one device's height with a tight one).
  std::vector<double> h_centre, h_sigma;
  mutable std::vector<Eigen::Matrix3d> rot_cache;  ///< [dev * K + k], per residuals() call
  mutable std::vector<Eigen::Vector3d> n_cache;    ///< device 2's speaker per exchange
  mutable std::vector<Eigen::Vector3d> v_cache;    ///< [dev * K + k] velocity of a moving device (m/s)
  std::vector<std::vector<Eigen::Vector3d>> w_body;  ///< [dev][k] gyro rate (body, rad/s); zero when still
  std::vector<double> dt_n_s;                      ///< per exchange: N's emission minus device 2's reference
  double yaw_sigma = 0.35;         ///< prior 1-sigma (loose while something moves, tight when all is still)

  Eigen::Matrix3d rotation(int d, int k, const Eigen::VectorXd& p) const {
    return r1t[d][k] * rot_z(p[psi_index[d]]) * rd[d][k];
  }
  Eigen::Vector3d x_of(int d, int k, const Eigen::VectorXd& p) const {
    return p.segment<3>(x_index[d][k]);
  }
  Eigen::Vector3d n_of(int k, const Eigen::VectorXd& p) const {
    return x_of(dev2, k, p) + rotation(dev2, k, p) * *speaker[dev2];
  }
  int n_residuals() const {
    int n = static_cast<int>(eqs.size()) + n_dev;  // + yaw priors
    for (int d = 0; d < n_dev; ++d) {
      int blocks = 0, prev = -1;
      for (std::size_t k = 0; k < x_index[d].size(); ++k) {
        if (x_index[d][k] < 0) continue;
        if (still[d]) {
          if (blocks == 0) blocks = 1;
        } else {
          ++blocks;
          if (prev >= 0) n += 3;  // smoothness
          prev = static_cast<int>(k);
        }
      }
      if (net.height_prior_m > 0) n += blocks;
    }
    return n;
  }
  /// Motion within an exchange (NetworkConfig::exchange_motion) and the timing instants of device 1's
  /// (M) and device 2's (N) tone (dsp::doppler_timing_instant_s). The velocities (v_cache) are held
  /// fixed over a Levenberg-Marquardt run (solve_lm), residuals() never change them.
  bool motion = false;
  double instant_m_s = 0.0, instant_n_s = 0.0;
  /// Per device and exchange: the velocity as a linear combination of the device's origins (exchange,
  /// coefficient): the derivative at t_k of the parabola through the three exchanges nearest in time
  /// (centred where it can be; a straight line through two; nothing for one).
  std::vector<std::vector<std::vector<std::pair<int, double>>>> stencil;  ///< [dev][k]
  void build_stencils() {
    const std::size_t K = m_k.size();
    stencil.assign(static_cast<std::size_t>(n_dev), std::vector<std::vector<std::pair<int, double>>>(K));
    for (int d = 0; d < n_dev; ++d) {
      if (still[d]) continue;
      std::vector<int> ks;
      for (std::size_t k = 0; k < K; ++k)
        if (x_index[d][k] >= 0) ks.push_back(static_cast<int>(k));
      if (ks.size() < 2) continue;
      for (std::size_t k = 0; k < K; ++k) {
        if (x_index[d][k] < 0) continue;
        const double t = t_k[k];
        std::vector<int> near = ks;
        std::sort(near.begin(), near.end(), [&](int a, int b) {
          return std::abs(t_k[static_cast<std::size_t>(a)] - t) < std::abs(t_k[static_cast<std::size_t>(b)] - t);
        });
        near.resize(std::min<std::size_t>(3, near.size()));
        std::sort(near.begin(), near.end());
        auto& st = stencil[static_cast<std::size_t>(d)][k];
        const int ia = near.front(), ic = near.back();
        const double ta = t_k[static_cast<std::size_t>(ia)], tc = t_k[static_cast<std::size_t>(ic)];
        if (near.size() == 3) {
          const int ib = near[1];
          const double tb = t_k[static_cast<std::size_t>(ib)];
          if (tb - ta > 0.01 && tc - tb > 0.01) {
            st = {{ia, (2 * t - tb - tc) / ((ta - tb) * (ta - tc))},
                  {ib, (2 * t - ta - tc) / ((tb - ta) * (tb - tc))},
                  {ic, (2 * t - ta - tb) / ((tc - ta) * (tc - tb))}};
            continue;
          }
        }
        const double dt = std::max(0.05, tc - ta);
        st = {{ia, -1.0 / dt}, {ic, 1.0 / dt}};
      }
    }
  }
  /// v_cache from the origins in p through the stencils, limited to 3 x speed_mps (a start of the
  /// multi-start, or a formation being left, can string a track metres apart: taken at face value, its
  /// velocity would move a tone's emitter by metres).
  void velocities(const Eigen::VectorXd& p) const {
    const std::size_t K = m_k.size();
    v_cache.assign(static_cast<std::size_t>(n_dev) * K, Eigen::Vector3d::Zero());
    const double v_max = 3.0 * net.speed_mps;
    for (int d = 0; d < n_dev; ++d)
      for (std::size_t k = 0; k < K; ++k) {
        Eigen::Vector3d& v = v_cache[static_cast<std::size_t>(d) * K + k];
        for (const auto& [kj, coef] : stencil[static_cast<std::size_t>(d)][k])
          v += coef * p.segment<3>(x_index[d][static_cast<std::size_t>(kj)]);
        if (v.norm() > v_max) v *= v_max / v.norm();
      }
  }
  /// Velocity (device 1's frame) of a point `body` of device d at exchange k whose body rotation is r:
  /// zero for device 1 (the frame, d < 0) and still devices; else the origin's (v_cache) plus the
  /// gyro's spin of the lever arm, r (w x body).
  Eigen::Vector3d point_velocity(int d, std::size_t k, const Eigen::Matrix3d& r, const Eigen::Vector3d& body) const {
    if (!motion || d < 0 || still[d]) return Eigen::Vector3d::Zero();
    return v_cache[static_cast<std::size_t>(d) * m_k.size() + k] + r * w_body[d][k].cross(body);
  }
  /// Whitened residuals; equation residuals first (eqs order), then priors.
  void residuals(const Eigen::VectorXd& p, Eigen::VectorXd& r) const {
    r.resize(n_residuals());
    // Rotations and device 2's speaker, once per device and exchange.
    const std::size_t K = m_k.size();
    rot_cache.resize(static_cast<std::size_t>(n_dev) * K);
    n_cache.resize(K);
    for (int d = 0; d < n_dev; ++d) {
      const Eigen::Matrix3d rz = rot_z(p[psi_index[d]]);
      for (std::size_t k = 0; k < K; ++k)
        if (x_index[d][k] >= 0) rot_cache[static_cast<std::size_t>(d) * K + k] = r1t[d][k] * rz * rd[d][k];
    }
    for (std::size_t k = 0; k < K; ++k)
      if (x_index[dev2][k] >= 0)
        n_cache[k] = p.segment<3>(x_index[dev2][k]) + rot_cache[static_cast<std::size_t>(dev2) * K + k] * *speaker[dev2];
    auto point_vel = [&](int d, std::size_t k, const Eigen::Vector3d& body) {
      return point_velocity(d, k, rot_cache[static_cast<std::size_t>(d) * K + k], body);
    };
    int i = 0;
    for (const Eq& e : eqs) {
      double v = 0.0;
      const std::size_t k = static_cast<std::size_t>(e.k);
      // Receiver minus emitter at the instants of emission and arrival (w), and their velocities.
      Eigen::Vector3d w = Eigen::Vector3d::Zero(), v_rx = Eigen::Vector3d::Zero(), v_tx = Eigen::Vector3d::Zero();
      if (e.kind != Kind::HearsM && motion) v_tx = point_vel(dev2, k, *speaker[dev2]);
      const Eigen::Vector3d n_emitted = n_cache[k] + dt_n_s[k] * v_tx;
      switch (e.kind) {
        case Kind::OneHearsN:
          w = e.point - n_emitted;
          v = w.norm() - p[rho_index[dev2][e.k]] - e.y;
          break;
        case Kind::HearsM:
          v_rx = point_vel(e.dev, k, e.point);
          w = x_of(e.dev, e.k, p) + rot_cache[static_cast<std::size_t>(e.dev) * K + k] * e.point - m_k[k];
          v = w.norm() + p[rho_index[e.dev][e.k]] - e.y;
          break;
        case Kind::HearsN:
          v_rx = point_vel(e.dev, k, e.point);
          w = x_of(e.dev, e.k, p) + rot_cache[static_cast<std::size_t>(e.dev) * K + k] * e.point + e.dt_rx_s * v_rx -
              n_emitted;
          v = w.norm() + p[rho_index[e.dev][e.k]] - p[rho_index[dev2][e.k]] - e.y;
          break;
      }
      // Range-Doppler coupling (dsp::doppler_timing_instant_s): the arrival was timed late by
      // rdot * instant (in metres), so the model's range is compared with y minus that.
      if (motion) {
        const double rdot = (v_rx - v_tx).dot(w) / std::max(w.norm(), 1e-12);
        v += rdot * (e.kind == Kind::HearsM ? instant_m_s : instant_n_s);
      }
      r[i++] = v / e.sigma;
    }
    for (int d = 0; d < n_dev; ++d) r[i++] = (p[psi_index[d]] - psi_anchor[d]) / yaw_sigma;
    for (int d = 0; d < n_dev; ++d) {
      int prev = -1;
      bool done_still = false;
      for (std::size_t k = 0; k < x_index[d].size(); ++k) {
        if (x_index[d][k] < 0) continue;
        const Eigen::Vector3d x = p.segment<3>(x_index[d][k]);
        if (still[d]) {
          if (done_still) continue;
          done_still = true;
        } else if (prev >= 0) {
          const double dt = std::max(0.05, t_k[k] - t_k[static_cast<std::size_t>(prev)]);
          const Eigen::Vector3d dx = (x - p.segment<3>(x_index[d][static_cast<std::size_t>(prev)])) / (net.speed_mps * dt);
          r[i++] = dx[0], r[i++] = dx[1], r[i++] = dx[2];
        }
        prev = static_cast<int>(k);
        if (net.height_prior_m > 0) r[i++] = (up_k[k].dot(x) - h_centre[d]) / h_sigma[d];
      }
    }
  }
};

/// Analytic Jacobian of Problem::residuals (all parameters), with dRz/dpsi = Rz S(z).
void jacobian(const Problem& pr, const Eigen::VectorXd& p, Eigen::MatrixXd& jac) {
  const int m = pr.n_residuals();
  jac.setZero(m, pr.n_params);
  const std::size_t K = pr.m_k.size();
  const int n_dev = pr.n_dev;
  std::vector<Eigen::Matrix3d> rot(static_cast<std::size_t>(n_dev) * K), drot(static_cast<std::size_t>(n_dev) * K);
  Eigen::Matrix3d sz;
  sz << 0, -1, 0, 1, 0, 0, 0, 0, 0;
  for (int d = 0; d < n_dev; ++d) {
    const Eigen::Matrix3d rz = rot_z(p[pr.psi_index[d]]);
    for (std::size_t k = 0; k < K; ++k) {
      if (pr.x_index[d][k] < 0) continue;
      rot[static_cast<std::size_t>(d) * K + k] = pr.r1t[d][k] * rz * pr.rd[d][k];
      drot[static_cast<std::size_t>(d) * K + k] = pr.r1t[d][k] * rz * sz * pr.rd[d][k];
    }
  }
  const int d2 = pr.dev2;
  auto n_at = [&](std::size_t k) {
    return Eigen::Vector3d(p.segment<3>(pr.x_index[d2][k]) + rot[static_cast<std::size_t>(d2) * K + k] * *pr.speaker[d2]);
  };
  int i = 0;
  // Motion within an exchange (as in residuals; the origins' velocities are held fixed over a run,
  // Problem::motion): a point's velocity, and the heading offset's part through the lever arm's spin
  // (w x body) given d residual / d velocity of device d's point `body` at exchange k = g (a row).
  auto point_velocity = [&](int d, std::size_t k, const Eigen::Vector3d& body) {
    return d < 0 ? Eigen::Vector3d(Eigen::Vector3d::Zero()) : pr.point_velocity(d, k, rot[static_cast<std::size_t>(d) * K + k], body);
  };
  auto motion_terms = [&](int d, std::size_t k, const Eigen::Vector3d& body, const Eigen::Vector3d& g) {
    if (d < 0 || pr.still[d]) return;
    const double inv = 1.0 / pr.eqs[static_cast<std::size_t>(i)].sigma;
    jac(i, pr.psi_index[d]) += inv * g.dot(drot[static_cast<std::size_t>(d) * K + k] * pr.w_body[d][k].cross(body));
  };
  for (const Eq& e : pr.eqs) {
    const std::size_t k = static_cast<std::size_t>(e.k);
    const double inv = 1.0 / e.sigma;
    switch (e.kind) {
      case Kind::OneHearsN: {
        const Eigen::Vector3d w = n_at(k) + pr.dt_n_s[k] * point_velocity(d2, k, *pr.speaker[d2]) - e.point;
        const Eigen::Vector3d u = w / std::max(w.norm(), 1e-12);
        jac.block<1, 3>(i, pr.x_index[d2][k]) += inv * u.transpose();
        jac(i, pr.psi_index[d2]) += inv * u.dot(drot[static_cast<std::size_t>(d2) * K + k] * *pr.speaker[d2]);
        jac(i, pr.rho_index[d2][k]) += -inv;
        if (pr.motion) motion_terms(d2, k, *pr.speaker[d2], (pr.dt_n_s[k] + pr.instant_n_s) * u);
        break;
      }
      case Kind::HearsM:
      case Kind::HearsN: {
        const std::size_t dk = static_cast<std::size_t>(e.dev) * K + k;
        const Eigen::Vector3d target =
            e.kind == Kind::HearsM ? pr.m_k[k] : Eigen::Vector3d(n_at(k) + pr.dt_n_s[k] * point_velocity(d2, k, *pr.speaker[d2]));
        const Eigen::Vector3d w = p.segment<3>(pr.x_index[e.dev][k]) + rot[dk] * e.point +
                                  (e.kind == Kind::HearsN ? e.dt_rx_s : 0.0) * point_velocity(e.dev, k, e.point) - target;
        const Eigen::Vector3d u = w / std::max(w.norm(), 1e-12);
        jac.block<1, 3>(i, pr.x_index[e.dev][k]) += inv * u.transpose();
        jac(i, pr.psi_index[e.dev]) += inv * u.dot(drot[dk] * e.point);
        jac(i, pr.rho_index[e.dev][k]) += inv;
        if (e.kind == Kind::HearsN) {
          jac.block<1, 3>(i, pr.x_index[d2][k]) -= inv * u.transpose();
          jac(i, pr.psi_index[d2]) -= inv * u.dot(drot[static_cast<std::size_t>(d2) * K + k] * *pr.speaker[d2]);
          jac(i, pr.rho_index[d2][k]) -= inv;
        }
        if (pr.motion) {  // the receiver's spin (its motion and coupling), the emitter's
          if (e.kind == Kind::HearsM) {
            motion_terms(e.dev, k, e.point, pr.instant_m_s * u);
          } else {
            motion_terms(e.dev, k, e.point, (e.dt_rx_s + pr.instant_n_s) * u);
            motion_terms(d2, k, *pr.speaker[d2], -(pr.dt_n_s[k] + pr.instant_n_s) * u);
          }
        }
        break;
      }
    }
    ++i;
  }
  for (int d = 0; d < n_dev; ++d) jac(i++, pr.psi_index[d]) = 1.0 / pr.yaw_sigma;
  for (int d = 0; d < n_dev; ++d) {
    int prev = -1;
    bool done_still = false;
    for (std::size_t k = 0; k < K; ++k) {
      if (pr.x_index[d][k] < 0) continue;
      if (pr.still[d]) {
        if (done_still) continue;
        done_still = true;
      } else if (prev >= 0) {
        const double dt = std::max(0.05, pr.t_k[k] - pr.t_k[static_cast<std::size_t>(prev)]);
        const double g = 1.0 / (pr.net.speed_mps * dt);
        for (int a = 0; a < 3; ++a) {
          jac(i, pr.x_index[d][k] + a) = g;
          jac(i, pr.x_index[d][static_cast<std::size_t>(prev)] + a) = -g;
          ++i;
        }
      }
      prev = static_cast<int>(k);
      if (pr.net.height_prior_m > 0) {
        jac.block<1, 3>(i, pr.x_index[d][k]) = pr.up_k[k].transpose() / pr.h_sigma[d];
        ++i;
      }
    }
  }
}

/// Huber weights on the equation residuals (priors keep weight 1).
void huber(const Eigen::VectorXd& r, int n_eq, double k, Eigen::VectorXd& w) {
  w.setOnes(r.size());
  for (int i = 0; i < n_eq; ++i) {
    const double a = std::abs(r[i]);
    if (a > k) w[i] = k / a;
  }
}

double weighted_cost(const Eigen::VectorXd& r, const Eigen::VectorXd& w) {
  return (r.array().square() * w.array()).sum();
}

/// One Levenberg-Marquardt run (solve_lm).
double solve_lm_pass(const Problem& pr, Eigen::VectorXd& p, const std::vector<bool>& free_mask, int iterations,
                     Eigen::MatrixXd* info_out) {
  const int n_eq = static_cast<int>(pr.eqs.size());
  std::vector<int> cols;
  for (int j = 0; j < pr.n_params; ++j)
    if (free_mask[static_cast<std::size_t>(j)]) cols.push_back(j);
  const int m = static_cast<int>(cols.size());
  Eigen::VectorXd r, rn, w;
  pr.residuals(p, r);
  huber(r, n_eq, pr.net.huber_k, w);
  double cost = weighted_cost(r, w);
  double lambda = 1e-3;
  Eigen::MatrixXd jac(r.size(), m);
  Eigen::MatrixXd jtj(m, m);
  Eigen::VectorXd jtr(m);
  Eigen::MatrixXd full;
  // Normal equations row by row over each row's non-zeros: an arrival touches at most two devices'
  // origins, headings and clocks, a prior one or three parameters, so a dense J^T J (rows x params^2) did ~15x the work (perf: half of a window solve).
  std::vector<int> nz;
  auto build = [&] {
    jacobian(pr, p, full);
    for (int c = 0; c < m; ++c) jac.col(c) = full.col(cols[static_cast<std::size_t>(c)]);
    jtj.setZero();
    jtr.setZero();
    for (Eigen::Index i = 0; i < jac.rows(); ++i) {
      nz.clear();
      for (int c = 0; c < m; ++c)
        if (jac(i, c) != 0.0) nz.push_back(c);
      const double wi = w[i];
      for (std::size_t a = 0; a < nz.size(); ++a) {
        const double ja = wi * jac(i, nz[a]);
        jtr[nz[a]] += ja * r[i];
        for (std::size_t b = 0; b <= a; ++b) jtj(nz[a], nz[b]) += ja * jac(i, nz[b]);
      }
    }
    jtj.triangularView<Eigen::StrictlyUpper>() = jtj.transpose();
  };
  build();
  for (int it = 0; it < iterations; ++it) {
    bool improved = false;
    for (int tries = 0; tries < 6 && !improved; ++tries) {
      Eigen::MatrixXd a = jtj;
      for (int c = 0; c < m; ++c) a(c, c) += lambda * std::max(jtj(c, c), 1e-9);
      const Eigen::VectorXd step = a.ldlt().solve(-jtr);
      if (!step.allFinite()) break;
      Eigen::VectorXd q = p;
      for (int c = 0; c < m; ++c) q[cols[static_cast<std::size_t>(c)]] += step[c];
      pr.residuals(q, rn);
      const double cn = weighted_cost(rn, w);
      if (cn < cost) {
        const bool tiny = step.norm() < 1e-7 || cost - cn < 1e-9 * cost;
        p = q;
        r = rn;
        huber(r, n_eq, pr.net.huber_k, w);
        cost = weighted_cost(r, w);
        lambda = std::max(lambda * 0.3, 1e-9);
        improved = true;
        build();
        if (tiny) it = iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  if (info_out) {
    info_out->setZero(pr.n_params, pr.n_params);
    for (int a = 0; a < m; ++a)
      for (int b = 0; b < m; ++b) (*info_out)(cols[static_cast<std::size_t>(a)], cols[static_cast<std::size_t>(b)]) = jtj(a, b);
  }
  return cost;
}

/// Levenberg-Marquardt over the parameters flagged in `free_mask`. Returns the final cost. With motion
/// within exchanges, the moving devices' velocities are taken from the start p and held over a run,
/// then re-derived from its result and the run repeated, up to three passes, until they change by
/// less than 5 mm/s. Every run, the multi-start's too: candidate formations are compared with
/// velocities of their own (docs/tum.md, "Motion within an exchange": only the final solve: 17 of 20
/// ellipse seeds instead of 19).
double solve_lm(const Problem& pr, Eigen::VectorXd& p, const std::vector<bool>& free_mask, int iterations,
                Eigen::MatrixXd* info_out = nullptr) {
  if (!pr.motion) return solve_lm_pass(pr, p, free_mask, iterations, info_out);
  double cost = 0.0;
  for (int pass = 0; pass < 3; ++pass) {
    pr.velocities(p);
    const std::vector<Eigen::Vector3d> used = pr.v_cache;
    cost = solve_lm_pass(pr, p, free_mask, iterations, info_out);
    if (pass == 2) break;
    pr.velocities(p);
    double change = 0.0;
    for (std::size_t i = 0; i < used.size(); ++i) change = std::max(change, (pr.v_cache[i] - used[i]).norm());
    pr.v_cache = used;
    if (change < 0.005) break;
  }
  return cost;
}

}  // namespace

NetworkResult NetworkSolver::add(const std::vector<DeviceExchange>& devices) {
  NetworkResult out;
  if (devices.size() < 2) return out;
  const double c = cfg_.speed_of_sound_mps;
  Exchange ex;
  ex.devices = devices;
  ex.t_m1 = own_emission_time(devices[0], devices[0].t1_s, c);
  ex.t_n2 = own_emission_time(devices[1], devices[1].t2_s, c);
  ex.t_ref = ex.t_m1;
  if (!std::isfinite(ex.t_m1) || !std::isfinite(ex.t_n2) || !devices[0].attitude || !devices[1].attitude ||
      !devices[0].speaker || !devices[1].speaker)
    return out;

  // Single-exchange roots of the working pair (solver.hpp): candidates for device 2's new position.
  const ExchangeResult single = solve_exchange({devices[0], devices[1]}, cfg_);
  if (single.devices.size() < 2 || !single.devices[1].ok) return out;

  window_.push_back(ex);
  for (auto& [id, xs] : moving_x_) xs.push_back(Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  while (static_cast<int>(window_.size()) > std::max(1, net_.window)) {
    window_.pop_front();
    for (auto& [id, xs] : moving_x_)
      if (!xs.empty()) xs.pop_front();
  }
  const int K = static_cast<int>(window_.size());
  const int newest = K - 1;

  // ---- layout ----
  Problem pr;
  pr.net = net_;
  pr.motion = net_.exchange_motion;
  pr.instant_m_s = net_.doppler_instant1_s;
  pr.instant_n_s = net_.doppler_instant2_s;
  const std::string id1 = devices[0].id;
  std::map<std::string, int> index;
  for (const Exchange& e : window_)
    for (std::size_t i = 1; i < e.devices.size(); ++i) {
      const DeviceExchange& d = e.devices[i];
      if (!d.attitude || d.id == id1) continue;
      if (!index.count(d.id)) {
        index[d.id] = pr.n_dev++;
        pr.ids.push_back(d.id);
      }
    }
  if (!index.count(devices[1].id)) return out;
  pr.dev2 = index[devices[1].id];
  pr.still.assign(static_cast<std::size_t>(pr.n_dev), true);
  pr.x_index.assign(static_cast<std::size_t>(pr.n_dev), std::vector<int>(static_cast<std::size_t>(K), -1));
  pr.rho_index = pr.x_index;
  pr.r1t.assign(static_cast<std::size_t>(pr.n_dev), std::vector<Eigen::Matrix3d>(static_cast<std::size_t>(K), Eigen::Matrix3d::Identity()));
  pr.rd = pr.r1t;
  pr.speaker.assign(static_cast<std::size_t>(pr.n_dev), std::nullopt);
  pr.w_body.assign(static_cast<std::size_t>(pr.n_dev), std::vector<Eigen::Vector3d>(static_cast<std::size_t>(K), Eigen::Vector3d::Zero()));
  pr.dt_n_s.assign(static_cast<std::size_t>(K), 0.0);
  std::vector<std::vector<const DeviceExchange*>> obs(static_cast<std::size_t>(pr.n_dev),
                                                      std::vector<const DeviceExchange*>(static_cast<std::size_t>(K), nullptr));
  for (int k = 0; k < K; ++k) {
    const Exchange& e = window_[static_cast<std::size_t>(k)];
    const Eigen::Matrix3d r1 = e.devices[0].attitude->toRotationMatrix();
    pr.m_k.push_back(*e.devices[0].speaker);
    pr.up_k.push_back(r1.transpose() * Eigen::Vector3d::UnitZ());
    pr.t_k.push_back(e.t_ref);
    for (std::size_t i = 1; i < e.devices.size(); ++i) {
      const DeviceExchange& d = e.devices[i];
      if (!d.attitude || d.id == id1) continue;
      const int di = index[d.id];
      obs[static_cast<std::size_t>(di)][static_cast<std::size_t>(k)] = &d;
      pr.r1t[di][k] = r1.transpose();
      pr.rd[di][k] = d.attitude->toRotationMatrix();
      if (d.speaker) pr.speaker[di] = d.speaker;
      if (d.moving) pr.still[di] = false;
      if (d.gyro_radps) pr.w_body[di][k] = *d.gyro_radps;
    }
    const double ref2 = reference_time_s(e.devices[1].t1_s);
    if (std::isfinite(ref2) && std::isfinite(e.t_n2)) pr.dt_n_s[static_cast<std::size_t>(k)] = e.t_n2 - ref2;
  }
  if (!pr.speaker[pr.dev2]) return out;
  // Heading offsets are observable only while the geometry changes (a device moves): with every device
  // still, each exchange repeats the same constraints and the offsets trade against positions. Then
  // they keep what motion taught them (psi_anchor), held by the attitude's own accuracy.
  const bool any_moving = std::find(pr.still.begin(), pr.still.end(), false) != pr.still.end();
  pr.yaw_sigma = any_moving ? net_.yaw_prior_rad : net_.still_yaw_prior_rad;
  for (int d = 0; d < pr.n_dev; ++d) pr.psi_anchor.push_back(any_moving ? 0.0 : state_[pr.ids[d]].psi_anchor);
  pr.h_centre.assign(static_cast<std::size_t>(pr.n_dev), 0.0);
  pr.h_sigma.assign(static_cast<std::size_t>(pr.n_dev), net_.height_prior_m);
  int np = 0;
  for (int d = 0; d < pr.n_dev; ++d) {
    pr.psi_index.push_back(np++);
    int shared = -1;
    for (int k = 0; k < K; ++k) {
      if (!obs[d][k]) continue;
      if (pr.still[d]) {
        if (shared < 0) shared = np, np += 3;
        pr.x_index[d][k] = shared;
      } else {
        pr.x_index[d][k] = np;
        np += 3;
      }
      pr.rho_index[d][k] = np++;
    }
  }
  pr.n_params = np;

  // ---- equations ----
  const double timing_m = c * cfg_.timing_std_s;
  auto sigma_for = [&](const Eigen::Vector3d& lever) {
    const double a = lever.norm() * cfg_.attitude_std_rad;
    return std::sqrt(timing_m * timing_m + a * a);
  };
  for (int k = 0; k < K; ++k) {
    const Exchange& e = window_[static_cast<std::size_t>(k)];
    const DeviceExchange& d1 = e.devices[0];
    if (obs[pr.dev2][k]) {
      for (std::size_t a = 0; a < d1.mics.size() && a < d1.t2_s.size(); ++a) {
        if (!std::isfinite(d1.t2_s[a])) continue;
        pr.eqs.push_back(Eq{Kind::OneHearsN, k, pr.dev2, d1.mics[a], c * (d1.t2_s[a] - e.t_n2), sigma_for(*pr.speaker[pr.dev2])});
      }
    }
    for (int d = 0; d < pr.n_dev; ++d) {
      const DeviceExchange* o = obs[d][k];
      if (!o) continue;
      for (std::size_t j = 0; j < o->mics.size(); ++j) {
        if (j < o->t1_s.size() && std::isfinite(o->t1_s[j]))
          pr.eqs.push_back(Eq{Kind::HearsM, k, d, o->mics[j], c * (o->t1_s[j] - e.t_m1), sigma_for(o->mics[j])});
        if (d != pr.dev2 && obs[pr.dev2][k] && j < o->t2_s.size() && std::isfinite(o->t2_s[j])) {
          const double ref = reference_time_s(o->t1_s);
          pr.eqs.push_back(Eq{Kind::HearsN, k, d, o->mics[j], c * (o->t2_s[j] - e.t_n2),
                              std::sqrt(2.0) * sigma_for(o->mics[j]), std::isfinite(ref) ? o->t2_s[j] - ref : 0.0});
        }
      }
    }
  }

  // ---- initial values ----
  Eigen::VectorXd p = Eigen::VectorXd::Zero(np);
  std::vector<bool> known(static_cast<std::size_t>(pr.n_dev), false);
  for (int d = 0; d < pr.n_dev; ++d) {
    const State& s = state_[pr.ids[d]];
    p[pr.psi_index[d]] = s.psi;
    auto& xs = moving_x_[pr.ids[d]];
    xs.resize(static_cast<std::size_t>(K), Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
    for (int k = 0; k < K; ++k) {
      if (pr.x_index[d][k] < 0) continue;
      Eigen::Vector3d x = s.x;
      if (!pr.still[d] && xs[static_cast<std::size_t>(k)].allFinite()) x = xs[static_cast<std::size_t>(k)];
      p.segment<3>(pr.x_index[d][k]) = x;
    }
    known[static_cast<std::size_t>(d)] = s.known;
  }
  if (pr.motion) {
    pr.build_stencils();
    pr.velocities(p);  // solve_lm sets them for each run; residuals() outside one use these
  }
  // Clock offsets from the HearsM arrivals at the positions in q (one device, or every device: -1).
  auto init_rho = [&](Eigen::VectorXd& q, int only = -1) {
    for (int d = 0; d < pr.n_dev; ++d)
      for (int k = 0; k < K; ++k) {
        if (only >= 0 && d != only) continue;
        if (pr.rho_index[d][k] < 0) continue;
        double sum = 0.0;
        int n = 0;
        for (const Eq& e : pr.eqs)
          if (e.kind == Kind::HearsM && e.dev == d && e.k == k) {
            sum += e.y - (pr.x_of(d, k, q) + pr.rotation(d, k, q) * e.point - pr.m_k[k]).norm();
            ++n;
          }
        if (n) q[pr.rho_index[d][k]] = sum / n;
      }
  };
  std::vector<bool> all(static_cast<std::size_t>(np), true);
  // One device's own parameters (heading offset, origins, clock offsets): the multi-start's mask.
  auto own_mask = [&](int d) {
    std::vector<bool> mask(static_cast<std::size_t>(np), false);
    mask[static_cast<std::size_t>(pr.psi_index[d])] = true;
    for (int k = 0; k < K; ++k) {
      if (pr.x_index[d][k] >= 0)
        for (int a = 0; a < 3; ++a) mask[static_cast<std::size_t>(pr.x_index[d][k] + a)] = true;
      if (pr.rho_index[d][k] >= 0) mask[static_cast<std::size_t>(pr.rho_index[d][k])] = true;
    }
    return mask;
  };
  const Eigen::Vector3d up_new = pr.up_k[static_cast<std::size_t>(newest)];
  const Eigen::Matrix3d horizontal = Eigen::Matrix3d::Identity() - up_new * up_new.transpose();
  // Distinct basins among solutions (cost, x, psi) of one still device: best first, each farther than
  // basin_distinct_m horizontally from every one kept before it (a mirror image through device 1's
  // horizontal plane is the same horizontal position: not a distinct basin).
  auto distinct_basins = [&](std::vector<Basin> sols, double drop_cost) {
    std::sort(sols.begin(), sols.end(), [](const Basin& a, const Basin& b) { return a.cost < b.cost; });
    std::vector<Basin> kept;
    for (const Basin& b : sols) {
      if (!b.x.allFinite() || !std::isfinite(b.cost) || b.x.norm() > cfg_.max_range_m) continue;
      if (!kept.empty() && b.cost - kept.front().cost > drop_cost) break;
      bool dup = false;
      for (const Basin& k : kept) dup = dup || (horizontal * (b.x - k.x)).norm() < net_.basin_distinct_m;
      if (!dup) kept.push_back(b);
      if (static_cast<int>(kept.size()) > net_.alternatives) break;
    }
    if (!kept.empty()) kept.erase(kept.begin());  // the best is the solution itself
    return kept;
  };
  std::vector<std::vector<std::vector<Basin>>> cand_basins;  // [candidate][device]: multi-start solutions
  std::vector<Basin> dev2_sols;                              // device 2's candidates, each solved

  // Device 2's newest position: every root of the single-exchange solve is a candidate (Sec. IV-B:
  // the roots are kept; the window decides).
  std::vector<Eigen::Vector3d> candidates;
  const bool dev2_known = known[static_cast<std::size_t>(pr.dev2)];
  if (pr.still[pr.dev2] && dev2_known) {
    candidates.push_back(p.segment<3>(pr.x_index[pr.dev2][newest]));
  } else {
    for (std::size_t i = 0; i < single.devices[1].roots.size() && i < 4; ++i) candidates.push_back(single.devices[1].roots[i].x);
    // A moving device 2's height is what the pair sees least (flat two-mic devices: second order);
    // the monitors see it, but only if the formation they are fitted around starts near it. While
    // the window fills, each root is also tried shifted by +-moving_height_candidates_m along the
    // vertical (with the world's hard iron, 3 of 20 ellipse seeds settled in a wrong formation from
    // a root at the wrong height: docs/tum.md "Network solve").
    if (net_.moving_height_candidates_m > 0 && !pr.still[pr.dev2] && K < net_.window) {
      const Eigen::Vector3d up = pr.up_k[static_cast<std::size_t>(newest)];
      const std::size_t n0 = candidates.size();
      for (std::size_t i = 0; i < n0; ++i)
        for (double dz : {-net_.moving_height_candidates_m, net_.moving_height_candidates_m}) candidates.push_back(candidates[i] + dz * up);
    }
    // A still device 2 is placed once: its mirror image through device 1's two-mic axis (the vertical
    // plane through device 1's mics; what a wrong heading of device 2 turns into the better fit of one
    // exchange) is a candidate too, so that the window can decide between the two formations.
    const DeviceExchange& d1 = devices[0];
    if (pr.still[pr.dev2] && !candidates.empty() && d1.mics.size() >= 2) {
      const Eigen::Vector3d up = pr.up_k[static_cast<std::size_t>(newest)];
      const Eigen::Vector3d axis = d1.mics[1] - d1.mics[0];
      const Eigen::Vector3d n = axis.cross(up);
      if (n.norm() > 1e-6) {
        const Eigen::Vector3d u = n.normalized(), mid = 0.5 * (d1.mics[0] + d1.mics[1]);
        const Eigen::Vector3d x = candidates.front();
        candidates.push_back(x - 2.0 * u.dot(x - mid) * u);
      }
    }
  }
  Eigen::VectorXd best_p = p;
  double best_cost = kInf;
  std::size_t best_cand = 0;
  std::vector<std::pair<Eigen::VectorXd, double>> cand_q;  // every candidate's solution and cost
  for (const Eigen::Vector3d& cand : candidates) {
    Eigen::VectorXd q = p;
    q.segment<3>(pr.x_index[pr.dev2][newest]) = cand;
    for (int k = 0; k < K; ++k)
      if (pr.x_index[pr.dev2][k] >= 0 && (!dev2_known || !moving_x_[pr.ids[pr.dev2]][static_cast<std::size_t>(k)].allFinite()))
        q.segment<3>(pr.x_index[pr.dev2][k]) = cand;
    init_rho(q);
    cand_basins.emplace_back(static_cast<std::size_t>(pr.n_dev));
    // Unknown monitors: multi-start on their own parameters with the rest fixed.
    for (int d = 0; d < pr.n_dev; ++d) {
      // A device seen for the first time, and every device while the window fills (one exchange leaves
      // a monitor nearly unobservable: its first basin may be wrong), is searched from many starts; a
      // known device's current solution is one of them.
      const bool warmup = K < net_.window || state_[pr.ids[d]].exchanges < net_.window;
      if (d == pr.dev2 || (known[static_cast<std::size_t>(d)] && !warmup)) continue;
      const std::vector<bool> mask = own_mask(d);
      std::vector<Basin>& sols = cand_basins.back()[static_cast<std::size_t>(d)];
      auto record = [&](const Eigen::VectorXd& t, double cst) {
        if (pr.still[d]) sols.push_back(Basin{t.segment<3>(pr.x_index[d][newest]), t[pr.psi_index[d]], cst});
      };
      const Eigen::Vector3d centre = 0.5 * (pr.m_k[newest] + pr.n_of(newest, q));
      Eigen::VectorXd best_local = q;
      double best_local_cost = kInf;
      const int n_dir = 26;
      const double golden = M_PI * (3.0 - std::sqrt(5.0));
      if (known[static_cast<std::size_t>(d)]) {
        Eigen::VectorXd t = q;
        init_rho(t);
        best_local_cost = solve_lm(pr, t, mask, 15);
        best_local = t;
        record(t, best_local_cost);
      }
      for (double radius : {0.7, 1.5, 2.5}) {
        for (int i = 0; i < n_dir; ++i) {
          const double z = 1.0 - 2.0 * (i + 0.5) / n_dir;
          const double rr = std::sqrt(std::max(0.0, 1.0 - z * z));
          const Eigen::Vector3d x0 = centre + radius * Eigen::Vector3d(rr * std::cos(golden * i), rr * std::sin(golden * i), z);
          Eigen::VectorXd t = q;
          t[pr.psi_index[d]] = 0.0;
          for (int k = 0; k < K; ++k)
            if (pr.x_index[d][k] >= 0) t.segment<3>(pr.x_index[d][k]) = x0;
          init_rho(t);
          const double cst = solve_lm(pr, t, mask, 15);
          record(t, cst);
          if (cst < best_local_cost) best_local_cost = cst, best_local = t;
        }
      }
      q = best_local;
    }
    const double cst = solve_lm(pr, q, all, candidates.size() > 1 ? 4 : net_.iterations);
    if (pr.still[pr.dev2]) dev2_sols.push_back(Basin{q.segment<3>(pr.x_index[pr.dev2][newest]), q[pr.psi_index[pr.dev2]], cst});
    cand_q.emplace_back(q, cst);
    if (cst < best_cost) best_cost = cst, best_p = q, best_cand = cand_basins.size() - 1;
  }
  // Snapshot of a solution: every device placed in the newest exchange -> its basin.
  auto snapshot = [&](const Eigen::VectorXd& q, double cst) {
    std::map<std::string, Basin> f;
    for (int d = 0; d < pr.n_dev; ++d)
      if (pr.x_index[d][newest] >= 0) f[pr.ids[d]] = Basin{q.segment<3>(pr.x_index[d][newest]), q[pr.psi_index[d]], cst};
    return f;
  };
  auto dev2_apart = [&](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    const int xi = pr.x_index[pr.dev2][newest];
    return (horizontal * (a.segment<3>(xi) - b.segment<3>(xi))).norm() >= net_.basin_distinct_m;
  };
  if (any_moving) {
    formations_.clear();
  } else if (cand_q.size() > 1) {
    // Device 2's other roots, each with its monitors: the runner-up formations (best first).
    std::sort(cand_q.begin(), cand_q.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
    formations_.clear();
    std::vector<const Eigen::VectorXd*> kept{&best_p};
    for (const auto& [q, cst] : cand_q) {
      if (static_cast<int>(formations_.size()) >= net_.alternatives) break;
      bool apart = true;
      for (const Eigen::VectorXd* k : kept) apart = apart && dev2_apart(q, *k);
      if (!apart) continue;
      formations_.push_back(snapshot(q, cst));
      kept.push_back(&q);
    }
  }
  // The chosen candidate's runner-up basins replace the kept ones where a multi-start ran.
  for (int d = 0; d < pr.n_dev; ++d) {
    const std::vector<Basin>& sols = cand_basins[best_cand][static_cast<std::size_t>(d)];
    if (!sols.empty()) state_[pr.ids[d]].alternatives = distinct_basins(sols, kInf);
  }
  if (dev2_sols.size() > 1) state_[pr.ids[pr.dev2]].alternatives = distinct_basins(dev2_sols, kInf);
  p = best_p;  // the best candidate after a few iterations; the final solve below converges it
  Eigen::MatrixXd info;
  double cost = solve_lm(pr, p, all, net_.iterations, &info);
  const int dof = std::max(1, pr.n_residuals() - np);

  // Kept basins of every still device, re-solved in this window (its own parameters, the rest fixed
  // at the solution): one that now fits better takes over (the growing window decides); the others'
  // costs weight the covariance's mixture below.
  std::vector<std::vector<Basin>> basins(static_cast<std::size_t>(pr.n_dev));
  auto resolve_basins = [&] {
    bool switched = false;
    for (int d = 0; d < pr.n_dev && !switched; ++d) {
      auto& alts = state_[pr.ids[d]].alternatives;
      basins[static_cast<std::size_t>(d)].clear();
      if (!pr.still[d] || pr.x_index[d][newest] < 0) {
        alts.clear();
        continue;
      }
      const std::vector<bool> mask = own_mask(d);
      const int xi = pr.x_index[d][newest];
      for (Basin& b : alts) {
        Eigen::VectorXd t = p;
        t.segment<3>(xi) = b.x;
        t[pr.psi_index[d]] = b.psi;
        init_rho(t, d);
        b.cost = solve_lm(pr, t, mask, 6);
        b.x = t.segment<3>(xi), b.psi = t[pr.psi_index[d]];
        if (b.cost < cost - 1e-9 && !switched) {
          // The runner-up fits the window better: it becomes the solution, the old one a runner-up.
          const Basin old{p.segment<3>(xi), p[pr.psi_index[d]], cost};
          p = t;
          cost = solve_lm(pr, p, all, net_.iterations, &info);
          b = old;
          ++basin_switches_;
          switched = true;
        }
      }
      if (switched) break;
      std::vector<Basin> all_b{Basin{p.segment<3>(xi), p[pr.psi_index[d]], cost}};
      all_b.insert(all_b.end(), alts.begin(), alts.end());
      alts = distinct_basins(all_b, net_.basin_drop_chi2 * std::max(1.0, cost / dof));
      basins[static_cast<std::size_t>(d)] = alts;
    }
    return switched;
  };
  // Runner-up formations, re-solved jointly from where they were: one that fits better takes over.
  std::vector<std::pair<std::map<std::string, Basin>, double>> formation_fits;
  for (auto& f : formations_) {
    Eigen::VectorXd t = p;
    for (int d = 0; d < pr.n_dev; ++d) {
      const auto it = f.find(pr.ids[d]);
      if (it == f.end() || pr.x_index[d][newest] < 0) continue;
      for (int k = 0; k < K; ++k)
        if (pr.x_index[d][k] >= 0) t.segment<3>(pr.x_index[d][k]) = it->second.x;
      t[pr.psi_index[d]] = it->second.psi;
    }
    init_rho(t);
    double cf = solve_lm(pr, t, all, 8);
    if (cf < cost) {
      const std::map<std::string, Basin> old = snapshot(p, cost);
      std::swap(p, t);
      cost = solve_lm(pr, p, all, net_.iterations, &info);
      cf = old.begin()->second.cost;
      ++basin_switches_;
    }
    f = snapshot(t, cf);
  }
  {
    const double drop = net_.basin_drop_chi2 * std::max(1.0, cost / dof);
    std::vector<std::map<std::string, Basin>> keep;
    for (auto& f : formations_) {
      const double cf = f.empty() ? kInf : f.begin()->second.cost;
      const auto it2 = f.find(pr.ids[pr.dev2]);
      if (cf - cost > drop || it2 == f.end() ||
          (horizontal * (it2->second.x - p.segment<3>(pr.x_index[pr.dev2][newest]))).norm() < net_.basin_distinct_m)
        continue;
      keep.push_back(std::move(f));
    }
    formations_ = std::move(keep);
  }
  for (int round = 0; round < 3 && resolve_basins(); ++round) {
  }
  // The formations' placements join each device's basins in the mixture.
  for (const auto& f : formations_)
    for (int d = 0; d < pr.n_dev; ++d) {
      const auto it = f.find(pr.ids[d]);
      if (it != f.end() && pr.still[d] && pr.x_index[d][newest] >= 0) basins[static_cast<std::size_t>(d)].push_back(it->second);
    }

  // Sec. VIII in the window: the range device 1 - device 2 is what one exchange measures best (the
  // distance sums, Eq. 3-4). A window whose device 2 disagrees with this exchange's range by more
  // than `outlier_m` was built on something wrong (an exchange paired across clocks wrongly, a wrong
  // basin): it is dropped and the solve restarts from this exchange alone.
  {
    const Eigen::Vector3d x2 = p.segment<3>(pr.x_index[pr.dev2][newest]);
    const double range1 = single.devices[1].roots.front().x.norm();
    if (std::abs(x2.norm() - range1) > net_.outlier_m && !restarting_) {
      ++restarts_;
      const Exchange keep = window_.back();
      window_.clear();
      state_.clear();
      formations_.clear();
      moving_x_.clear();
      restarting_ = true;
      NetworkResult again = add(keep.devices);
      restarting_ = false;
      again.restarted = true;
      return again;
    }
  }

  // ---- results ----
  Eigen::VectorXd r;
  pr.residuals(p, r);
  out.chi2_dof = cost / dof;
  const double scale = std::max(1.0, out.chi2_dof);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(info);
  Eigen::MatrixXd cov = lu.rank() == np ? Eigen::MatrixXd(lu.inverse()) : Eigen::MatrixXd::Identity(np, np) * kInf;
  out.ok = true;
  out.t_ref_s = ex.t_ref;
  out.up = pr.up_k[static_cast<std::size_t>(newest)];
  NetworkPlacement p1;
  p1.id = id1;
  p1.ok = true;
  out.devices.push_back(p1);
  for (int d = 0; d < pr.n_dev; ++d) {
    State& s = state_[pr.ids[d]];
    auto& xs = moving_x_[pr.ids[d]];
    for (int k = 0; k < K; ++k)
      if (pr.x_index[d][k] >= 0) xs[static_cast<std::size_t>(k)] = p.segment<3>(pr.x_index[d][k]);
    s.psi = p[pr.psi_index[d]];
    if (any_moving) s.psi_anchor = s.psi;
    const int xi = pr.x_index[d][newest];
    if (xi < 0) continue;  // not in the newest exchange
    if (!p.segment<3>(xi).allFinite() || p.segment<3>(xi).norm() > cfg_.max_range_m) {
      s = State{};  // diverged: searched afresh next time, not published
      continue;
    }
    s.x = p.segment<3>(xi);
    s.known = true;
    ++s.exchanges;
    NetworkPlacement np_;
    np_.id = pr.ids[d];
    np_.ok = true;
    np_.still = pr.still[d];
    np_.origin = s.x;
    np_.cov = cov.block<3, 3>(xi, xi) * scale;
    np_.yaw_offset_rad = s.psi;
    // Height: observed only when the data narrow the prior clearly (network.hpp).
    np_.vertical_std_m = std::sqrt(std::max(0.0, up_new.dot(np_.cov * up_new)));
    if (net_.height_prior_m > 0 && np_.vertical_std_m > net_.unobserved_height_ratio * net_.height_prior_m) {
      np_.height_observed = false;
      // Sigma points: the device's height pinned at +-1 posterior std from the solution (its own
      // parameters re-solved, the rest fixed). A range fixes the slant distance, so the horizontal
      // position moves by h(s) ~ s^2: with s ~ N(0, std^2), E[h h^T] = 3/2 (h+ h+^T + h- h-^T).
      const std::vector<bool> mask = own_mask(d);
      const double centre = pr.h_centre[d], sig = pr.h_sigma[d];
      Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
      for (double sign : {1.0, -1.0}) {
        const double shift = sign * np_.vertical_std_m;
        Eigen::VectorXd t = p;
        for (int k = 0; k < K; ++k)
          if (pr.x_index[d][k] >= 0 && (!pr.still[d] || k == newest)) t.segment<3>(pr.x_index[d][k]) += shift * pr.up_k[k];
        pr.h_centre[d] = up_new.dot(s.x) + shift;
        pr.h_sigma[d] = 1e-3;
        solve_lm(pr, t, mask, 4);
        const Eigen::Vector3d h = horizontal * (t.segment<3>(xi) - s.x);
        second += 1.5 * h * h.transpose();
      }
      pr.h_centre[d] = centre, pr.h_sigma[d] = sig;
      np_.cov += second;
    }
    // Basins: the mixture of the reported solution and its kept runner-ups, weighted by their fit
    // (exp(-chi2/2), chi2 scaled like the covariance), about the reported point.
    const std::vector<Basin>& alts = basins[static_cast<std::size_t>(d)];
    if (!alts.empty()) {
      double wsum = 1.0;
      Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
      for (const Basin& b : alts) {
        const double w = std::exp(-0.5 * std::max(0.0, b.cost - cost) / scale);
        const Eigen::Vector3d dx = np_.height_observed ? Eigen::Vector3d(b.x - s.x) : Eigen::Vector3d(horizontal * (b.x - s.x));
        spread += w * dx * dx.transpose();
        wsum += w;
      }
      np_.cov += spread / wsum;
      np_.basins = 1 + static_cast<int>(alts.size());
      np_.basin_weight = 1.0 / wsum;
    }
    double sum = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < pr.eqs.size(); ++i)
      if (pr.eqs[i].k == newest && (pr.eqs[i].dev == d)) sum += r[static_cast<Eigen::Index>(i)] * r[static_cast<Eigen::Index>(i)], ++n;
    np_.rms_sigma = n ? std::sqrt(sum / n) : 0.0;
    out.devices.push_back(np_);
  }
  return out;
}

}  // namespace locus::plugins::tum
