// A generic sequential-importance-resampling particle filter with systematic resampling.
//
// The particle count is fixed at construction; particles, weights and the resampling scratch are
// allocated there once, so predict/update/resample never allocate [RT] (as long as the user's State
// copy does not). The model is supplied per call as callables, so one filter type serves every
// localizer (TUM's relative positions, SpyLoc's walking position, ...):
//
//   ParticleFilter<Pose> pf(2000, seed);
//   pf.initialize([&](Pose& p, Rng& rng) { ... draw from the prior ... });
//   pf.predict([&](Pose& p, Rng& rng) { ... motion model with noise ... });
//   pf.update([&](const Pose& p) { return log_likelihood(z, p); });
//   if (pf.effective_sample_size() < 0.5 * pf.size()) pf.resample();
//
// Weights are kept normalised in the linear domain; update() takes log-likelihoods and subtracts
// their maximum before exponentiating, so very unlikely measurements do not underflow to all-zero.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

namespace locus::dsp {

template <typename State>
class ParticleFilter {
 public:
  using Rng = std::mt19937_64;

  /// [main] `count` >= 1 particles (default-constructed State), uniform weights.
  explicit ParticleFilter(std::size_t count, std::uint64_t seed = 1)
      : particles_(count), scratch_(count), weights_(count, count ? 1.0 / static_cast<double>(count) : 0.0),
        logw_(count), rng_(seed) {
    if (count == 0) throw std::invalid_argument("ParticleFilter: count must be >= 1");
  }

  std::size_t size() const noexcept { return particles_.size(); }
  std::vector<State>& particles() noexcept { return particles_; }
  const std::vector<State>& particles() const noexcept { return particles_; }
  const std::vector<double>& weights() const noexcept { return weights_; }
  Rng& rng() noexcept { return rng_; }

  /// [RT] init(State&, Rng&) for every particle; weights uniform.
  template <typename Init>
  void initialize(Init&& init) {
    for (State& p : particles_) init(p, rng_);
    std::fill(weights_.begin(), weights_.end(), 1.0 / static_cast<double>(size()));
  }

  /// [RT] Propagates every particle: motion(State&, Rng&).
  template <typename Motion>
  void predict(Motion&& motion) {
    for (State& p : particles_) motion(p, rng_);
  }

  /// [RT] Multiplies each weight by exp(log_likelihood(const State&)) and renormalises. Returns
  /// false (and resets to uniform weights) when every likelihood is zero or not finite: the
  /// measurement is inconsistent with every particle.
  template <typename LogLik>
  bool update(LogLik&& log_likelihood) {
    double max_l = -std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < size(); ++i) {
      const double w = weights_[i];
      const double l = w > 0 ? log_likelihood(static_cast<const State&>(particles_[i])) + std::log(w)
                             : -std::numeric_limits<double>::infinity();
      logw_[i] = std::isnan(l) ? -std::numeric_limits<double>::infinity() : l;
      max_l = std::max(max_l, logw_[i]);
    }
    if (!std::isfinite(max_l)) {
      std::fill(weights_.begin(), weights_.end(), 1.0 / static_cast<double>(size()));
      return false;
    }
    double sum = 0.0;
    for (std::size_t i = 0; i < size(); ++i) sum += (weights_[i] = std::exp(logw_[i] - max_l));
    for (double& w : weights_) w /= sum;
    return true;
  }

  /// 1 / sum(w^2): size() for uniform weights, 1 when one particle holds all the weight.
  double effective_sample_size() const noexcept {
    double s = 0.0;
    for (double w : weights_) s += w * w;
    return s > 0 ? 1.0 / s : 0.0;
  }

  /// [RT] Systematic resampling: one uniform offset u ~ U[0, 1/N), pointers u + k/N through the
  /// cumulative weights. Particle i is copied floor(N w_i) or ceil(N w_i) times. Weights uniform.
  void resample() {
    const std::size_t n = size();
    const double step = 1.0 / static_cast<double>(n);
    std::uniform_real_distribution<double> uni(0.0, step);
    double u = uni(rng_);
    double cum = weights_[0];
    std::size_t i = 0;
    for (std::size_t k = 0; k < n; ++k) {
      while (u > cum && i + 1 < n) cum += weights_[++i];
      scratch_[k] = particles_[i];
      u += step;
    }
    particles_.swap(scratch_);
    std::fill(weights_.begin(), weights_.end(), step);
  }

  /// Weighted mean of value(const State&) (any type with + and scalar *), e.g. a position.
  template <typename Value, typename Fn>
  Value mean(Fn&& value, Value zero) const {
    Value acc = zero;
    for (std::size_t i = 0; i < size(); ++i) acc = acc + weights_[i] * value(particles_[i]);
    return acc;
  }

  /// The particle of largest weight.
  const State& best() const noexcept {
    return particles_[static_cast<std::size_t>(std::max_element(weights_.begin(), weights_.end()) - weights_.begin())];
  }

 private:
  std::vector<State> particles_, scratch_;
  std::vector<double> weights_, logw_;
  Rng rng_;
};

}  // namespace locus::dsp
