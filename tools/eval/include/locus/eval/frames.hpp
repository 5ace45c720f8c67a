// The frames an estimate may be expressed in, and how the scorer maps ground truth into them.
// docs/eval.md is the reference for plugin authors; in short (`@T` = optional suffix, a time on the
// reference device's clock):
//
//   world              the scene world frame (anchored systems).
//   <name>_start[@T]   origin at the reference's true position at T; y = its body y axis projected on
//                      the horizontal plane (body −z when y is within ~11.5° of vertical), z = up,
//                      x = y × z. Without @T, T = the first truth sample of the reference.
//                      `player_start` (AMIL), `observer_start` (LocBLE), `A_start`...
//   <name>_origin[@T]  origin at the reference's position at T, world axes.
//   <name>_north[@T]   origin at the reference's position at T, x east, y magnetic north (horizontal
//                      part of truth.magnetic_field_world), z up: compass-referenced dead reckoning.
//   body               origin and axes of the reference's body at the estimate's own time.
//   relative           up to a rigid transform: each snapshot (same plugin, reference, frame, t_s) is
//                      aligned to truth by the best-fit rotation + translation before scoring.
//   relative_trace     up to one rigid transform for all estimates of the plugin (traces/formation).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Dense>

#include "locus/eval/truth.hpp"

namespace locus::eval {

enum class FrameKind { World, Start, Origin, North, Body, Relative, RelativeTrace };

struct FrameSpec {
  FrameKind kind = FrameKind::World;
  std::string name;                    ///< as written in the estimate
  std::optional<double> t0_local_s;    ///< the @T suffix, reference clock

  /// Frames tied to a device need a non-empty `reference` in the estimate.
  bool needs_reference() const noexcept;
  /// Frames known only up to a rigid transform (scored after alignment).
  bool aligned() const noexcept { return kind == FrameKind::Relative || kind == FrameKind::RelativeTrace; }
};

/// Parses a frame name. Throws std::invalid_argument saying what was expected.
FrameSpec parse_frame(std::string_view name);

/// A known frame placed in the world: p_frame = axes^T · (p_world − origin). Columns of `axes` are the
/// frame's unit x, y, z axes in world coordinates.
struct FramePlacement {
  Vec3 origin_m = Vec3::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
  Vec3 to_frame(const Vec3& world) const { return axes.transpose() * (world - origin_m); }
};

/// Horizontal heading axes of a device attitude (the `_start` frame's axes): columns x, y, z.
Eigen::Matrix3d heading_axes(const Eigen::Quaterniond& attitude);

/// Places a non-aligned frame for an estimate whose true time is `t_true_s`. `reference` is the
/// estimate's reference device. Throws std::runtime_error when the truth lacks what the frame needs
/// (no trajectory of the reference, no magnetic field, an aligned frame).
FramePlacement place_frame(const FrameSpec& frame, const std::string& reference, double t_true_s,
                           const TruthData& truth);

/// dst ≈ R·src + t, least squares (Kabsch/Umeyama without scale). dims == 2: rotation about z only,
/// z components ignored (the result has z rotation only, t.z = 0); dims == 3: full rotation
/// (proper, det = +1). Needs at least one point; one point gives R = I.
struct RigidFit {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Vec3 translation = Vec3::Zero();
  Vec3 apply(const Vec3& p) const { return rotation * p + translation; }
};
RigidFit fit_rigid(const std::vector<Vec3>& src, const std::vector<Vec3>& dst, int dims);

}  // namespace locus::eval
