// Hand-held phone attitude helper.
#include "locus/sim/motion/motion.hpp"

#include <numbers>

namespace locus::sim::motion {

Eigen::Quaterniond heading_pitch_roll(double heading_rad, double pitch_rad, double roll_rad) {
  using Eigen::AngleAxisd;
  using Eigen::Vector3d;
  return Eigen::Quaterniond(AngleAxisd(heading_rad - 0.5 * std::numbers::pi, Vector3d::UnitZ())) *
         Eigen::Quaterniond(AngleAxisd(pitch_rad, Vector3d::UnitX())) *
         Eigen::Quaterniond(AngleAxisd(roll_rad, Vector3d::UnitY()));
}

}  // namespace locus::sim::motion
