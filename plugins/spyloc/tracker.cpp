// SpyLoc EKF tracker. See tracker.hpp.
#include "tracker.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace locus::plugins::spyloc {

void Tracker::init(double t_s, const std::array<double, 2>& xy, const std::array<double, 3>& cov, double speed_std_mps) {
  t_ = t_s;
  x_ << xy[0], xy[1], 0.0, 0.0;
  P_.setZero();
  P_(0, 0) = cov[0];
  P_(0, 1) = P_(1, 0) = cov[1];
  P_(1, 1) = cov[2];
  P_(2, 2) = P_(3, 3) = speed_std_mps * speed_std_mps;
  init_ = true;
}

void Tracker::predict(double t_s) {
  const double dt = t_s - t_;
  if (!(dt > 0.0)) return;
  Eigen::Matrix4d F = Eigen::Matrix4d::Identity();
  F(0, 2) = F(1, 3) = dt;
  const double q = cfg_.accel_std_mps2 * cfg_.accel_std_mps2;
  Eigen::Matrix4d Q = Eigen::Matrix4d::Zero();
  for (int a = 0; a < 2; ++a) {
    Q(a, a) = q * dt * dt * dt / 3.0;
    Q(a, a + 2) = Q(a + 2, a) = q * dt * dt / 2.0;
    Q(a + 2, a + 2) = q * dt;
  }
  x_ = F * x_;
  P_ = F * P_ * F.transpose() + Q;
  const double v = std::hypot(x_(2), x_(3));
  if (v > cfg_.max_speed_mps) {
    x_(2) *= cfg_.max_speed_mps / v;
    x_(3) *= cfg_.max_speed_mps / v;
  }
  t_ = t_s;
}

namespace {

/// One range update of a 4-state EKF (both trackers): the innovation nu with range std std_m, gated
/// (gate_long for a range longer than predicted), and beyond huber sigmas taken with the variance that
/// puts it at huber sigmas (0 = off). Writes the NIS and the innovation variance; false = gated out.
bool range_update(Eigen::Vector4d& x, Eigen::Matrix4d& P, const Eigen::RowVector4d& H, double nu, double std_m,
                  double gate_sigma, double gate_long_sigma, double huber, double& nis, double& S_out) {
  const double S = (H * P * H.transpose())(0, 0) + std_m * std_m;
  S_out = S;
  nis = nu * nu / S;
  const double gate = nu > 0.0 ? gate_long_sigma : gate_sigma;
  if (nis > gate * gate) return false;
  double R = std_m * std_m, S_eff = S;
  if (huber > 0.0 && nis > huber * huber) {
    S_eff = nu * nu / (huber * huber);
    R += S_eff - S;
  }
  const Eigen::Vector4d K = P * H.transpose() / S_eff;
  x += K * nu;
  const Eigen::Matrix4d I_KH = Eigen::Matrix4d::Identity() - K * H;
  P = I_KH * P * I_KH.transpose() + K * R * K.transpose();  // Joseph form
  return true;
}

/// The slant range r from (x, y) at height z to beacon b and its row of the measurement Jacobian
/// (either tracker: position in the first two states).
Eigen::RowVector4d range_row(const Eigen::Vector4d& x, const std::array<double, 3>& b, double z_m, double& r) {
  const Eigen::Vector3d d(x(0) - b[0], x(1) - b[1], z_m - b[2]);
  r = std::max(d.norm(), 1e-6);
  Eigen::RowVector4d H = Eigen::RowVector4d::Zero();
  H(0) = d.x() / r;
  H(1) = d.y() / r;
  return H;
}

/// The slant range to beacon b and its variance under P.
RangePrediction predicted_range(const Eigen::Vector4d& x, const Eigen::Matrix4d& P, const std::array<double, 3>& b,
                                double z_m) {
  double r = 0.0;
  const Eigen::RowVector4d H = range_row(x, b, z_m, r);
  return {r, std::max(0.0, (H * P * H.transpose())(0, 0))};
}

}  // namespace

RangePrediction Tracker::predict_range(const std::array<double, 3>& b, double z_m) const {
  return predicted_range(x_, P_, b, z_m);
}

RangePrediction PdrTracker::predict_range(const std::array<double, 3>& b, double z_m) const {
  return predicted_range(x_, P_, b, z_m);
}

bool Tracker::update_range(const std::array<double, 3>& b, double z_m, double range_m, double std_m, double& nis) {
  double r = 0.0;
  const Eigen::RowVector4d H = range_row(x_, b, z_m, r);
  double S = 0.0;
  return range_update(x_, P_, H, range_m - r, std_m, cfg_.gate_sigma, cfg_.gate_long_sigma, cfg_.huber_sigma, nis, S);
}

void Tracker::inflate(double pos_std_m, double vel_std_mps) {
  P_(0, 0) += pos_std_m * pos_std_m;
  P_(1, 1) += pos_std_m * pos_std_m;
  P_(2, 2) += vel_std_mps * vel_std_mps;
  P_(3, 3) += vel_std_mps * vel_std_mps;
}

void Tracker::update_speed(double speed_mps, double std_mps) {
  const double v = std::hypot(x_(2), x_(3));
  if (v < 0.05) return;  // direction unknown: a speed alone cannot be applied
  Eigen::RowVector4d H = Eigen::RowVector4d::Zero();
  H(2) = x_(2) / v;
  H(3) = x_(3) / v;
  const double S = (H * P_ * H.transpose())(0, 0) + std_mps * std_mps;
  const Eigen::Vector4d K = P_ * H.transpose() / S;
  x_ += K * (speed_mps - v);
  P_ = (Eigen::Matrix4d::Identity() - K * H) * P_;
  P_ = 0.5 * (P_ + P_.transpose());
}

double Tracker::position_std() const { return std::sqrt(std::max(0.0, P_(0, 0) + P_(1, 1))); }

// ---------------------------------------------------------------- PdrTracker

void PdrTracker::init(const std::array<double, 2>& xy, const std::array<double, 3>& cov, double psi_rad,
                      double psi_std_rad, double k, double k_std) {
  x_ << xy[0], xy[1], psi_rad, k;
  P_.setZero();
  P_(0, 0) = cov[0];
  P_(0, 1) = P_(1, 0) = cov[1];
  P_(1, 1) = cov[2];
  P_(2, 2) = psi_std_rad * psi_std_rad;
  P_(3, 3) = k_std * k_std;
  init_ = true;
}

void PdrTracker::reset_position(const std::array<double, 2>& xy, const std::array<double, 3>& cov, double psi_widen_rad) {
  x_(0) = xy[0];
  x_(1) = xy[1];
  P_.row(0).setZero();
  P_.row(1).setZero();
  P_.col(0).setZero();
  P_.col(1).setZero();
  P_(0, 0) = cov[0];
  P_(0, 1) = P_(1, 0) = cov[1];
  P_(1, 1) = cov[2];
  P_(2, 2) += psi_widen_rad * psi_widen_rad;
}

void PdrTracker::step(const std::array<double, 2>& d_m) {
  const double len = std::hypot(d_m[0], d_m[1]);
  if (!(len > 1e-9)) return;
  const double c = std::cos(x_(2)), s = std::sin(x_(2)), k = x_(3);
  const Eigen::Vector2d rd(c * d_m[0] - s * d_m[1], s * d_m[0] + c * d_m[1]);  // R(ψ)·d
  Eigen::Matrix4d F = Eigen::Matrix4d::Identity();
  F(0, 2) = -k * rd.y();  // ∂(k R d)/∂ψ = k·(−s dx − c dy, c dx − s dy)
  F(1, 2) = k * rd.x();
  F(0, 3) = rd.x();
  F(1, 3) = rd.y();
  x_(0) += k * rd.x();
  x_(1) += k * rd.y();
  const Eigen::Vector2d u = rd / len, n(-u.y(), u.x());
  const double along = cfg_.stride_std_frac * k * len, across = cfg_.heading_std_rad * k * len;
  Eigen::Matrix4d Q = Eigen::Matrix4d::Zero();
  Q.topLeftCorner<2, 2>() = along * along * u * u.transpose() + across * across * n * n.transpose();
  Q(2, 2) = cfg_.psi_walk_rad * cfg_.psi_walk_rad;
  Q(3, 3) = cfg_.k_walk * cfg_.k_walk;
  P_ = F * P_ * F.transpose() + Q;
}

bool PdrTracker::update_range(const std::array<double, 3>& b, double z_m, double range_m, double std_m, double& nis) {
  double r = 0.0;
  const Eigen::RowVector4d H = range_row(x_, b, z_m, r);
  const bool ok = range_update(x_, P_, H, range_m - r, std_m, cfg_.gate_sigma, cfg_.gate_long_sigma, cfg_.huber_sigma, nis, last_S_);
  if (ok) x_(3) = std::clamp(x_(3), 0.5, 2.0);
  return ok;
}

double PdrTracker::position_std() const { return std::sqrt(std::max(0.0, P_(0, 0) + P_(1, 1))); }
double PdrTracker::psi_std_rad() const { return std::sqrt(std::max(0.0, P_(2, 2))); }
double PdrTracker::stride_scale_std() const { return std::sqrt(std::max(0.0, P_(3, 3))); }

Alignment align_paths(const std::vector<std::array<double, 2>>& dr, const std::vector<std::array<double, 2>>& track) {
  Alignment a;
  const std::size_t n = std::min(dr.size(), track.size());
  if (n < 2) return a;
  Eigen::Vector2d ma = Eigen::Vector2d::Zero(), mb = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    ma += Eigen::Vector2d(dr[i][0], dr[i][1]);
    mb += Eigen::Vector2d(track[i][0], track[i][1]);
  }
  ma /= static_cast<double>(n);
  mb /= static_cast<double>(n);
  double sdot = 0.0, scross = 0.0, saa = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d p = Eigen::Vector2d(dr[i][0], dr[i][1]) - ma, q = Eigen::Vector2d(track[i][0], track[i][1]) - mb;
    sdot += p.dot(q);
    scross += p.x() * q.y() - p.y() * q.x();
    saa += p.squaredNorm();
  }
  if (!(saa > 0.0)) return a;
  a.psi_rad = std::atan2(scross, sdot);
  a.k = std::hypot(sdot, scross) / saa;
  a.spread_m = std::sqrt(saa / static_cast<double>(n));
  const double c = std::cos(a.psi_rad), s = std::sin(a.psi_rad);
  double res = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d p = Eigen::Vector2d(dr[i][0], dr[i][1]) - ma, q = Eigen::Vector2d(track[i][0], track[i][1]) - mb;
    const Eigen::Vector2d m(a.k * (c * p.x() - s * p.y()), a.k * (s * p.x() + c * p.y()));
    res += (q - m).squaredNorm();
  }
  a.rms_m = std::sqrt(res / static_cast<double>(n));
  return a;
}

}  // namespace locus::plugins::spyloc
