// Hand-gesture model (AMIL): min-jerk strokes between waypoints, pauses, yaw drift and tremor.
#include "locus/sim/motion/gesture.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "locus/sim/rng.hpp"
#include "locus/numbers.hpp"

namespace locus::sim::motion {
namespace {

// Minimum-jerk profile and its derivatives with respect to u.
double mj(double u) { return u * u * u * (10.0 + u * (-15.0 + 6.0 * u)); }
double mj1(double u) { return 30.0 * u * u * (1.0 - u) * (1.0 - u); }
double mj2(double u) { return 60.0 * u - 180.0 * u * u + 120.0 * u * u * u; }
// Wiggle bump 64u³(1−u)³ (peak 1 at u = 1/2; value, slope and curvature 0 at both ends).
double bump(double u) { const double w = u * (1.0 - u); return 64.0 * w * w * w; }
double bump1(double u) { const double w = u * (1.0 - u); return 192.0 * w * w * (1.0 - 2.0 * u); }
double bump2(double u) {
  const double w = u * (1.0 - u), s = 1.0 - 2.0 * u;
  return 192.0 * (2.0 * w * s * s - 2.0 * w * w);
}
constexpr double kBump1Max = 3.4346;  // max |bump1|

}  // namespace

GestureTrajectory::GestureTrajectory(const GestureParams& params, double t0_s, std::uint64_t seed)
    : params_(params), t0_s_(t0_s) {
  const auto& p = params_;
  if (p.waypoints_m.size() < 2) throw std::invalid_argument("gesture: need at least 2 waypoints");
  if (!(p.mean_speed_mps > 0.0) || !(p.min_stroke_s > 0.0))
    throw std::invalid_argument("gesture: mean_speed_mps and min_stroke_s must be > 0");
  if (!(p.pause_min_s >= 0.0) || p.pause_max_s < p.pause_min_s || p.lead_in_s < 0.0 || p.lead_out_s < 0.0)
    throw std::invalid_argument("gesture: pauses must satisfy 0 <= pause_min_s <= pause_max_s, leads >= 0");
  if (p.tremor_m < 0.0 || p.tremor_rad < 0.0 || p.yaw_wobble_rad < 0.0 || !(p.tremor_hz > 0.0))
    throw std::invalid_argument("gesture: tremor/wobble must be >= 0 and tremor_hz > 0");
  if (!(p.wiggle_m >= 0.0) || !(p.yaw_stroke_rad >= 0.0) || !(p.waypoint_jitter_m >= 0.0))
    throw std::invalid_argument("gesture: wiggle_m, yaw_stroke_rad and waypoint_jitter_m must be >= 0");

  Rng rng(seed);
  const Eigen::Rotation2Dd plane(p.plane_yaw_rad);
  for (const auto& w : p.waypoints_m) {
    const Eigen::Vector2d r = plane * w;
    points_world_.push_back(p.origin_m + Vec3(r.x(), r.y(), 0.0));
  }
  const std::size_t n = points_world_.size();
  Rng hand(seed ^ 0x5EEDC0FFEE11ull);  // wiggle, mid-stroke yaw, corner misses
  for (std::size_t k = 1; k < n; ++k)
    if (p.waypoint_jitter_m > 0.0)
      points_world_[k] += Vec3(p.waypoint_jitter_m * hand.normal(), p.waypoint_jitter_m * hand.normal(), 0.0);
  for (std::size_t k = 0; k + 1 < n; ++k) {
    Vec3 d = points_world_[k + 1] - points_world_[k];
    d.z() = 0.0;
    const double len = d.norm();
    const Vec3 along = len > 0.0 ? Vec3(d / len) : Vec3::UnitX();
    const Vec3 across(-along.y(), along.x(), 0.0);
    const double w_across = p.wiggle_m * hand.normal(), w_along = p.wiggle_m * hand.normal();
    wiggle_.push_back(w_across * across + w_along * along);
    yaw_bump_.push_back(p.yaw_stroke_rad * hand.normal());
  }
  yaw_at_.resize(n);
  yaw_at_[0] = p.device_heading_rad;
  for (std::size_t k = 1; k < n; ++k) yaw_at_[k] = p.device_heading_rad + p.yaw_wobble_rad * rng.normal();

  double t = t0_s;
  for (std::size_t k = 0; k < n; ++k) {
    double dur = rng.uniform(p.pause_min_s, p.pause_max_s);
    if (k == 0) dur += p.lead_in_s;
    if (k + 1 == n) dur += p.lead_out_s;
    pauses_.push_back({t, t + dur, points_world_[k]});
    t += dur;
    if (k + 1 < n) {
      const double d = (points_world_[k + 1] - points_world_[k]).norm();
      const double T = std::max(p.min_stroke_s, d / p.mean_speed_mps);
      max_speed_ = std::max(max_speed_, (1.875 * d + kBump1Max * wiggle_[k].norm()) / T);  // min-jerk peak + wiggle
      t += T;
    }
  }
  t_end_s_ = t;

  // Tremor: three sinusoids per axis spread around tremor_hz, total std = the set value.
  for (int axis = 0; axis < 6; ++axis) {
    const double stdv = axis < 3 ? p.tremor_m : p.tremor_rad;
    const bool active = p.lifted || axis == 0 || axis == 1 || axis == 5;  // on a table: x, y, yaw only
    for (int c = 0; c < 3; ++c) {
      Tremor tr{active ? stdv * std::sqrt(2.0 / 3.0) : 0.0, p.tremor_hz * rng.uniform(0.7, 1.3),
                rng.uniform(0.0, kTwoPi)};
      tremor_[axis].push_back(tr);
      if (axis < 3) max_speed_ += tr.amp * 2.0 * std::numbers::pi * tr.freq_hz;
    }
  }
  max_speed_ = 1.05 * max_speed_ + 1e-3;
}

void GestureTrajectory::eval(double t, Vec3& pos, Vec3& vel, Vec3& acc, double& yaw) const {
  vel.setZero();
  acc.setZero();
  const std::size_t n = pauses_.size();
  if (t <= pauses_.front().end_s) {
    pos = points_world_.front();
    yaw = yaw_at_.front();
  } else if (t >= pauses_.back().start_s) {
    pos = points_world_.back();
    yaw = yaw_at_.back();
  } else {
    // Find the pause or stroke containing t.
    std::size_t k = 0;
    while (k + 1 < n && t >= pauses_[k + 1].start_s) ++k;
    if (t <= pauses_[k].end_s) {
      pos = points_world_[k];
      yaw = yaw_at_[k];
    } else {
      const double t0 = pauses_[k].end_s, T = pauses_[k + 1].start_s - t0;
      const double u = std::clamp((t - t0) / T, 0.0, 1.0);
      const Vec3 d = points_world_[k + 1] - points_world_[k];
      const double dyaw = yaw_at_[k + 1] - yaw_at_[k];
      const Vec3& o = wiggle_[k];
      pos = points_world_[k] + d * mj(u) + o * bump(u);
      vel = d * (mj1(u) / T) + o * (bump1(u) / T);
      acc = d * (mj2(u) / (T * T)) + o * (bump2(u) / (T * T));
      yaw = yaw_at_[k] + dyaw * mj(u) + yaw_bump_[k] * bump(u);
    }
  }
  for (int axis = 0; axis < 3; ++axis) {
    for (const auto& tr : tremor_[axis]) {
      const double w = kTwoPi * tr.freq_hz;
      pos[axis] += tr.amp * std::sin(w * t + tr.phase);
      vel[axis] += tr.amp * w * std::cos(w * t + tr.phase);
      acc[axis] -= tr.amp * w * w * std::sin(w * t + tr.phase);
    }
  }
}

Pose GestureTrajectory::pose(double t_s) const {
  Vec3 p, v, a;
  double yaw;
  eval(t_s, p, v, a, yaw);
  double rot[3] = {0.0, 0.0, 0.0};  // about body x (pitch), y (roll), world z (yaw)
  for (int axis = 0; axis < 3; ++axis)
    for (const auto& tr : tremor_[3 + axis]) rot[axis] += tr.amp * std::sin(kTwoPi * tr.freq_hz * t_s + tr.phase);
  Pose out;
  out.position_m = p;
  out.attitude = heading_pitch_roll(yaw + rot[2], params_.tilt_pitch_rad + rot[0], params_.tilt_roll_rad + rot[1]);
  return out;
}

Eigen::Vector3d GestureTrajectory::velocity(double t_s) const {
  Vec3 p, v, a;
  double yaw;
  eval(t_s, p, v, a, yaw);
  return v;
}

Eigen::Vector3d GestureTrajectory::acceleration(double t_s) const {
  Vec3 p, v, a;
  double yaw;
  eval(t_s, p, v, a, yaw);
  return a;
}

}  // namespace locus::sim::motion
