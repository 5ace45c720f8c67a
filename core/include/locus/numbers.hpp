// Numeric constants shared by the core, the plugins and the tools. One definition each: files that a
// unity build compiles together (CMake UNITY_BUILD, see CMakeLists.txt) must not each define their
// own in an anonymous namespace, and one spelling keeps the sources alike.
#pragma once

#include <limits>
#include <numbers>

namespace locus {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace locus
