// Gaussian mixture model with full covariances, fitted by expectation-maximisation.
//
// Initialisation: k-means++ seeding (deterministic for a seed), a few Lloyd iterations, then EM
// until the mean log-likelihood improves by less than `tolerance` or `max_iterations` is reached.
// `reg_covar` is added to every covariance diagonal (keeps components of few or collinear points
// invertible), as scikit-learn's GaussianMixture does. Fitting allocates [main]; predict() and
// log_likelihood() of one sample allocate nothing for fixed-size callers (they work on the stored
// Cholesky factors) but take Eigen::VectorXd, so treat them as [main] unless the vectors are preallocated.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace locus::dsp {

struct GmmOptions {
  int components = 2;
  int max_iterations = 200;
  double tolerance = 1e-6;   ///< on the mean per-sample log-likelihood
  double reg_covar = 1e-6;   ///< added to covariance diagonals
  std::uint64_t seed = 1;
};

class Gmm {
 public:
  /// [main] Fits on `samples` (one row per observation). Throws std::invalid_argument when there are
  /// fewer samples than components, non-finite values or a bad option. Returns the number of EM
  /// iterations run.
  int fit(const Eigen::MatrixXd& samples, const GmmOptions& options = {});

  /// Sets the model directly (weights sum to 1, covariances symmetric positive definite); throws
  /// std::invalid_argument otherwise.
  void set(std::vector<double> weights, std::vector<Eigen::VectorXd> means, std::vector<Eigen::MatrixXd> covariances);

  /// log p(x) under the mixture.
  double log_likelihood(const Eigen::VectorXd& x) const;
  /// Mean log p over the rows of `samples`.
  double score(const Eigen::MatrixXd& samples) const;
  /// Index of the component of highest posterior probability.
  int predict(const Eigen::VectorXd& x) const;
  /// Posterior probabilities of each component (sums to 1).
  Eigen::VectorXd posterior(const Eigen::VectorXd& x) const;

  int components() const noexcept { return static_cast<int>(weights_.size()); }
  const std::vector<double>& weights() const noexcept { return weights_; }
  const std::vector<Eigen::VectorXd>& means() const noexcept { return means_; }
  const std::vector<Eigen::MatrixXd>& covariances() const noexcept { return covs_; }
  /// Mean log-likelihood after each EM iteration of the last fit (non-decreasing up to rounding).
  const std::vector<double>& history() const noexcept { return history_; }

 private:
  void factorize();
  /// log(w_k) + log N(x; mu_k, Sigma_k) for every k into `out`.
  void component_log_densities(const Eigen::VectorXd& x, Eigen::VectorXd& out) const;

  std::vector<double> weights_;
  std::vector<Eigen::VectorXd> means_;
  std::vector<Eigen::MatrixXd> covs_;
  std::vector<Eigen::LLT<Eigen::MatrixXd>> llts_;
  std::vector<double> log_norm_;  // -0.5 (d log 2pi + log det Sigma_k)
  std::vector<double> history_;
};

}  // namespace locus::dsp
