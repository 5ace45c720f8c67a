// Pedestrian model: a person walking along a polyline with a phone held in front, screen up.
//
// Gait (what the step and stride plugins must recover):
//  - step times: step k lasts T_k = 1/f_k, f_k = step_freq_hz·(1 + cv·N(0,1)) (per-step variation);
//    heel strikes at the step boundaries (true_steps()).
//  - step length (SpyLoc, seeds/001: s = a·f + b, a and b person-dependent) plus a small random
//    part; the defaults of a and b scale with body height.
//  - vertical bounce: inverted-pendulum gait (Montage, seeds/002: stride = 2·cot(φ)·b, φ half the
//    angle between the legs): with leg length L = 0.53·height and sin φ = s/(2L), the hip rises
//    b = L·(1 − cos φ) between heel strike (lowest) and mid-stance (highest); the phone follows the
//    hip, z = z0 − (b/2)·cos(2π·phase) (times bounce_gain).
//  - forward speed surges once per step (fastest at heel strike, slowest at mid-stance):
//    distance within a step = s·(u + (surge/2π)·sin 2πu), u the step phase.
//  - lateral sway at half the step frequency (the body shifts over the stance foot): sway_m·sin(π·Φ),
//    Φ the continuous step count.
//  - start from rest and stop at rest: the first and last steps use quintic profiles with zero
//    velocity and acceleration at rest; the bounce fades in/out over them.
//  - turns: the heading along the path changes smoothly (quintic in arclength over turn_length_m
//    centred at each corner), so the walked path rounds the polyline's corners.
//  - the phone: yaw = heading (body y forward), pitched up by hold_pitch_rad (screen towards the
//    face), small wobble at the step frequency and a slow random wander.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "locus/sim/motion/motion.hpp"
#include "locus/sim/trajectory.hpp"

namespace locus::sim::motion {

struct PedestrianParams {
  std::vector<Eigen::Vector2d> path_m;   ///< polyline (world x, y), at least 2 points
  double height_m = 1.75;                ///< body height
  double phone_height_m = 0.0;           ///< phone height above the floor; 0 = 0.62·height
  double floor_z_m = 0.0;
  double step_freq_hz = 1.9;             ///< mean step frequency (1.6-2.2 Hz typical)
  double step_freq_cv = 0.02;            ///< per-step relative variation of the frequency
  std::optional<double> stride_a_m_s;    ///< s = a·f + b; default a = 0.143·height (s per Hz)
  std::optional<double> stride_b_m;      ///< default b = 0.143·height
  double stride_noise_m = 0.015;         ///< std of the per-step random part of the length
  double surge = 0.15;                   ///< relative forward-speed oscillation within a step
  double bounce_gain = 0.7;              ///< phone bounce / pendulum bounce (knee flexion, arm damping:
                                         ///< ~5 cm measured vs ~7 cm for a rigid pendulum)
  double sway_m = 0.02;                  ///< lateral sway amplitude (half step frequency)
  double turn_length_m = 1.5;            ///< arclength over which a corner's heading change happens
  double hold_pitch_rad = 0.44;          ///< phone tilt towards the face (~25°)
  double wobble_rad = 0.02;              ///< phone attitude wobble amplitude (each axis)
  double start_rest_s = 1.0;             ///< standing still before the first step
  double end_rest_s = 1.0;               ///< standing still after the last step
};

/// A heel strike (true time) and the length of the step it ends.
struct StepTruth {
  double t_s = 0.0;
  double stride_m = 0.0;       ///< distance walked by this step (path arclength)
  double frequency_hz = 0.0;   ///< 1 / duration of this step
};

class PedestrianTrajectory final : public Trajectory {
 public:
  /// Builds the walk starting at true time t0_s (the rest period starts there); the number of steps
  /// follows from the path length. Throws std::invalid_argument for a path of < 2 points, zero
  /// length, or out-of-range parameters (frequency outside 0.5..4 Hz, height outside 0.5..2.5 m).
  PedestrianTrajectory(const PedestrianParams& params, double t0_s, std::uint64_t seed);

  Pose pose(double t_true_s) const override;
  double max_speed_mps() const override { return max_speed_; }
  /// Rest starts at start_s(); walking spans [walk_start_s(), walk_end_s()]; rest until end_s().
  double start_s() const noexcept { return t0_s_; }
  double walk_start_s() const noexcept { return t_walk0_s_; }
  double walk_end_s() const noexcept { return t_walk1_s_; }
  double end_s() const noexcept { return t_end_s_; }

  /// Heel strikes in order: one per step, at the END of each step (the first step's heel strike is
  /// when the first foot lands).
  const std::vector<StepTruth>& true_steps() const noexcept { return steps_; }
  /// Nominal step length for frequency f: a·f + b.
  double model_stride_m(double freq_hz) const noexcept { return a_ * freq_hz + b_; }
  double leg_length_m() const noexcept { return leg_m_; }
  /// Peak-to-peak hip bounce for a step of length s (inverted pendulum), metres.
  double bounce_for_stride_m(double stride_m) const noexcept;
  /// Length of the smoothed path actually walked (m).
  double path_length_m() const noexcept { return path_len_; }
  const PedestrianParams& params() const noexcept { return params_; }

 private:
  struct PathSample {
    double x, y, heading;
  };
  void path_at(double s_m, double& x, double& y, double& heading) const;
  /// Distance along the path, continuous step count Φ, bounce amplitude at t.
  void gait_at(double t_s, double& dist_m, double& phase, double& bounce_m) const;

  PedestrianParams params_;
  double t0_s_ = 0.0, t_walk0_s_ = 0.0, t_walk1_s_ = 0.0, t_end_s_ = 0.0;
  double max_speed_ = 0.0, a_ = 0.0, b_ = 0.0, leg_m_ = 0.0, phone_z_m_ = 0.0, path_len_ = 0.0;
  double ds_ = 0.01;                   // path table resolution (m)
  std::vector<PathSample> path_;       // smoothed path by arclength
  std::vector<double> step_t0_;        // start time of each step; size n+1 (last = end of walk)
  std::vector<double> step_d0_;        // distance at the start of each step; size n+1
  std::vector<double> step_len_;       // size n
  std::vector<StepTruth> steps_;
  double wobble_phase_[3]{}, wander_phase_[3]{}, wander_freq_[3]{};
};

}  // namespace locus::sim::motion
