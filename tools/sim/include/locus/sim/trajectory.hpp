// Trajectories: the true pose (position + attitude) of a simulated object as a function of TRUE time.
//
// Everything the simulator renders is derived from these: acoustic delays (per sample, so motion
// produces Doppler by itself), IMU readings (derivatives), BLE distances and truth.csv. Frames follow
// the scene format: world right-handed, metres, z up; the attitude quaternion rotates body vectors
// into the world frame (body frame: Android convention, x right, y up the screen, z out of it).
//
// Implementations must be pure functions of t (thread-compatible, no hidden state), defined for every
// real t (hold the first/last pose outside their range), and smooth enough to differentiate twice
// where the IMU is synthesised from them (the default derivatives are central differences).
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Geometry>

namespace locus::sim {

struct Pose {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond attitude = Eigen::Quaterniond::Identity();  ///< body -> world
  /// World position of a point given in the body frame.
  Eigen::Vector3d to_world(const Eigen::Vector3d& body_point_m) const { return position_m + attitude * body_point_m; }
};

class Trajectory {
 public:
  virtual ~Trajectory() = default;
  /// Pose at true time t.
  virtual Pose pose(double t_true_s) const = 0;
  /// True when pose() does not depend on t (lets the renderer use constant delays).
  virtual bool is_static() const { return false; }

  /// World velocity (m/s). Default: central difference with step h.
  virtual Eigen::Vector3d velocity(double t_true_s) const;
  /// World acceleration (m/s^2), gravity NOT included. Default: second central difference.
  virtual Eigen::Vector3d acceleration(double t_true_s) const;
  /// Angular velocity in the BODY frame (rad/s), what a gyroscope reads. Default: from
  /// q(t−h)^−1·q(t+h).
  virtual Eigen::Vector3d angular_velocity_body(double t_true_s) const;
  /// Upper bound of the speed (m/s) used to size render windows; 0 for static objects.
  virtual double max_speed_mps() const { return is_static() ? 0.0 : 10.0; }

  /// Differentiation step of the default derivatives (s).
  static constexpr double kDiffStep_s = 1e-3;
};

/// A pose that never changes.
class StaticTrajectory final : public Trajectory {
 public:
  explicit StaticTrajectory(Pose pose) : pose_(std::move(pose)) {}
  StaticTrajectory(const Eigen::Vector3d& position_m, const Eigen::Quaterniond& attitude = Eigen::Quaterniond::Identity())
      : pose_{position_m, attitude.normalized()} {}
  Pose pose(double) const override { return pose_; }
  bool is_static() const override { return true; }
  Eigen::Vector3d velocity(double) const override { return Eigen::Vector3d::Zero(); }
  Eigen::Vector3d acceleration(double) const override { return Eigen::Vector3d::Zero(); }
  Eigen::Vector3d angular_velocity_body(double) const override { return Eigen::Vector3d::Zero(); }

 private:
  Pose pose_;
};

/// Poses sampled at increasing times: position by centripetal-free Catmull-Rom cubic (C1, passes
/// through the samples), attitude by slerp. Holds the end poses outside [t.front(), t.back()].
class SampledTrajectory final : public Trajectory {
 public:
  /// Throws std::invalid_argument if sizes differ, t is empty or not strictly increasing.
  SampledTrajectory(std::vector<double> t_s, std::vector<Pose> poses);
  Pose pose(double t_true_s) const override;
  bool is_static() const override { return poses_.size() == 1; }
  double max_speed_mps() const override { return max_speed_; }
  const std::vector<double>& times() const noexcept { return t_; }
  const std::vector<Pose>& poses() const noexcept { return poses_; }

 private:
  std::vector<double> t_;
  std::vector<Pose> poses_;
  double max_speed_ = 0.0;
};

/// A closed-form trajectory (ellipse, circle, min-jerk stroke...). `max_speed_mps` bounds |v|.
class FunctionTrajectory final : public Trajectory {
 public:
  using Fn = std::function<Pose(double)>;
  FunctionTrajectory(Fn fn, double max_speed_mps) : fn_(std::move(fn)), max_speed_(max_speed_mps) {}
  Pose pose(double t_true_s) const override { return fn_(t_true_s); }
  double max_speed_mps() const override { return max_speed_; }

 private:
  Fn fn_;
  double max_speed_;
};

/// Attitude of a device lying flat (screen up, body z = world z) whose body y axis (top of the
/// screen) points along the horizontal direction `heading_xy` (need not be unit).
Eigen::Quaterniond flat_attitude(const Eigen::Vector2d& heading_xy);

/// Minimum-jerk interpolation weight s(u) = 10u^3 − 15u^4 + 6u^5 for u in [0,1] (clamped), and its
/// first two derivatives with respect to u.
double min_jerk(double u) noexcept;
double min_jerk_d1(double u) noexcept;
double min_jerk_d2(double u) noexcept;

}  // namespace locus::sim
