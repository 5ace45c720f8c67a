// Hand-gesture model: a phone slid (or held) by hand along straight strokes between waypoints, with
// a pause at every waypoint — the AMIL gesture (seeds/004: "from (0,0) to (-30.5,0), to (0,30.5), to
// (30.5,0) and back to (0,0)" cm, five beeps, one per pause, finishing within ~4-5 s).
//
// Each stroke is a minimum-jerk move (Flash & Hogan): p(u) = p0 + (p1−p0)·(10u³ − 15u⁴ + 6u⁵),
// u = (t−t0)/T, so velocity and acceleration are zero at both ends; the stroke duration follows the
// distance, T = max(min_stroke_s, distance / mean_speed_mps). The phone's yaw changes a little from
// waypoint to waypoint (a hand rotates the phone as it moves; min-jerk too), and physiological
// tremor (8-12 Hz, sub-millimetre) rides on top everywhere. Pauses are where the player beeps.
//
// A hand is not a robot (what makes the gesture as hard as the world, docs/simulator-motion.md):
//   * wiggle: every stroke bows off the straight line and speeds up / lags along it by a smooth bump
//     o_k·64u³(1−u)³ (zero position, velocity and acceleration change at both ends), o_k drawn per
//     stroke, N(0, wiggle_m) across and along the stroke;
//   * yaw during strokes: the phone turns by N(0, yaw_stroke_rad) at mid-stroke (same bump) on top
//     of the waypoint-to-waypoint heading change, and comes back;
//   * the corners actually drawn miss the nominal waypoints by N(0, waypoint_jitter_m) per axis
//     (all but the first, which is the origin of the gesture);
//   * a phone on a table is not level (camera bump, table): constant tilt_pitch/roll, so gravity
//     leaks into the accelerometer's x and y (9.81·sin 0.6° = 0.1 m/s²).
#pragma once

#include <cstdint>
#include <vector>

#include "locus/sim/motion/motion.hpp"
#include "locus/sim/trajectory.hpp"

namespace locus::sim::motion {

using Vec3 = Eigen::Vector3d;

struct GestureParams {
  /// Waypoints in the gesture plane (metres, relative to the first one, x/y of the plane frame).
  /// Default: the AMIL triangle of 30.5 cm sides, starting and ending in the middle of the base.
  std::vector<Eigen::Vector2d> waypoints_m{{0.0, 0.0}, {-0.305, 0.0}, {0.0, 0.305}, {0.305, 0.0}, {0.0, 0.0}};
  Vec3 origin_m = Vec3::Zero();     ///< world position of the first waypoint
  double plane_yaw_rad = 0.0;       ///< rotation of the gesture plane about world z
  double device_heading_rad = 1.5707963267948966;  ///< heading of the phone body y axis (flat, screen
                                                   ///< up); π/2 = body axes along world axes
  double mean_speed_mps = 0.45;     ///< mean stroke speed (distance / stroke duration)
  double min_stroke_s = 0.4;
  double pause_min_s = 0.3;         ///< pause at every waypoint, drawn uniformly in [min, max]
  double pause_max_s = 0.6;
  double lead_in_s = 0.5;           ///< at rest before the gesture (part of the first pause)
  double lead_out_s = 0.5;          ///< at rest after it (part of the last pause)
  double yaw_wobble_rad = 0.035;    ///< std of the phone's heading deviation at each waypoint (~2°)
  double tremor_m = 5e-5;           ///< std of tremor displacement (each axis; ~0.15 m/s² at 9 Hz)
  double tremor_rad = 5e-4;         ///< std of tremor rotation (each axis)
  double tremor_hz = 9.0;           ///< centre of the tremor band (components spread ±30 %)
  bool lifted = false;              ///< false: on a table (z fixed, flat); true: in the air (z tremor, tilt)
  double wiggle_m = 0.0;            ///< std of a stroke's mid-point deviation, across and along it
  double yaw_stroke_rad = 0.0;      ///< std of the yaw excursion at mid-stroke
  double waypoint_jitter_m = 0.0;   ///< std (per axis) of a drawn corner's miss of its nominal waypoint
  double tilt_pitch_rad = 0.0;      ///< constant pitch (about body x) of the phone lying on the table
  double tilt_roll_rad = 0.0;       ///< constant roll (about body y): camera bump, uneven table
};

/// A pause of the gesture: the phone rests at `position_m` from start_s to end_s (true time).
struct PauseInterval {
  double start_s = 0.0;
  double end_s = 0.0;
  Vec3 position_m = Vec3::Zero();  ///< the waypoint (without tremor)
  double mid_s() const noexcept { return 0.5 * (start_s + end_s); }
};

class GestureTrajectory final : public Trajectory {
 public:
  /// Builds the gesture starting at true time t0_s (the lead-in starts there); `seed` draws pause
  /// lengths, heading wobble, tremor, wiggle, mid-stroke yaw and corner misses (the last three from
  /// a separate stream, so a gesture without them is the same as before they existed). Throws std::invalid_argument for fewer than 2 waypoints or
  /// non-positive speeds/durations.
  GestureTrajectory(const GestureParams& params, double t0_s, std::uint64_t seed);

  Pose pose(double t_true_s) const override;
  Eigen::Vector3d velocity(double t_true_s) const override;       ///< closed form
  Eigen::Vector3d acceleration(double t_true_s) const override;   ///< closed form
  double max_speed_mps() const override { return max_speed_; }

  double start_s() const noexcept { return t0_s_; }
  double end_s() const noexcept { return t_end_s_; }
  /// One pause per waypoint, in order (the first includes the lead-in, the last the lead-out).
  /// Stroke k runs from pauses()[k].end_s to pauses()[k+1].start_s.
  const std::vector<PauseInterval>& pauses() const noexcept { return pauses_; }
  const GestureParams& params() const noexcept { return params_; }

 private:
  struct Tremor {
    double amp, freq_hz, phase;
  };
  void eval(double t_s, Vec3& p, Vec3& v, Vec3& a, double& yaw) const;

  GestureParams params_;
  double t0_s_, t_end_s_, max_speed_ = 0.0;
  std::vector<PauseInterval> pauses_;
  std::vector<Vec3> points_world_;
  std::vector<double> yaw_at_;          // device heading at each waypoint
  std::vector<Vec3> wiggle_;            // stroke k: mid-point offset (bump amplitude), world
  std::vector<double> yaw_bump_;        // stroke k: mid-stroke yaw excursion
  std::vector<Tremor> tremor_[6];       // x, y, z displacement; rotation about x, y, z
};

}  // namespace locus::sim::motion
