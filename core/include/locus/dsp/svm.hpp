// Linear support vector machine inference: binary (sign of w·x + b) and multi-class one-vs-rest
// (argmax over classes of w_c·x + b_c), with optional feature standardisation ((x - mean) / scale,
// as LocBLE standardises its 9 RSS features before its linear SVM, paper 003 Sec. 3). Weights
// typically come from a model trained offline (e.g. scikit-learn's LinearSVC: coef_, intercept_).
// A small Pegasos trainer (primal stochastic sub-gradient on the hinge loss) is included for tests
// and quick experiments.
#pragma once

#include <Eigen/Core>
#include <cstdint>

namespace locus::dsp {

class LinearSvm {
 public:
  /// [main] weights: classes x features (1 row = binary), bias: classes. Throws
  /// std::invalid_argument on inconsistent sizes or non-finite values.
  LinearSvm(Eigen::MatrixXd weights, Eigen::VectorXd bias);
  /// [main] Adds standardisation: x' = (x - mean) / scale (scale > 0 everywhere).
  void set_standardization(Eigen::VectorXd mean, Eigen::VectorXd scale);

  /// Decision values w_c·x' + b_c (one per class row) into `out` (sized classes()) [RT if `out` is
  /// preallocated].
  void decision(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> out) const noexcept;
  /// Binary models: 1 if w·x' + b > 0 else 0. Multi-class: the index of the largest decision value.
  int predict(const Eigen::Ref<const Eigen::VectorXd>& x) const noexcept;

  Eigen::Index classes() const noexcept { return w_.rows(); }
  Eigen::Index features() const noexcept { return w_.cols(); }
  const Eigen::MatrixXd& weights() const noexcept { return w_; }
  const Eigen::VectorXd& bias() const noexcept { return b_; }

 private:
  Eigen::MatrixXd w_;
  Eigen::VectorXd b_, mean_, inv_scale_;
};

struct PegasosOptions {
  double lambda = 1e-3;   ///< L2 regularisation
  int epochs = 50;
  std::uint64_t seed = 1;
};

/// [main] Trains a linear SVM. labels: 0..C-1 (C = 2 gives a binary model with one row; C > 2 gives
/// one-vs-rest rows). Features are used as given (standardise them first if their scales differ).
/// Throws std::invalid_argument on empty data, mismatched sizes or labels out of range.
LinearSvm train_linear_svm(const Eigen::MatrixXd& samples, const Eigen::VectorXi& labels, int classes,
                           const PegasosOptions& options = {});

}  // namespace locus::dsp
