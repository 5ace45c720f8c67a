// Gaussian mixture EM (see gmm.hpp).
#include "locus/dsp/gmm.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>

namespace locus::dsp {

namespace {

double log_sum_exp(const Eigen::VectorXd& v) {
  const double m = v.maxCoeff();
  if (!std::isfinite(m)) return m;
  return m + std::log((v.array() - m).exp().sum());
}

}  // namespace

void Gmm::factorize() {
  const std::size_t k = weights_.size();
  llts_.clear();
  log_norm_.assign(k, 0.0);
  for (std::size_t c = 0; c < k; ++c) {
    llts_.emplace_back(covs_[c]);
    if (llts_.back().info() != Eigen::Success)
      throw std::invalid_argument("Gmm: covariance of component " + std::to_string(c) + " is not positive definite");
    const Eigen::MatrixXd& l = llts_.back().matrixLLT();
    double logdet = 0.0;
    for (Eigen::Index i = 0; i < l.rows(); ++i) logdet += 2.0 * std::log(l(i, i));
    log_norm_[c] = -0.5 * (static_cast<double>(covs_[c].rows()) * std::log(2.0 * std::numbers::pi) + logdet);
  }
}

void Gmm::set(std::vector<double> weights, std::vector<Eigen::VectorXd> means, std::vector<Eigen::MatrixXd> covariances) {
  if (weights.empty() || weights.size() != means.size() || weights.size() != covariances.size())
    throw std::invalid_argument("Gmm::set: weights, means and covariances must have the same non-zero count");
  double sum = 0.0;
  for (double w : weights) {
    if (!(w > 0.0)) throw std::invalid_argument("Gmm::set: weights must be > 0");
    sum += w;
  }
  if (std::abs(sum - 1.0) > 1e-9) throw std::invalid_argument("Gmm::set: weights must sum to 1, got " + std::to_string(sum));
  const Eigen::Index d = means[0].size();
  for (std::size_t c = 0; c < means.size(); ++c)
    if (means[c].size() != d || covariances[c].rows() != d || covariances[c].cols() != d)
      throw std::invalid_argument("Gmm::set: component " + std::to_string(c) + " has inconsistent dimensions");
  weights_ = std::move(weights);
  means_ = std::move(means);
  covs_ = std::move(covariances);
  factorize();
}

void Gmm::component_log_densities(const Eigen::VectorXd& x, Eigen::VectorXd& out) const {
  const std::size_t k = weights_.size();
  out.resize(static_cast<Eigen::Index>(k));
  for (std::size_t c = 0; c < k; ++c) {
    const Eigen::VectorXd diff = x - means_[c];
    const Eigen::VectorXd z = llts_[c].matrixL().solve(diff);
    out[static_cast<Eigen::Index>(c)] = std::log(weights_[c]) + log_norm_[c] - 0.5 * z.squaredNorm();
  }
}

double Gmm::log_likelihood(const Eigen::VectorXd& x) const {
  if (weights_.empty()) throw std::logic_error("Gmm: not fitted");
  if (x.size() != means_[0].size())
    throw std::invalid_argument("Gmm: sample has " + std::to_string(x.size()) + " dimensions, model " +
                                std::to_string(means_[0].size()));
  Eigen::VectorXd l;
  component_log_densities(x, l);
  return log_sum_exp(l);
}

double Gmm::score(const Eigen::MatrixXd& samples) const {
  double s = 0.0;
  for (Eigen::Index i = 0; i < samples.rows(); ++i) s += log_likelihood(samples.row(i).transpose());
  return samples.rows() > 0 ? s / static_cast<double>(samples.rows()) : 0.0;
}

Eigen::VectorXd Gmm::posterior(const Eigen::VectorXd& x) const {
  if (weights_.empty()) throw std::logic_error("Gmm: not fitted");
  Eigen::VectorXd l;
  component_log_densities(x, l);
  const double lse = log_sum_exp(l);
  return (l.array() - lse).exp();
}

int Gmm::predict(const Eigen::VectorXd& x) const {
  Eigen::VectorXd l;
  if (weights_.empty()) throw std::logic_error("Gmm: not fitted");
  component_log_densities(x, l);
  Eigen::Index best = 0;
  l.maxCoeff(&best);
  return static_cast<int>(best);
}

int Gmm::fit(const Eigen::MatrixXd& samples, const GmmOptions& opt) {
  const Eigen::Index n = samples.rows(), d = samples.cols();
  const int k = opt.components;
  if (k < 1) throw std::invalid_argument("Gmm::fit: components must be >= 1");
  if (d < 1) throw std::invalid_argument("Gmm::fit: samples have no columns");
  if (n < k) throw std::invalid_argument("Gmm::fit: " + std::to_string(n) + " samples for " + std::to_string(k) + " components");
  if (!samples.allFinite()) throw std::invalid_argument("Gmm::fit: samples contain NaN or infinity");
  if (opt.max_iterations < 1 || !(opt.reg_covar >= 0.0)) throw std::invalid_argument("Gmm::fit: bad options");

  // k-means++ seeding.
  std::mt19937_64 rng(opt.seed);
  std::vector<Eigen::VectorXd> centers;
  centers.push_back(samples.row(std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng)).transpose());
  Eigen::VectorXd d2(n);
  while (static_cast<int>(centers.size()) < k) {
    for (Eigen::Index i = 0; i < n; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (const auto& c : centers) best = std::min(best, (samples.row(i).transpose() - c).squaredNorm());
      d2[i] = best;
    }
    const double total = d2.sum();
    Eigen::Index pick = 0;
    if (total > 0) {
      double r = std::uniform_real_distribution<double>(0.0, total)(rng);
      for (pick = 0; pick < n - 1 && r > d2[pick]; ++pick) r -= d2[pick];
    } else {
      pick = std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng);
    }
    centers.push_back(samples.row(pick).transpose());
  }
  // Lloyd iterations.
  std::vector<int> label(static_cast<std::size_t>(n), 0);
  for (int it = 0; it < 10; ++it) {
    for (Eigen::Index i = 0; i < n; ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (int c = 0; c < k; ++c) {
        const double dd = (samples.row(i).transpose() - centers[static_cast<std::size_t>(c)]).squaredNorm();
        if (dd < best) {
          best = dd;
          label[static_cast<std::size_t>(i)] = c;
        }
      }
    }
    std::vector<Eigen::VectorXd> sums(static_cast<std::size_t>(k), Eigen::VectorXd::Zero(d));
    std::vector<int> counts(static_cast<std::size_t>(k), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      sums[static_cast<std::size_t>(label[static_cast<std::size_t>(i)])] += samples.row(i).transpose();
      ++counts[static_cast<std::size_t>(label[static_cast<std::size_t>(i)])];
    }
    for (int c = 0; c < k; ++c)
      if (counts[static_cast<std::size_t>(c)] > 0) centers[static_cast<std::size_t>(c)] = sums[static_cast<std::size_t>(c)] / counts[static_cast<std::size_t>(c)];
  }
  // Responsibilities from the hard labels, then EM.
  Eigen::MatrixXd resp = Eigen::MatrixXd::Zero(n, k);
  for (Eigen::Index i = 0; i < n; ++i) resp(i, label[static_cast<std::size_t>(i)]) = 1.0;

  weights_.assign(static_cast<std::size_t>(k), 1.0 / k);
  means_.assign(static_cast<std::size_t>(k), Eigen::VectorXd::Zero(d));
  covs_.assign(static_cast<std::size_t>(k), Eigen::MatrixXd::Identity(d, d));
  history_.clear();
  auto m_step = [&] {
    for (int c = 0; c < k; ++c) {
      const std::size_t cs = static_cast<std::size_t>(c);
      const double nk = resp.col(c).sum() + 10 * std::numeric_limits<double>::epsilon();
      weights_[cs] = nk / static_cast<double>(n);
      means_[cs] = (samples.transpose() * resp.col(c)) / nk;
      const Eigen::MatrixXd centered = samples.rowwise() - means_[cs].transpose();
      covs_[cs] = (centered.transpose() * resp.col(c).asDiagonal() * centered) / nk;
      covs_[cs].diagonal().array() += opt.reg_covar;
    }
    double s = 0.0;
    for (double w : weights_) s += w;
    for (double& w : weights_) w /= s;
    factorize();
  };
  m_step();
  double prev = -std::numeric_limits<double>::infinity();
  int it = 0;
  Eigen::VectorXd l;
  for (it = 1; it <= opt.max_iterations; ++it) {
    double total = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {  // E step
      component_log_densities(samples.row(i).transpose(), l);
      const double lse = log_sum_exp(l);
      total += lse;
      resp.row(i) = (l.array() - lse).exp().transpose();
    }
    const double mean_ll = total / static_cast<double>(n);
    history_.push_back(mean_ll);
    if (std::abs(mean_ll - prev) < opt.tolerance) break;
    prev = mean_ll;
    m_step();
  }
  return std::min(it, opt.max_iterations);
}

}  // namespace locus::dsp
