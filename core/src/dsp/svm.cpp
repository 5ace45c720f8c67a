// Linear SVM inference and Pegasos training (see svm.hpp).
#include "locus/dsp/svm.hpp"

#include <random>
#include <stdexcept>
#include <string>

namespace locus::dsp {

LinearSvm::LinearSvm(Eigen::MatrixXd weights, Eigen::VectorXd bias) : w_(std::move(weights)), b_(std::move(bias)) {
  if (w_.rows() < 1 || w_.cols() < 1) throw std::invalid_argument("LinearSvm: empty weight matrix");
  if (b_.size() != w_.rows())
    throw std::invalid_argument("LinearSvm: " + std::to_string(w_.rows()) + " weight rows but " +
                                std::to_string(b_.size()) + " biases");
  if (!w_.allFinite() || !b_.allFinite()) throw std::invalid_argument("LinearSvm: non-finite weight or bias");
  mean_ = Eigen::VectorXd::Zero(w_.cols());
  inv_scale_ = Eigen::VectorXd::Ones(w_.cols());
}

void LinearSvm::set_standardization(Eigen::VectorXd mean, Eigen::VectorXd scale) {
  if (mean.size() != w_.cols() || scale.size() != w_.cols())
    throw std::invalid_argument("LinearSvm: standardisation needs " + std::to_string(w_.cols()) + " values");
  if (!(scale.array() > 0).all() || !mean.allFinite() || !scale.allFinite())
    throw std::invalid_argument("LinearSvm: standardisation scales must be finite and > 0");
  mean_ = std::move(mean);
  inv_scale_ = scale.cwiseInverse();
}

void LinearSvm::decision(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> out) const noexcept {
  for (Eigen::Index c = 0; c < w_.rows(); ++c) {
    double s = b_[c];
    for (Eigen::Index f = 0; f < w_.cols(); ++f) s += w_(c, f) * (x[f] - mean_[f]) * inv_scale_[f];
    out[c] = s;
  }
}

int LinearSvm::predict(const Eigen::Ref<const Eigen::VectorXd>& x) const noexcept {
  int best = 0;
  double best_v = 0.0;
  for (Eigen::Index c = 0; c < w_.rows(); ++c) {
    double s = b_[c];
    for (Eigen::Index f = 0; f < w_.cols(); ++f) s += w_(c, f) * (x[f] - mean_[f]) * inv_scale_[f];
    if (w_.rows() == 1) return s > 0 ? 1 : 0;
    if (c == 0 || s > best_v) {
      best_v = s;
      best = static_cast<int>(c);
    }
  }
  return best;
}

namespace {

/// One binary Pegasos model for targets y in {-1, +1}; the bias is the weight of a constant feature
/// 1 appended to every sample (regularised like the others, the usual Pegasos extension).
void pegasos(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const PegasosOptions& opt, Eigen::Ref<Eigen::VectorXd> w,
             double& b) {
  const Eigen::Index n = x.rows();
  std::mt19937_64 rng(opt.seed);
  std::uniform_int_distribution<Eigen::Index> pick(0, n - 1);
  w.setZero();
  b = 0.0;
  Eigen::VectorXd w_avg = Eigen::VectorXd::Zero(w.size());
  double b_avg = 0.0;
  long t = 0;
  const long total = static_cast<long>(opt.epochs) * n;
  for (long s = 0; s < total; ++s) {
    ++t;
    const Eigen::Index i = pick(rng);
    const double eta = 1.0 / (opt.lambda * static_cast<double>(t));
    const double margin = y[i] * (x.row(i).dot(w) + b);
    w *= (1.0 - eta * opt.lambda);
    b *= (1.0 - eta * opt.lambda);
    if (margin < 1.0) {
      w += eta * y[i] * x.row(i).transpose();
      b += eta * y[i];
    }
    if (s >= total / 2) {  // average the second half of the iterates (more stable)
      w_avg += w;
      b_avg += b;
    }
  }
  const double count = static_cast<double>(total - total / 2);
  w = w_avg / count;
  b = b_avg / count;
}

}  // namespace

LinearSvm train_linear_svm(const Eigen::MatrixXd& samples, const Eigen::VectorXi& labels, int classes,
                           const PegasosOptions& options) {
  if (samples.rows() == 0 || samples.cols() == 0) throw std::invalid_argument("train_linear_svm: no samples");
  if (labels.size() != samples.rows())
    throw std::invalid_argument("train_linear_svm: " + std::to_string(samples.rows()) + " samples but " +
                                std::to_string(labels.size()) + " labels");
  if (classes < 2) throw std::invalid_argument("train_linear_svm: need at least 2 classes");
  if ((labels.array() < 0).any() || (labels.array() >= classes).any())
    throw std::invalid_argument("train_linear_svm: labels must be in 0.." + std::to_string(classes - 1));
  if (!(options.lambda > 0) || options.epochs < 1) throw std::invalid_argument("train_linear_svm: bad options");
  const Eigen::Index rows = classes == 2 ? 1 : classes;
  Eigen::MatrixXd w(rows, samples.cols());
  Eigen::VectorXd b(rows);
  for (Eigen::Index c = 0; c < rows; ++c) {
    const int positive = classes == 2 ? 1 : static_cast<int>(c);
    Eigen::VectorXd y(samples.rows());
    for (Eigen::Index i = 0; i < samples.rows(); ++i) y[i] = labels[i] == positive ? 1.0 : -1.0;
    Eigen::VectorXd wc(samples.cols());
    double bc = 0.0;
    PegasosOptions o = options;
    o.seed = options.seed + static_cast<std::uint64_t>(c);
    pegasos(samples, y, o, wc, bc);
    w.row(c) = wc.transpose();
    b[c] = bc;
  }
  return LinearSvm(std::move(w), std::move(b));
}

}  // namespace locus::dsp
