// Pose interpolation between the samples of a trajectory: where a time falls among the samples, the
// position linearly and the attitude by Eigen's slerp (shortest arc). The one copy used by the
// scene's TruthTrajectories (truth.hpp), the evaluator's truth tracks and the simulator's sampled
// trajectories, so the truth a scene is scored against is interpolated the way it was simulated.
// Plain maths, no allocation.
#pragma once

#include <Eigen/Geometry>

#include <cstddef>

namespace locus::scene {

/// Where a time falls among ascending sample times.
struct TimeBracket {
  std::size_t lo = 0;  ///< the sample at or before the time
  std::size_t hi = 0;  ///< the sample after it; hi == lo: hold sample lo
  double u = 0.0;      ///< fraction of the way from lo to hi, in [0, 1)
};

/// Time `t` among `count` (>= 1) ascending times time_of(0) .. time_of(count − 1): the first sample
/// is held at or before the first time (and for NaN), the last at or after the last time; in between
/// lo is the last sample at or before t, hi = lo + 1 and u = (t − t_lo) / (t_hi − t_lo) (0 when the
/// two times are equal).
template <typename TimeOf>
TimeBracket bracket(std::size_t count, double t, TimeOf time_of) {
  if (!(t > time_of(0))) return {0, 0, 0.0};
  if (t >= time_of(count - 1)) return {count - 1, count - 1, 0.0};
  std::size_t first = 0, n = count;  // upper bound: the first sample with time > t
  while (n > 0) {
    const std::size_t half = n / 2;
    if (!(t < time_of(first + half))) {
      first += half + 1;
      n -= half + 1;
    } else {
      n = half;
    }
  }
  const std::size_t lo = first - 1;
  const double span = time_of(first) - time_of(lo);
  return {lo, first, span > 0.0 ? (t - time_of(lo)) / span : 0.0};
}

/// The position a fraction `u` of the way from `a` to `b`: a + u (b − a).
inline Eigen::Vector3d interpolate_position(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double u) {
  return a + u * (b - a);
}

/// The attitude a fraction `u` of the way from unit quaternion `a` to `b`: Eigen's slerp, which takes
/// the shortest arc (q and −q are the same rotation).
inline Eigen::Quaterniond interpolate_attitude(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double u) {
  return a.slerp(u, b);
}

}  // namespace locus::scene
