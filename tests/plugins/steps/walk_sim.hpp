// A synthetic walker's IMU for the motion plugin tests: a phone held at a fixed tilt relative to the
// walker, who stands, walks straight segments at varying step frequency, turns smoothly, and pauses.
// The vertical hip motion follows the inverted pendulum (bounce h = l - sqrt(l^2 - (s/2)^2) for a
// step of length s and leg length l), with a second harmonic, forward surge, lateral sway at half
// the step frequency, pelvis yaw sway, sensor noise, gyro bias and timestamp jitter. Truth: the
// time of every heel strike (vertical-acceleration peak), the stride of each step, each turn.
#pragma once

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "locus/events.hpp"

namespace locus::test {

struct WalkSegment {
  enum Kind { Stand, Walk, Turn } kind = Stand;
  double duration_s = 1.0;
  double step_hz_start = 1.8, step_hz_end = 1.8;  ///< Walk/Turn: the step frequency ramps linearly
  double stride_m = 0.7;                          ///< Walk/Turn: step length
  double turn_rad = 0.0;                          ///< Turn: heading change (+ = left, CCW)
};

struct WalkTruth {
  std::vector<double> step_t_s;
  std::vector<double> step_stride_m;
  std::vector<double> turn_end_t_s;
  std::vector<double> turn_rad;
};

struct WalkOptions {
  double rate_hz = 100.0;
  double jitter_s = 0.002;
  double accel_noise = 0.25, gyro_noise = 0.02, gyro_bias = 0.01;
  double leg_m = 0.9;
  double harmonic = 0.3, harmonic_phase = 0.6;
  /// Left/right asymmetry: a vertical component at half the step frequency (relative to the
  /// fundamental), so every other mid-stride bump of the harmonic rises higher (a limp, or a phone
  /// on one hip).
  double asymmetry = 0.0;
  Eigen::Quaterniond device_tilt = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitX()) *
                                                      Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()));
  bool with_mag = false;
  unsigned seed = 1;
};

inline std::vector<ImuSample> simulate_walk(const std::vector<WalkSegment>& segs, const WalkOptions& o, WalkTruth& truth) {
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> jit(-o.jitter_s, o.jitter_s);
  const double pi = std::numbers::pi;
  const double dt = 1.0 / o.rate_hz;
  const Eigen::Vector3d bias(o.gyro_bias, -0.5 * o.gyro_bias, 0.7 * o.gyro_bias);
  const Eigen::Vector3d field_world(20.0, 0.0, -40.0);
  std::vector<ImuSample> out;
  double t = 0.0, phase = 0.0, heading = 0.3;
  // Walking amplitude envelope ramps over 0.4 s at walk start/end so the walk starts like a real one.
  for (std::size_t si = 0; si < segs.size(); ++si) {
    const WalkSegment& s = segs[si];
    const bool moving = s.kind != WalkSegment::Stand;
    const bool prev_moving = si > 0 && segs[si - 1].kind != WalkSegment::Stand;
    const bool next_moving = si + 1 < segs.size() && segs[si + 1].kind != WalkSegment::Stand;
    const int n = static_cast<int>(std::lround(s.duration_s / dt));
    const double h = moving ? o.leg_m - std::sqrt(o.leg_m * o.leg_m - 0.25 * s.stride_m * s.stride_m) : 0.0;
    for (int i = 0; i < n; ++i, t += dt) {
      const double u = static_cast<double>(i) / n;
      const double f = s.step_hz_start + (s.step_hz_end - s.step_hz_start) * u;
      double env = 0.0;
      if (moving) {
        env = 1.0;
        const double tin = i * dt, tout = (n - i) * dt;
        if (!prev_moving && tin < 0.4) env = tin / 0.4;
        if (!next_moving && tout < 0.4) env = std::min(env, tout / 0.4);
      }
      double yaw_rate = 0.0;
      if (s.kind == WalkSegment::Turn) {
        // Smooth (raised-cosine) yaw rate profile integrating to turn_rad over the segment.
        yaw_rate = s.turn_rad / s.duration_s * (1.0 - std::cos(2.0 * pi * u));
      }
      const double w = 2.0 * pi * f;
      const double prev_phase = phase;
      if (moving) phase += w * dt;
      if (moving && std::floor(phase / (2 * pi)) > std::floor(prev_phase / (2 * pi)) && env >= 0.5) {
        truth.step_t_s.push_back(t + dt);
        truth.step_stride_m.push_back(s.stride_m);
      }
      // World-frame accelerations of the walker (x forward, y left in the walker frame).
      const double av = env * (0.5 * h * w * w *
                               (std::cos(phase) + o.harmonic * std::cos(2 * phase + o.harmonic_phase) +
                                o.asymmetry * std::sin(0.5 * phase)));
      const double af = env * 0.8 * std::sin(phase + 0.4);
      const double al = env * 0.5 * std::sin(0.5 * phase);
      const double sway = env * 0.06 * std::sin(0.5 * phase);
      const double sway_rate = env * 0.06 * 0.5 * w * std::cos(0.5 * phase);
      const double psi = heading + sway;
      const Eigen::Vector3d a_world(af * std::cos(psi) - al * std::sin(psi), af * std::sin(psi) + al * std::cos(psi), av);
      const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ())) * o.device_tilt;
      const Eigen::Vector3d spec = q.conjugate() * (a_world + Eigen::Vector3d(0, 0, 9.80665));
      const Eigen::Vector3d gyro = q.conjugate() * Eigen::Vector3d(0, 0, yaw_rate + sway_rate);
      const Eigen::Vector3d mag = q.conjugate() * field_world;
      ImuSample smp;
      smp.device = "walker";
      smp.t_s = t + jit(rng);
      for (int k = 0; k < 3; ++k) {
        smp.accel_mps2[k] = static_cast<float>(spec[k] + o.accel_noise * n01(rng));
        smp.gyro_radps[k] = static_cast<float>(gyro[k] + bias[k] + o.gyro_noise * n01(rng));
        smp.mag_ut[k] = static_cast<float>(mag[k] + 0.5 * n01(rng));
      }
      smp.has_mag = o.with_mag;
      out.push_back(smp);
      heading += yaw_rate * dt;
    }
    if (s.kind == WalkSegment::Turn) {
      truth.turn_end_t_s.push_back(t);
      truth.turn_rad.push_back(s.turn_rad);
    }
  }
  return out;
}

/// A mixed walk: standing, slow to fast straight walks, left and right turns, a pause.
inline std::vector<WalkSegment> mixed_walk(double f_scale = 1.0) {
  using K = WalkSegment;
  return {
      {K::Stand, 3.0},
      {K::Walk, 20.0, 1.5 * f_scale, 2.1 * f_scale, 0.65},
      {K::Turn, 1.6, 2.0 * f_scale, 1.8 * f_scale, 0.65, std::numbers::pi / 2},
      {K::Walk, 15.0, 1.8 * f_scale, 1.8 * f_scale, 0.72},
      {K::Stand, 3.0},
      {K::Walk, 12.0, 1.7 * f_scale, 2.2 * f_scale, 0.78},
      {K::Turn, 1.8, 2.0 * f_scale, 2.0 * f_scale, 0.7, -std::numbers::pi / 2},
      {K::Walk, 20.0, 2.2 * f_scale, 1.6 * f_scale, 0.7},
      {K::Turn, 2.5, 1.7 * f_scale, 1.7 * f_scale, 0.6, std::numbers::pi},
      {K::Walk, 10.0, 1.7 * f_scale, 1.7 * f_scale, 0.68},
      {K::Stand, 3.0},
  };
}

}  // namespace locus::test
