// Madgwick and Mahony attitude filters (see ahrs.hpp). The objective functions are written with the
// rotation matrix R(q) (body -> reference) and its partial derivatives, so one code path serves the
// gravity and the magnetic terms.
#include "locus/dsp/ahrs.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace locus::dsp {

namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::Vector4d;

/// d(R(q)^T v)/d(w,x,y,z) for the polynomial form of R (valid on and near the unit sphere).
Eigen::Matrix<double, 3, 4> jacobian_rt(const Quaterniond& q, const Vector3d& v) noexcept {
  const double w = q.w(), x = q.x(), y = q.y(), z = q.z();
  Matrix3d dw, dx, dy, dz;
  dw << 0, -2 * z, 2 * y, 2 * z, 0, -2 * x, -2 * y, 2 * x, 0;
  dx << 0, 2 * y, 2 * z, 2 * y, -4 * x, -2 * w, 2 * z, 2 * w, -4 * x;
  dy << -4 * y, 2 * x, 2 * w, 2 * x, 0, 2 * z, -2 * w, 2 * z, -4 * y;
  dz << -4 * z, -2 * w, 2 * x, 2 * w, -4 * z, 2 * y, 2 * x, 2 * y, 0;
  Eigen::Matrix<double, 3, 4> j;
  j.col(0) = dw.transpose() * v;
  j.col(1) = dx.transpose() * v;
  j.col(2) = dy.transpose() * v;
  j.col(3) = dz.transpose() * v;
  return j;
}

Vector4d as_vec(const Quaterniond& q) noexcept { return Vector4d(q.w(), q.x(), q.y(), q.z()); }
Quaterniond from_vec(const Vector4d& v) noexcept { return Quaterniond(v[0], v[1], v[2], v[3]); }

/// 0.5 * q ⊗ (0, w) as a (w,x,y,z) vector.
Vector4d q_dot(const Quaterniond& q, const Vector3d& w) noexcept {
  return 0.5 * as_vec(q * Quaterniond(0.0, w.x(), w.y(), w.z()));
}

/// The Earth field reference of Madgwick/Mahony: the measured field rotated into the reference
/// frame, with its horizontal part put on +x.
Vector3d field_reference(const Quaterniond& q, const Vector3d& m_unit) noexcept {
  const Vector3d h = q * m_unit;
  return Vector3d(std::hypot(h.x(), h.y()), 0.0, h.z());
}

bool usable(const Vector3d& v) noexcept { return v.allFinite() && v.squaredNorm() > 1e-20; }

}  // namespace

double heading_of(const Quaterniond& q) noexcept {
  const Vector3d y = q * Vector3d::UnitY();
  return std::atan2(y.y(), y.x());
}

Quaterniond attitude_from_accel(const Vector3d& accel) noexcept {
  if (!usable(accel)) return Quaterniond::Identity();
  return Quaterniond::FromTwoVectors(accel.normalized(), Vector3d::UnitZ()).normalized();
}

Quaterniond attitude_from_accel_mag(const Vector3d& accel, const Vector3d& mag) noexcept {
  if (!usable(accel) || !usable(mag)) return attitude_from_accel(accel);
  const Vector3d up = accel.normalized();
  Vector3d north = mag - mag.dot(up) * up;
  if (north.norm() < 1e-6 * mag.norm()) return attitude_from_accel(accel);
  north.normalize();
  const Vector3d west = up.cross(north);
  Matrix3d r;  // body -> reference: rows are the reference axes expressed in the body frame
  r.row(0) = north.transpose();
  r.row(1) = west.transpose();
  r.row(2) = up.transpose();
  return Quaterniond(r).normalized();
}

void Madgwick::update(const Vector3d& gyro, const Vector3d& accel, double dt_s) noexcept {
  Vector4d qd = q_dot(q_, gyro);
  if (usable(accel)) {
    const Vector3d a = accel.normalized();
    const Vector3d f = q_.conjugate() * Vector3d::UnitZ() - a;
    const Vector4d grad = jacobian_rt(q_, Vector3d::UnitZ()).transpose() * f;
    const double n = grad.norm();
    if (n > 1e-12) qd -= beta_ * grad / n;
  }
  q_ = from_vec(as_vec(q_) + qd * dt_s).normalized();
}

void Madgwick::update(const Vector3d& gyro, const Vector3d& accel, const Vector3d& mag, double dt_s) noexcept {
  if (!usable(mag) || !usable(accel)) return update(gyro, accel, dt_s);
  const Vector3d a = accel.normalized();
  const Vector3d m = mag.normalized();
  const Vector3d b = field_reference(q_, m);
  const Vector3d fg = q_.conjugate() * Vector3d::UnitZ() - a;
  const Vector3d fb = q_.conjugate() * b - m;
  const Vector4d grad = jacobian_rt(q_, Vector3d::UnitZ()).transpose() * fg + jacobian_rt(q_, b).transpose() * fb;
  Vector4d qd = q_dot(q_, gyro);
  const double n = grad.norm();
  if (n > 1e-12) qd -= beta_ * grad / n;
  q_ = from_vec(as_vec(q_) + qd * dt_s).normalized();
}

void Mahony::step(const Vector3d& gyro, const Vector3d& err, double dt_s) noexcept {
  if (ki_ > 0.0) bias_ += ki_ * err * dt_s;
  const Vector3d w = gyro + kp_ * err + bias_;
  q_ = from_vec(as_vec(q_) + q_dot(q_, w) * dt_s).normalized();
}

void Mahony::update(const Vector3d& gyro, const Vector3d& accel, double dt_s) noexcept {
  Vector3d err = Vector3d::Zero();
  if (usable(accel)) err = accel.normalized().cross(q_.conjugate() * Vector3d::UnitZ());
  step(gyro, err, dt_s);
}

void Mahony::update(const Vector3d& gyro, const Vector3d& accel, const Vector3d& mag, double dt_s) noexcept {
  if (!usable(mag) || !usable(accel)) return update(gyro, accel, dt_s);
  const Vector3d m = mag.normalized();
  const Vector3d b = field_reference(q_, m);
  Vector3d err = accel.normalized().cross(q_.conjugate() * Vector3d::UnitZ());
  err += m.cross(q_.conjugate() * b);
  step(gyro, err, dt_s);
}

void HardIronCalibrator::reset() noexcept {
  a_.setZero();
  b_.setZero();
  h_.setZero();
  theta_.setZero();
  wxm_.setZero();
  t_interval_ = 0.0;
  started_ = false;
  max_std_ = cfg_.prior_ut;
  turns_ = 0;
}

void HardIronCalibrator::update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& mag, double dt_s) noexcept {
  if (!gyro.allFinite() || !mag.allFinite()) return;
  if (!started_ || !(dt_s >= 0.0)) {
    started_ = true;
    m0_ = mag;
    theta_.setZero();
    wxm_.setZero();
    t_interval_ = 0.0;
    return;
  }
  theta_ += gyro * dt_s;
  wxm_ += gyro.cross(mag) * dt_s;
  t_interval_ += dt_s;
  if (t_interval_ < cfg_.interval_s) return;
  if (theta_.norm() >= cfg_.min_turn_rad) {
    Eigen::Matrix3d skew;
    skew << 0, -theta_.z(), theta_.y(), theta_.z(), 0, -theta_.x(), -theta_.y(), theta_.x(), 0;
    const Eigen::Vector3d z = (mag - m0_) + wxm_;
    const double forget = std::exp(-t_interval_ / cfg_.tau_s);
    const double w = 1.0 / (2.0 * cfg_.noise_ut * cfg_.noise_ut);
    a_ = forget * a_ + w * skew.transpose() * skew;
    b_ = forget * b_ + w * skew.transpose() * z;
    const Eigen::Matrix3d post = a_ + Eigen::Matrix3d::Identity() / (cfg_.prior_ut * cfg_.prior_ut);
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(post);
    h_ = ldlt.solve(b_);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(post, Eigen::EigenvaluesOnly);
    max_std_ = 1.0 / std::sqrt(std::max(eig.eigenvalues()[0], 1e-300));
    ++turns_;
  }
  m0_ = mag;
  theta_.setZero();
  wxm_.setZero();
  t_interval_ = 0.0;
}

}  // namespace locus::dsp
