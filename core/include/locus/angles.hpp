// Angle helpers shared by the plugins, the simulator and the evaluator (one copy, one rule).
//
// Why std::remainder: it is exact (the remainder of a double by 2π, rounded once, is representable),
// so an angle already inside the range comes back unchanged, bit for bit, and wrapping the
// difference of two headings never adds rounding error. Header-only and allocation-free: [RT].
#pragma once

#include <cmath>
#include <numbers>

namespace locus {

/// [RT] The angle `a_rad` wrapped to (−π, π] (radians). NaN and ±∞ give NaN.
inline double wrap_pi(double a_rad) noexcept {
  double a = std::remainder(a_rad, 2.0 * std::numbers::pi);
  if (a <= -std::numbers::pi) a += 2.0 * std::numbers::pi;
  return a;
}

}  // namespace locus
