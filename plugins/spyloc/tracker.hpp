// SpyLoc tracker: dead reckoning between beeps, each LoS range a correction (paper 001, §VI).
//
// Why an extended Kalman filter on [x, y, vx, vy]: the paper dead-reckons with steps and heading and
// recalibrates with every single LoS range (§VI "single-range calibration": one range fixes the
// position along its direction, the motion model carries the rest). A constant-velocity EKF does
// exactly that with one range at a time, and keeps a covariance, so the estimate's std_m follows from
// the same model (scaled by std_scale, measured on scenes). Step events (the `steps` detector)
// add a speed observation |v| = stride·f when present; a pause (no step for pause_s) pulls the speed
// to zero.
// Robustness: each range is gated on its normalised innovation (gate_sigma; gate_long_sigma for a
// range longer than predicted: NLoS paths are only ever longer); ranges the classifier calls NLoS
// never reach the filter.
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

namespace locus::plugins::spyloc {

/// What a track predicts for a range before it is measured: the slant range from the track's position
/// and its variance (the position covariance along the line of sight; add the range's own variance
/// for the innovation's).
struct RangePrediction {
  double range_m = 0.0;
  double var_m2 = 0.0;
};

struct TrackerConfig {
  double accel_std_mps2 = 1.0;  ///< white acceleration of the constant-velocity model
  double max_speed_mps = 2.5;
  double gate_sigma = 4.0;
  /// Gate on ranges LONGER than predicted (an NLoS path is never shorter than the direct one, so a
  /// missed NLoS beep is a positive outlier). 2.5 vs 4 (= gate_sigma): p90 better on 10 of 12
  /// simulated seeds (101-112; median of p90 2.5 vs 4.3 m) and on spyloc-104 (4.8 vs 5.4 m).
  double gate_long_sigma = 2.5;
  /// As PdrConfig::huber_sigma; 0 (off) in the plugin: with dead_reckoning false, 2 made seeds 101-120
  /// worse (pooled p90 0.82 -> 0.93 m; spyloc-104 6.98 -> 3.46 m): a constant-velocity track needs
  /// its ranges to pull hard.
  double huber_sigma = 0.0;
};

class Tracker {
 public:
  explicit Tracker(TrackerConfig cfg = {}) : cfg_(cfg) {}
  /// Starts at a fix with its covariance (xx, xy, yy), speed unknown.
  void init(double t_s, const std::array<double, 2>& xy, const std::array<double, 3>& cov, double speed_std_mps);
  bool initialised() const noexcept { return init_; }
  void predict(double t_s);
  /// Range update (slant range to `beacon` with the device at height z). Returns false when gated out
  /// (the filter is unchanged); `nis` receives the normalised innovation squared.
  bool update_range(const std::array<double, 3>& beacon, double z_m, double range_m, double std_m, double& nis);
  /// The range to `beacon` this track predicts now (no update).
  RangePrediction predict_range(const std::array<double, 3>& beacon, double z_m) const;
  /// Widens the covariance (lost track: ranges keep disagreeing): position ± pos_std, velocity ± vel_std.
  void inflate(double pos_std_m, double vel_std_mps);
  /// Speed observation (steps): |v| = speed ± std.
  void update_speed(double speed_mps, double std_mps);
  std::array<double, 2> position() const { return {x_(0), x_(1)}; }
  std::array<double, 2> velocity() const { return {x_(2), x_(3)}; }
  /// sqrt of the position covariance trace.
  double position_std() const;
  /// Position covariance (xx, xy, yy).
  std::array<double, 3> position_cov() const { return {P_(0, 0), P_(0, 1), P_(1, 1)}; }
  double t_s() const noexcept { return t_; }

 private:
  TrackerConfig cfg_;
  bool init_ = false;
  double t_ = 0.0;
  Eigen::Vector4d x_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d P_ = Eigen::Matrix4d::Identity();
};

/// Pedestrian dead-reckoning tracker (the paper's §VI motion model): the walker moves only by its
/// steps. State [x, y, ψ, k]: position, the rotation ψ from the dead-reckoning frame (relative
/// heading of the phone, core/dsp/dead_reckoning.hpp) to the world, and the stride scale k (the step
/// detector's stride model vs this walker). A step's displacement d (dead-reckoning frame) moves the
/// walker by k·R(ψ)·d; each LoS range corrects position, ψ and k together (the paper's "step model
/// fitted from ranging"). Standing still, the position holds: no constant-velocity drift.
struct PdrConfig {
  double stride_std_frac = 0.08;  ///< per-step stride error (fraction of the stride)
  double heading_std_rad = 0.06;  ///< per-step direction error (sway, trunk rotation)
  double psi_walk_rad = 0.01;     ///< per-step random walk of ψ (gyro drift, phone re-gripped)
  double k_walk = 0.004;          ///< per-step random walk of k
  /// Bound (sigmas) of a range update that passes the gate: an innovation ν beyond it is taken with
  /// the variance that puts it at huber_sigma sigmas (S → ν²/huber_sigma²), so it moves the state
  /// (huber_sigma² / NIS) as far as the plain update; the hypothesis' likelihood still counts the
  /// whole innovation. 0 = off (the plugin's default: 2).
  double huber_sigma = 0.0;
  double gate_sigma = 4.0;
  double gate_long_sigma = 2.5;
};

class PdrTracker {
 public:
  explicit PdrTracker(PdrConfig cfg = {}) : cfg_(cfg) {}
  /// Starts at xy (covariance xx, xy, yy) with ψ ± psi_std and k ± k_std.
  void init(const std::array<double, 2>& xy, const std::array<double, 3>& cov, double psi_rad, double psi_std_rad,
            double k, double k_std);
  /// A new position (a fix after the track was lost); ψ and k stay, their variances widened.
  void reset_position(const std::array<double, 2>& xy, const std::array<double, 3>& cov, double psi_widen_rad);
  bool initialised() const noexcept { return init_; }
  /// Moves by the dead-reckoning displacement d_m (x, y in the dead-reckoning frame).
  void step(const std::array<double, 2>& d_m);
  /// As Tracker::update_range.
  bool update_range(const std::array<double, 3>& beacon, double z_m, double range_m, double std_m, double& nis);
  /// As Tracker::predict_range.
  RangePrediction predict_range(const std::array<double, 3>& beacon, double z_m) const;
  std::array<double, 2> position() const { return {x_(0), x_(1)}; }
  double position_std() const;
  double psi_rad() const { return x_(2); }
  double psi_std_rad() const;
  double stride_scale() const { return x_(3); }
  double stride_scale_std() const;
  /// Innovation variance of the last update_range() call (m²).
  double last_innovation_var() const { return last_S_; }

 private:
  PdrConfig cfg_;
  double last_S_ = 1.0;
  bool init_ = false;
  Eigen::Vector4d x_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d P_ = Eigen::Matrix4d::Identity();
};

/// Rotation ψ and scale k that map the dead-reckoning path onto the tracked one (2-D Procrustes on
/// centred point sets, least squares): track − mean ≈ k·R(ψ)·(dr − mean). `spread_m` = rms distance
/// of the dead-reckoning points from their mean; `rms_m` = the fit's rms residual.
struct Alignment {
  double psi_rad = 0.0, k = 1.0, spread_m = 0.0, rms_m = 0.0;
};
Alignment align_paths(const std::vector<std::array<double, 2>>& dr, const std::vector<std::array<double, 2>>& track);

}  // namespace locus::plugins::spyloc
