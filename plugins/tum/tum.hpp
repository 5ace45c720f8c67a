// `tum`: the TUM localizer (paper 000): two working devices exchange tones (an up and a down LFM
// chirp, overlapping under loose sync), every device with two or more mics times both tones on its own
// clock, and working device 1 places every device (position of its body origin and its speaker, in
// device 1's body frame) at each exchange. Documentation: docs/tum.md (Plugin, Messages, Config).
//
// One instance runs on every node (locus replay: one node per scene device). Every instance:
//   - groups its device's AudioDetections of the two tones (template index -> tone from the scene's
//     signals, as the chirp detector's `from_scene` numbers them) into one exchange: the detections
//     that lie within `pair_window_s` of the exchange's first; the next exchange's first detection
//     (or finish()) closes it;
//   - keeps its attitude (Attitude events of the `attitude` detector) and a motion flag (ImuSample);
//   - publishes one ObsMessage per exchange on <topic>/obs/<device> (messages.hpp).
// Device 1's instance (the reporter) pairs the other devices' exchanges with its own (align_clocks:
// the clock offset the tone intervals agree on), places every device by a least-squares window over
// the last exchanges (network.hpp, on top of solver.hpp: Eq. 2-6 for the working pair, Eq. 17-21 for
// the monitoring devices, every root kept), optionally passes moving devices through the Sec. V
// particle filter (tracker.hpp, `filter: particle`), and publishes one Estimate per device:
// reference = device 1, frame "body", t_s = device 1's tone emission on its clock (one snapshot per
// exchange), position = the device's body origin, std_m, confidence, flags.
// Live (HostContext::emitter set, docs/tum.md "Live roles"): every instance also synchronises its host
// clock with the others' over link round trips, the nodes elect the working pair (closest clocks,
// sync.hpp), and the two working devices emit their tones through the emitter on the elected schedule.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::tum {

/// The `tum` localizer plugin (static storage).
const locus_plugin_descriptor* descriptor();
/// Its parameter schema.
const ParamSchema& schema();

}  // namespace locus::plugins::tum
