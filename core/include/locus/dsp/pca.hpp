// Principal component analysis: the eigen-decomposition of the sample covariance, components sorted
// by decreasing variance. SpyLoc (paper 001, Sec. IV) takes the first component of the horizontal
// world-frame acceleration over a window as the walking axis: principal_axis_2d() does that without
// allocating [RT].
#pragma once

#include <Eigen/Core>
#include <cstddef>

namespace locus::dsp {

class Pca {
 public:
  /// [main] Fits on `samples` (one row per observation, >= 2 rows). Throws std::invalid_argument
  /// when there are fewer than 2 rows or no columns.
  void fit(const Eigen::MatrixXd& samples);

  /// Column k = k-th principal axis (unit length, sign chosen so its largest |component| is > 0).
  const Eigen::MatrixXd& components() const noexcept { return components_; }
  /// Variance along each component (unbiased, n - 1), decreasing.
  const Eigen::VectorXd& explained_variance() const noexcept { return variance_; }
  /// Fraction of the total variance per component.
  Eigen::VectorXd explained_variance_ratio() const;
  const Eigen::VectorXd& mean() const noexcept { return mean_; }

  /// [main] Scores of `samples` on the first `k` components (k = 0: all).
  Eigen::MatrixXd transform(const Eigen::MatrixXd& samples, Eigen::Index k = 0) const;
  /// [main] Back-projection of scores to the original space.
  Eigen::MatrixXd inverse_transform(const Eigen::MatrixXd& scores) const;

 private:
  Eigen::VectorXd mean_;
  Eigen::MatrixXd components_;
  Eigen::VectorXd variance_;
};

/// The principal axis of 2-D points (x[i], y[i]), i < n, in closed form [RT].
struct PrincipalAxis2d {
  double angle_rad = 0.0;     ///< direction of the first axis from +x, in (-pi/2, pi/2]
  double variance_major = 0.0;
  double variance_minor = 0.0;
  /// variance_major / (variance_major + variance_minor): 0.5 = no preferred axis, 1 = a line.
  double linearity() const noexcept {
    const double t = variance_major + variance_minor;
    return t > 0 ? variance_major / t : 0.5;
  }
};
PrincipalAxis2d principal_axis_2d(const double* x, const double* y, std::size_t n) noexcept;

}  // namespace locus::dsp
