// Attitude and heading reference: Madgwick's gradient-descent filter and Mahony's complementary
// filter, from gyroscope + accelerometer, with the magnetometer when present.
//
// Conventions (docs/scene-format.md): the quaternion q = (w, x, y, z) rotates body vectors into the
// reference frame, v_ref = q ⊗ v_body ⊗ q*. The reference frame is right-handed with z up; an
// accelerometer at rest reads +g along the body direction that points up (specific force). Without
// a magnetometer yaw is relative to the attitude at reset (it drifts with the gyro bias); with one,
// the reference x axis points to magnetic north projected on the horizontal plane (y = west, as a
// right-handed z-up frame requires).
//
// Both filters are plain value types: update() never allocates [RT].
#pragma once

#include <Eigen/Geometry>

namespace locus::dsp {

/// Heading of the body y axis (Android: "up along the screen") in the reference frame: the angle of
/// its horizontal projection from the reference x axis, counter-clockwise about z, in (-pi, pi].
double heading_of(const Eigen::Quaterniond& q) noexcept;

/// Attitude from gravity alone: the shortest rotation taking the measured "up" (the accelerometer
/// direction at rest) to reference +z (a device lying flat, screen up, gives the identity).
Eigen::Quaterniond attitude_from_accel(const Eigen::Vector3d& accel) noexcept;

/// Attitude from gravity and the magnetic field (TRIAD): reference z = measured up, x = the
/// horizontal part of the field (magnetic north), y = z × x (west). Falls back to
/// attitude_from_accel when the field is zero or parallel to gravity.
Eigen::Quaterniond attitude_from_accel_mag(const Eigen::Vector3d& accel, const Eigen::Vector3d& mag) noexcept;

/// Madgwick, "An efficient orientation filter for inertial and inertial/magnetic sensor arrays"
/// (2010): one normalised gradient-descent step per sample towards the attitude that explains the
/// measured gravity (and magnetic field), fused with gyro integration. `beta` (rad/s) is the gain:
/// sqrt(3/4) times the expected gyro error; larger = faster convergence, noisier.
class Madgwick {
 public:
  explicit Madgwick(double beta = 0.1) noexcept : beta_(beta) {}
  void set_beta(double beta) noexcept { beta_ = beta; }
  void reset(const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) noexcept { q_ = q.normalized(); }
  /// [RT] gyro rad/s, accel m/s^2 (any scale; a zero vector is ignored), dt_s > 0.
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt_s) noexcept;
  /// [RT] with magnetometer (any unit; a zero vector falls back to update without it).
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
              double dt_s) noexcept;
  const Eigen::Quaterniond& q() const noexcept { return q_; }

 private:
  double beta_;
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
};

/// Mahony, Hamel, Pflimlin, "Nonlinear complementary filters on the special orthogonal group" (2008),
/// explicit complementary filter: the cross product between measured and predicted gravity (and
/// field) directions is the attitude error; kp (1/s) feeds it back to the gyro, ki (1/s^2)
/// integrates it into a gyro-bias estimate.
class Mahony {
 public:
  explicit Mahony(double kp = 1.0, double ki = 0.0) noexcept : kp_(kp), ki_(ki) {}
  void set_gains(double kp, double ki) noexcept { kp_ = kp; ki_ = ki; }
  void reset(const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) noexcept {
    q_ = q.normalized();
    bias_.setZero();
  }
  /// [RT] same contract as Madgwick::update.
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt_s) noexcept;
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, const Eigen::Vector3d& mag,
              double dt_s) noexcept;
  const Eigen::Quaterniond& q() const noexcept { return q_; }
  /// The integral term: minus the estimated gyro bias (rad/s), body frame.
  const Eigen::Vector3d& integral() const noexcept { return bias_; }

 private:
  void step(const Eigen::Vector3d& gyro, const Eigen::Vector3d& err, double dt_s) noexcept;
  double kp_, ki_;
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
};

/// Either filter behind one switch (what the motion plugins configure).
class Ahrs {
 public:
  enum class Kind { Madgwick, Mahony };
  Ahrs() = default;
  Ahrs(Kind kind, double gain, double ki = 0.0) noexcept { configure(kind, gain, ki); }
  /// gain: Madgwick beta or Mahony kp; ki: Mahony only.
  void configure(Kind kind, double gain, double ki = 0.0) noexcept {
    kind_ = kind;
    madgwick_.set_beta(gain);
    mahony_.set_gains(gain, ki);
  }
  void reset(const Eigen::Quaterniond& q = Eigen::Quaterniond::Identity()) noexcept {
    madgwick_.reset(q);
    mahony_.reset(q);
  }
  /// [RT] `mag` may be nullptr.
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, const Eigen::Vector3d* mag,
              double dt_s) noexcept {
    if (kind_ == Kind::Madgwick) {
      mag ? madgwick_.update(gyro, accel, *mag, dt_s) : madgwick_.update(gyro, accel, dt_s);
    } else {
      mag ? mahony_.update(gyro, accel, *mag, dt_s) : mahony_.update(gyro, accel, dt_s);
    }
  }
  const Eigen::Quaterniond& q() const noexcept { return kind_ == Kind::Madgwick ? madgwick_.q() : mahony_.q(); }
  Kind kind() const noexcept { return kind_; }

 private:
  Kind kind_ = Kind::Mahony;
  Madgwick madgwick_;
  Mahony mahony_;
};

}  // namespace locus::dsp
