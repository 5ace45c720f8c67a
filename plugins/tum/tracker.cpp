// TUM particle filter: see tracker.hpp.
#include "tracker.hpp"

#include <cmath>
#include <random>

namespace locus::plugins::tum {

double constraint_log_likelihood(const std::vector<dsp::RangeEquation>& eqs, const Eigen::Vector3d& x) {
  // r_i = n_i + s_i rho - y_i; rho* = sum w s (y - n) / sum w s^2.
  double num = 0.0, den = 0.0;
  for (const auto& e : eqs) {
    if (e.sign == 0.0) continue;
    const double w = 1.0 / (e.sigma * e.sigma);
    num += w * e.sign * (e.y - (x + e.offset - e.target).norm());
    den += w * e.sign * e.sign;
  }
  const double rho = den > 0 ? num / den : 0.0;
  double cost = 0.0;
  for (const auto& e : eqs) {
    const double r = (x + e.offset - e.target).norm() + e.sign * rho - e.y;
    cost += r * r / (e.sigma * e.sigma);
  }
  return -0.5 * cost;
}

Tracker::Tracker(const TrackerConfig& cfg, std::uint64_t seed)
    : cfg_(cfg), pf_(static_cast<std::size_t>(std::max(1, cfg.particles)), seed) {}

std::optional<Eigen::Vector3d> Tracker::prior() const {
  if (!initialised_ || !cfg_.filter) return std::nullopt;
  return mean_;
}

TrackOutput Tracker::summary(bool outlier) const {
  TrackOutput o;
  o.ok = true;
  o.outlier = outlier;
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  const auto& ps = pf_.particles();
  const auto& ws = pf_.weights();
  for (std::size_t i = 0; i < ps.size(); ++i) m += ws[i] * ps[i];
  Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < ps.size(); ++i) c += ws[i] * (ps[i] - m) * (ps[i] - m).transpose();
  o.origin = m;
  o.cov = c + Eigen::Matrix3d::Identity() * (cfg_.std_floor_m * cfg_.std_floor_m / 3.0);
  const double std = std::sqrt(std::max(0.0, o.cov.trace()));
  o.confidence = outlier ? 0.2 : 1.0 / (1.0 + std / 0.1);
  return o;
}

TrackOutput Tracker::update(const Placement& p, bool moving, double t_s) {
  if (!cfg_.filter || p.roots.empty() || p.equations.empty()) {
    TrackOutput o;
    o.ok = p.ok;
    o.origin = p.origin;
    o.cov = p.cov + Eigen::Matrix3d::Identity() * (cfg_.std_floor_m * cfg_.std_floor_m / 3.0);
    const double std = std::sqrt(std::max(0.0, o.cov.trace()));
    o.confidence = 1.0 / (1.0 + std / 0.1);
    mean_ = p.origin;
    initialised_ = p.ok;
    return o;
  }
  if (!initialised_) {
    // Every root gets particles in proportion to exp(-cost/2), spread by its covariance.
    std::vector<double> w;
    for (const auto& r : p.roots) w.push_back(std::exp(-0.5 * (r.cost - p.roots.front().cost)));
    std::discrete_distribution<std::size_t> pick(w.begin(), w.end());
    std::normal_distribution<double> n01(0.0, 1.0);
    std::vector<Eigen::Matrix3d> chol;
    for (const auto& r : p.roots) {
      Eigen::Matrix3d c = r.cov.topLeftCorner<3, 3>();
      if (!c.allFinite()) c = Eigen::Matrix3d::Identity() * 0.01;
      c += Eigen::Matrix3d::Identity() * 1e-6;
      Eigen::LLT<Eigen::Matrix3d> llt(c);
      chol.push_back(llt.info() == Eigen::Success ? Eigen::Matrix3d(llt.matrixL()) : Eigen::Matrix3d::Identity() * 0.05);
    }
    pf_.initialize([&](Eigen::Vector3d& x, auto& rng) {
      const std::size_t k = pick(rng);
      x = p.roots[k].x + chol[k] * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    });
    pf_.update([&](const Eigen::Vector3d& x) { return constraint_log_likelihood(p.equations, x); });
    initialised_ = true;
    last_t_ = t_s;
    TrackOutput o = summary(false);
    mean_ = o.origin;
    return o;
  }
  const double dt = std::clamp(t_s - last_t_, 0.0, 10.0);
  last_t_ = t_s;
  const double step = moving ? std::max(cfg_.still_step_m, cfg_.moving_speed_mps * dt) : cfg_.still_step_m;
  std::normal_distribution<double> n01(0.0, 1.0);
  pf_.predict([&](Eigen::Vector3d& x, auto& rng) { x += step * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); });

  // Sec. VIII: the fix jumped farther than the motion allows -> outlier, predict only.
  const double allowed = cfg_.outlier_jump_m + (moving ? 3.0 * cfg_.moving_speed_mps * dt : 0.0);
  bool near = false;
  for (const auto& r : p.roots)
    if ((r.x - mean_).norm() <= allowed) near = true;
  if (!near && consecutive_outliers_ < 3) {
    ++consecutive_outliers_;
    TrackOutput o = summary(true);
    mean_ = o.origin;
    return o;
  }
  if (!near) {  // three in a row: the track is what is wrong; restart from this fix
    consecutive_outliers_ = 0;
    initialised_ = false;
    return update(p, moving, t_s);
  }
  consecutive_outliers_ = 0;
  if (!pf_.update([&](const Eigen::Vector3d& x) { return constraint_log_likelihood(p.equations, x); })) {
    initialised_ = false;
    return update(p, moving, t_s);
  }
  return settle(0.3 * step, n01);
}

TrackOutput Tracker::settle(double rough, std::normal_distribution<double>& n01) {
  if (pf_.effective_sample_size() < 0.5 * static_cast<double>(pf_.size())) {
    pf_.resample();
    pf_.predict([&](Eigen::Vector3d& x, auto& rng) { x += rough * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); });
  }
  TrackOutput o = summary(false);
  mean_ = o.origin;
  return o;
}

}  // namespace locus::plugins::tum

namespace locus::plugins::tum {

TrackOutput Tracker::update_gaussian(const Eigen::Vector3d& x, const Eigen::Matrix3d& cov_in, bool moving, double t_s) {
  Eigen::Matrix3d cov = cov_in;
  if (!cov.allFinite()) cov = Eigen::Matrix3d::Identity() * 0.25;
  cov += Eigen::Matrix3d::Identity() * 1e-6;
  Eigen::LLT<Eigen::Matrix3d> llt(cov);
  if (llt.info() != Eigen::Success) {
    cov = Eigen::Matrix3d::Identity() * std::max(1e-4, cov.trace() / 3.0);
    llt.compute(cov);
  }
  const Eigen::Matrix3d info = cov.inverse();
  const Eigen::Matrix3d lower = llt.matrixL();
  std::normal_distribution<double> n01(0.0, 1.0);
  auto loglik = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d d = p - x;
    return -0.5 * d.dot(info * d);
  };
  if (!initialised_) {
    pf_.initialize([&](Eigen::Vector3d& p, auto& rng) { p = x + lower * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); });
    initialised_ = true;
    last_t_ = t_s;
    TrackOutput o = summary(false);
    mean_ = o.origin;
    return o;
  }
  const double dt = std::clamp(t_s - last_t_, 0.0, 10.0);
  last_t_ = t_s;
  const double step = moving ? std::max(cfg_.still_step_m, cfg_.moving_speed_mps * dt) : cfg_.still_step_m;
  pf_.predict([&](Eigen::Vector3d& p, auto& rng) { p += step * Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); });
  // Sec. VIII: a fix farther from the track than the motion since the last one allows is an outlier.
  const double allowed = cfg_.outlier_jump_m + (moving ? 3.0 * cfg_.moving_speed_mps * dt : 0.0);
  if ((x - mean_).norm() > allowed) {
    if (++consecutive_outliers_ <= 3) {
      TrackOutput o = summary(true);
      mean_ = o.origin;
      return o;
    }
    consecutive_outliers_ = 0;
    initialised_ = false;  // the track, not the fixes, is wrong: restart from this fix
    return update_gaussian(x, cov_in, moving, t_s);
  }
  consecutive_outliers_ = 0;
  if (!pf_.update(loglik)) {
    initialised_ = false;
    return update_gaussian(x, cov_in, moving, t_s);
  }
  return settle(0.2 * step, n01);
}

}  // namespace locus::plugins::tum
