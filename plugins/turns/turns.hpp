// `turns`: a walker's turns from the IMU (paper 003 LocBLE, Sec. 5.2.2: find the "bump" of the
// gyroscope caused by a turn, its beginning and end, and the heading change between them).
//
// Signal: the yaw rate in the reference frame, w_z = (q·gyro_body).z (independent of how the phone
// is held; q from the plugin's own AHRS), smoothed by a one-pole low-pass (`smoothing_s`) against the
// sway of each step. A turn starts when |smoothed w_z| exceeds `start_rate_radps` and ends at the
// first moment it is back below `end_rate_radps`, confirmed after it stayed there for `hold_s`. Its
// angle is the integral of the raw w_z from the last calm instant before the start to the end (the
// gyro path; with a magnetometer the AHRS heading includes it, but integration is immune to the
// moments where the heading of the body y axis is undefined, e.g. phone upright in a pocket). A
// turn of |angle| >= min_turn_rad and duration <= max_turn_s is reported.
//
// Representation: one Attitude event per turn, at its end (t_s = end of the turn), with
//   q_wxyz      = the turn itself, a pure rotation about reference z: (cos(a/2), 0, 0, sin(a/2)),
//                 a > 0 = counter-clockwise seen from above = a LEFT turn; angle = 2·atan2(q_z, q_w);
//   heading_rad = the AHRS heading of the body y axis after the turn.
// The `detector` field (the instance name) tells these events apart from the `attitude` plugin's.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::turns {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::turns
