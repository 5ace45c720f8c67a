// `montage` (paper 002): a group of walkers ranges to each other with Gold-coded tones all emitted at
// once after a radio start signal, and the group's formation and traces are tracked from the ranges
// plus every walker's movement vectors, without anchors (docs/montage.md, "The localizer").
//
// One instance per device (every device runs the same config; `locus replay` runs one node per scene
// device). Each instance:
//  - times its own emission and the other users' arrivals from the `goldcode` detector (template k =
//    the k-th gold emitter of the scene, or of param `users` live) and publishes one round message per
//    own emission (tau since its latest start signal, `RadioSync`), so ETOA ranges need no clock sync;
//  - turns its `steps` and `attitude` events (and raw IMU) into movement vectors: stride, phone
//    heading, and the walking-direction offset from the horizontal acceleration (movement.hpp), and
//    publishes them per step;
//  - publishes its progress (tau) so the reporter knows what has been sent.
// The reporter's instance (param `reporter`, default the last user: on replay the last node to
// finish) groups round messages by tau, computes the ETOA distances, runs the formation solver
// (solver.hpp) round by round, and publishes every localized walker's position per round
// (frame `relative_trace`, reference = the reporter, t_s on its clock: the round's emissions) with a
// std and a confidence, and every walker's steps again with the stride calibrated by ranging.
#pragma once

#include "locus/params.hpp"
#include "locus/plugin.hpp"

namespace locus::plugins::montage {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::montage
