// TUM's continuous localization (paper Sec. V-B, Sec. VIII outlier rule): one particle filter per
// located device, in device 1's body frame.
//
// State: the device's body origin (the paper's six-tuple keeps the attitude too; here the attitude is
// the `attitude` detector's at each exchange, already inside the constraints, Eq. 14's second factor).
// Propagation (Eq. 15): a device the IMU reports still gets a millimetre random walk; a moving one a
// random walk of `moving_speed_mps` * dt per axis (no IMU displacement is integrated: see docs/tum.md).
// Weights (Eq. 13, 16): the exchange's own constraint residuals at each particle (the clock-offset
// nuisance profiled out), Gaussian in the whitened residuals rather than Eq. 16's 1/sum|delta d|, so
// that every root of the static solution keeps its particles until motion removes the ambiguity.
// Outliers (Sec. VIII): a fix whose best root is farther from the track than `outlier_jump_m` plus the
// motion allowed since the last exchange is excluded (predict only) and flagged.
// Systematic resampling when the effective sample size drops below half, with a small roughening.
#pragma once

#include <random>

#include <Eigen/Dense>
#include <optional>

#include "locus/dsp/particle_filter.hpp"
#include "solver.hpp"

namespace locus::plugins::tum {

struct TrackerConfig {
  bool filter = true;              ///< false: pass the static fix through
  int particles = 200;
  double outlier_jump_m = 0.3;
  double moving_speed_mps = 0.5;   ///< 1-sigma speed of a moving device's random walk
  double still_step_m = 0.002;     ///< 1-sigma random walk per exchange of a still device
  double std_floor_m = 0.0;        ///< added (in quadrature) to the reported std
};

struct TrackOutput {
  bool ok = false;
  bool outlier = false;            ///< this exchange's fix was excluded (Sec. VIII)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double confidence = 0.0;
};

/// Log-likelihood of `x` (a candidate origin) under a placement's equations: -0.5 * the whitened
/// residual sum, with the clock offset rho at its best value for x.
double constraint_log_likelihood(const std::vector<dsp::RangeEquation>& eqs, const Eigen::Vector3d& x);

class Tracker {
 public:
  Tracker(const TrackerConfig& cfg, std::uint64_t seed);
  /// The track's current position, when it has one (steers the static solver's choice of root).
  std::optional<Eigen::Vector3d> prior() const;
  /// One exchange's placement of this device at time t (device 1's clock); `moving` from its IMU.
  TrackOutput update(const Placement& p, bool moving, double t_s);
  /// One fix given as a Gaussian (the network solve's position and covariance).
  TrackOutput update_gaussian(const Eigen::Vector3d& x, const Eigen::Matrix3d& cov, bool moving, double t_s);
  const dsp::ParticleFilter<Eigen::Vector3d>& filter() const { return pf_; }

 private:
  TrackOutput summary(bool outlier) const;
  /// After a weight update: resample (and roughen by `rough` m) when the effective sample size has
  /// fallen below half, then the summary; n01 is the caller's draw stream.
  TrackOutput settle(double rough, std::normal_distribution<double>& n01);
  TrackerConfig cfg_;
  dsp::ParticleFilter<Eigen::Vector3d> pf_;
  bool initialised_ = false;
  double last_t_ = 0.0;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
  int consecutive_outliers_ = 0;
};

}  // namespace locus::plugins::tum
