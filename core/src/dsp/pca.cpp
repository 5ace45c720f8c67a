// PCA via Eigen's self-adjoint eigen-solver on the covariance (see pca.hpp).
#include "locus/dsp/pca.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace locus::dsp {

void Pca::fit(const Eigen::MatrixXd& samples) {
  if (samples.rows() < 2 || samples.cols() < 1)
    throw std::invalid_argument("Pca::fit: need at least 2 samples (rows) of at least 1 dimension, got " +
                                std::to_string(samples.rows()) + "x" + std::to_string(samples.cols()));
  if (!samples.allFinite()) throw std::invalid_argument("Pca::fit: samples contain NaN or infinity");
  mean_ = samples.colwise().mean().transpose();
  const Eigen::MatrixXd centered = samples.rowwise() - mean_.transpose();
  const Eigen::MatrixXd cov = (centered.transpose() * centered) / static_cast<double>(samples.rows() - 1);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
  const Eigen::Index d = cov.rows();
  components_.resize(d, d);
  variance_.resize(d);
  for (Eigen::Index k = 0; k < d; ++k) {  // eigenvalues come increasing: reverse
    Eigen::VectorXd v = es.eigenvectors().col(d - 1 - k);
    Eigen::Index imax = 0;
    v.cwiseAbs().maxCoeff(&imax);
    if (v[imax] < 0) v = -v;
    components_.col(k) = v;
    variance_[k] = std::max(0.0, es.eigenvalues()[d - 1 - k]);
  }
}

Eigen::VectorXd Pca::explained_variance_ratio() const {
  const double total = variance_.sum();
  if (total <= 0) return Eigen::VectorXd::Zero(variance_.size());
  return variance_ / total;
}

Eigen::MatrixXd Pca::transform(const Eigen::MatrixXd& samples, Eigen::Index k) const {
  if (samples.cols() != mean_.size())
    throw std::invalid_argument("Pca::transform: expected " + std::to_string(mean_.size()) + " columns, got " +
                                std::to_string(samples.cols()));
  if (k <= 0 || k > components_.cols()) k = components_.cols();
  return (samples.rowwise() - mean_.transpose()) * components_.leftCols(k);
}

Eigen::MatrixXd Pca::inverse_transform(const Eigen::MatrixXd& scores) const {
  if (scores.cols() > components_.cols())
    throw std::invalid_argument("Pca::inverse_transform: too many score columns");
  Eigen::MatrixXd out = scores * components_.leftCols(scores.cols()).transpose();
  out.rowwise() += mean_.transpose();
  return out;
}

PrincipalAxis2d principal_axis_2d(const double* x, const double* y, std::size_t n) noexcept {
  PrincipalAxis2d r;
  if (n < 2) return r;
  double mx = 0, my = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mx += x[i];
    my += y[i];
  }
  mx /= static_cast<double>(n);
  my /= static_cast<double>(n);
  double sxx = 0, syy = 0, sxy = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dx = x[i] - mx, dy = y[i] - my;
    sxx += dx * dx;
    syy += dy * dy;
    sxy += dx * dy;
  }
  const double inv = 1.0 / static_cast<double>(n - 1);
  sxx *= inv;
  syy *= inv;
  sxy *= inv;
  // Eigen-decomposition of [[sxx, sxy], [sxy, syy]].
  const double half_tr = 0.5 * (sxx + syy);
  const double disc = std::sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy);
  r.variance_major = half_tr + disc;
  r.variance_minor = std::max(0.0, half_tr - disc);
  double a = 0.5 * std::atan2(2.0 * sxy, sxx - syy);  // in (-pi/2, pi/2]
  if (a <= -std::numbers::pi / 2) a += std::numbers::pi;
  r.angle_rad = a;
  return r;
}

}  // namespace locus::dsp
