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
#include <cstdint>

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

/// Hard iron of a magnetometer, learnt from the device's own turning (the magnetometer's constant
/// offset h in the body frame: a phone's or board's magnets and iron; 1-5 uT against a horizontal
/// field of ~20 uT, i.e. up to ~15 deg of heading). A turning device sees the field rotate about h:
/// with m = R^T F + h and dR/dt = R [w]x, dm/dt = -w x (m - h), so over an interval
///   (m(t1) - m(t0)) + integral(w x m dt) = theta x h,   theta = integral(w dt)   (exact, h constant)
/// which is linear in h with the gyro's rotation as regressor: a still device gives no equation at
/// all (no bias towards its one reading, as a sphere fit to a noise blob would). Intervals of
/// `interval_s` whose rotation exceeds `min_turn_rad` (many times the gyro bias's drift) add
///   A += [theta]x^T [theta]x / s^2,  b += [theta]x^T z / s^2   (s^2 = 2 noise_ut^2: two readings)
/// with exponential forgetting (time constant tau_s: a magnet moving in the case is relearnt); the
/// estimate is the posterior mean with the prior h ~ N(0, prior_ut^2 I): along the axis the device
/// never turned about, or before it turns at all, it stays at 0. Plain value type: no allocation [RT].
class HardIronCalibrator {
 public:
  struct Config {
    double interval_s = 0.5;     ///< integration interval of one equation
    double min_turn_rad = 0.15;  ///< an interval turning less adds nothing
    double tau_s = 120.0;        ///< forgetting time constant
    double prior_ut = 5.0;       ///< 1-sigma of each hard-iron component before any turn
    double noise_ut = 0.5;       ///< magnetometer noise (1 sigma per reading and axis)
  };
  HardIronCalibrator() noexcept { reset(); }
  void configure(const Config& c) noexcept {
    cfg_ = c;
    reset();
  }
  void reset() noexcept;
  /// [RT] one sample: gyro rad/s and field (the unit of prior_ut / noise_ut), dt_s since the last.
  void update(const Eigen::Vector3d& gyro, const Eigen::Vector3d& mag, double dt_s) noexcept;
  /// [RT] posterior mean of the hard iron (body frame); zero until the device turned.
  const Eigen::Vector3d& hard_iron() const noexcept { return h_; }
  /// [RT] posterior 1-sigma of the least known direction of h.
  double max_std() const noexcept { return max_std_; }
  /// Intervals that turned enough to count (since reset).
  std::uint64_t turns() const noexcept { return turns_; }

 private:
  Config cfg_;
  Eigen::Matrix3d a_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d h_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d m0_ = Eigen::Vector3d::Zero(), theta_ = Eigen::Vector3d::Zero(), wxm_ = Eigen::Vector3d::Zero();
  double t_interval_ = 0.0;
  bool started_ = false;
  double max_std_ = 0.0;
  std::uint64_t turns_ = 0;
};

}  // namespace locus::dsp
