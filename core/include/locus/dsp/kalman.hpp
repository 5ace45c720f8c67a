// Linear Kalman filter over Eigen matrices: fixed sizes (N states, M measurements, U controls known
// at compile time: everything on the stack) or Eigen::Dynamic sizes given to the constructor (all
// storage, including the workspace of predict/update, allocated there once).
//
//   x' = F x + B u + w,  w ~ N(0, Q)        z = H x + v,  v ~ N(0, R)
//
// update() uses the Joseph form of the covariance update (symmetric and positive semi-definite even
// with rounding) and a Cholesky (LLT) solve of the innovation covariance. predict()/update() never
// allocate for either kind of size [RT] (tests/core/dsp_estimation checks it with Eigen's malloc
// guard). Fill F, H, Q, R (and B) directly; they are public.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <limits>

namespace locus::dsp {

template <int N, int M, int U = 1, typename Scalar = double>
class KalmanFilter {
 public:
  using StateVec = Eigen::Matrix<Scalar, N, 1>;
  using MeasVec = Eigen::Matrix<Scalar, M, 1>;
  using CtrlVec = Eigen::Matrix<Scalar, U, 1>;
  using StateMat = Eigen::Matrix<Scalar, N, N>;
  using MeasMat = Eigen::Matrix<Scalar, M, M>;
  using ObsMat = Eigen::Matrix<Scalar, M, N>;
  using GainMat = Eigen::Matrix<Scalar, N, M>;
  using CtrlMat = Eigen::Matrix<Scalar, N, U>;

  /// [main] Sizes are ignored for fixed dimensions and required for dynamic ones. F = I, H = 0,
  /// Q = 0, R = I, B = 0, x = 0, P = I.
  explicit KalmanFilter(Eigen::Index n = (N > 0 ? N : 0), Eigen::Index m = (M > 0 ? M : 0),
                        Eigen::Index u = (U > 0 ? U : 0))
      : x(n), P(n, n), F(n, n), Q(n, n), H(m, n), R(m, m), B(n, u),
        y_(m), ysolved_(m), S_(m, m), K_(n, m), HP_(m, n), tmpN_(n, n), tmpN2_(n, n), ikh_(n, n), KR_(n, m), llt_(m) {
    x.setZero();
    P.setIdentity();
    F.setIdentity();
    Q.setZero();
    H.setZero();
    R.setIdentity();
    B.setZero();
    S_.setZero();
  }

  /// [RT] x = F x; P = F P F^T + Q.
  void predict() noexcept {
    tmpN2_.col(0).noalias() = F * x;  // reuse a column as the temporary state
    x = tmpN2_.col(0);
    propagate_covariance();
  }

  /// [RT] x = F x + B u; P = F P F^T + Q.
  void predict(const CtrlVec& u) noexcept {
    tmpN2_.col(0).noalias() = F * x;
    tmpN2_.col(0).noalias() += B * u;
    x = tmpN2_.col(0);
    propagate_covariance();
  }

  /// [RT] Measurement update. Returns false (and leaves x, P unchanged) when the innovation
  /// covariance is not positive definite.
  bool update(const MeasVec& z) noexcept {
    y_ = z;
    y_.noalias() -= H * x;
    HP_.noalias() = H * P;
    S_ = R;
    S_.noalias() += HP_ * H.transpose();
    llt_.compute(S_);
    if (llt_.info() != Eigen::Success) return false;
    // K = P H^T S^-1  <=>  K^T = S^-1 (H P) (P symmetric); solve in place on HP_.
    llt_.solveInPlace(HP_);
    K_ = HP_.transpose();
    x.noalias() += K_ * y_;
    // Joseph form: P = (I - K H) P (I - K H)^T + K R K^T.
    ikh_.setIdentity();
    ikh_.noalias() -= K_ * H;
    tmpN_.noalias() = ikh_ * P;
    P.noalias() = tmpN_ * ikh_.transpose();
    KR_.noalias() = K_ * R;
    P.noalias() += KR_ * K_.transpose();
    // Innovation statistics for the caller (NIS): y^T S^-1 y with the factor already computed.
    ysolved_ = y_;
    llt_.solveInPlace(ysolved_);
    nis_ = y_.dot(ysolved_);
    return true;
  }

  /// Innovation of the last update (z - H x before the update).
  const MeasVec& innovation() const noexcept { return y_; }
  /// Innovation covariance of the last update.
  const MeasMat& innovation_covariance() const noexcept { return S_; }
  /// Normalised innovation squared of the last update (chi-square with M dof when consistent).
  Scalar nis() const noexcept { return nis_; }
  /// Gain of the last update.
  const GainMat& gain() const noexcept { return K_; }

  StateVec x;
  StateMat P;
  StateMat F;
  StateMat Q;
  ObsMat H;
  MeasMat R;
  CtrlMat B;

 private:
  void propagate_covariance() noexcept {
    tmpN_.noalias() = F * P;
    P.noalias() = tmpN_ * F.transpose();
    P += Q;
  }

  MeasVec y_, ysolved_;
  MeasMat S_;
  GainMat K_;
  ObsMat HP_;
  StateMat tmpN_, tmpN2_, ikh_;
  GainMat KR_;
  Eigen::LLT<MeasMat> llt_;
  Scalar nis_ = std::numeric_limits<Scalar>::quiet_NaN();
};

/// A filter whose sizes are chosen at run time.
using DynamicKalmanFilter = KalmanFilter<Eigen::Dynamic, Eigen::Dynamic, Eigen::Dynamic>;

}  // namespace locus::dsp
