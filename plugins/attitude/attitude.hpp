// `attitude`: device orientation from its IMU (Madgwick or Mahony, gyro + accel, magnetometer when
// present), emitted as Attitude events (q_wxyz rotates body vectors into the reference frame,
// heading_rad = heading of the body y axis, see locus/dsp/ahrs.hpp) at `output_rate_hz`.
//
// Time base: each update integrates over the device-local dt between samples (jitter-proof); the
// first sample and every gap longer than max_gap_s restart the attitude from gravity (and the field
// when `use_mag`). Without a magnetometer yaw is relative to the start and drifts with the gyro
// bias; with one, reference x is magnetic north. Events are emitted on the sample at or after each
// output instant (t_s = that sample's time), `output_rate_hz` = 0 emits on every sample.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::attitude {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::attitude
