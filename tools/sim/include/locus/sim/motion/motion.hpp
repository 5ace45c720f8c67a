// Shared helpers of the simulator's motion models (gesture, pedestrian): attitude of a hand-held
// phone. The models themselves are locus::sim::Trajectory implementations (trajectory.hpp).
//
// Frames (docs/scene-format.md): world right-handed, metres, z up; body frame Android convention
// (x right, y up along the screen, z out of the screen); an attitude rotates body vectors into world.
#pragma once

#include <Eigen/Geometry>

namespace locus::sim::motion {

/// Attitude of a hand-held phone: body y points along `heading_rad` (in the world x-y plane, from +x,
/// counter-clockwise), then tilted up about body x by `pitch_rad` (screen towards the face), then
/// rolled about body y by `roll_rad`: q = Rz(heading − π/2)·Rx(pitch)·Ry(roll).
/// heading π/2, pitch 0, roll 0 is the identity (body axes = world axes, flat, screen up).
Eigen::Quaterniond heading_pitch_roll(double heading_rad, double pitch_rad, double roll_rad);

}  // namespace locus::sim::motion
