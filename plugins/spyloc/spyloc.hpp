// `spyloc` localizer (paper 001): a walker's phone ranges to anchored beacons from a radio sync and
// the multitone beep that follows it a known delay later, tells LoS from NLoS beeps by their decay,
// and tracks between fixes.
//
// Why this shape: the beacon sends its sync over radio (µs latency) and beeps sync_delay_s later, so
// one beep gives an absolute range c·(t_beep − t_sync − delay) on the phone's own clock, no clock
// synchronisation needed; but a beep heard around a partition arrives by a longer (diffracted or
// reflected) path, metres too long, so every beep is classified before it may touch the position.
//
// Inputs (one device, HostContext::device on replay):
//   radio_sync        from the beacon `source` (sync.csv on replay);
//   audio_detection   of the `multitone` detector: template = the beacon's tone mask;
//   decay_features    right after it (same frame): T5..T30 for the classifier.
// Beacons: the scene's multitone emitters with an anchor (SceneSignal::has_anchor) and a
// sync_delay_s; identity = their tone set as bits of tones_hz (the detector's tone grid).
// Per beep: the latest sync of its beacon that can precede it (range in [−sync_slack_s·c,
// max_range_m]) gives the range; no such sync (lost) → the beep is skipped (counted). The
// classifier (classifier.hpp; model file from `locus train spyloc`) gives P(LoS); LoS when
// ≥ los_threshold. NLoS ranges never enter the filter.
// Position: trilateration (solver.hpp) from LoS ranges of >= 3 beacons within init_window_s, at the
// assumed device height; a mirror ambiguity (beacons in a line) is resolved by `region_m` when given,
// else by the candidate farther from the world axes (scene frames hold the room in x, y >= 0), and
// flagged `ambiguous`. Then the EKF (tracker.hpp) predicts to each beep and applies its LoS range;
// reinit_after consecutive gated-out LoS ranges widen the track (inflate_m) so the ranges pull it back.
// Output: one `estimate` per processed beep after the first fix: world frame, target = the device,
// t_s = the beep's arrival (device clock), std_m = std_scale·sqrt(trace P) (std_scale 2.36 measured
// so that 68 % of errors fall within std_m on simulated seeds 101-120; spyloc-104: 71 %), confidence = exp(−std_m / 1 m) (×0.5 when ambiguous or
// the beep was gated out), los = this beep's verdict.
// Not done here (issue 16): link/BLE sync for live boards, step-length model and heading from the IMU.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::spyloc {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::spyloc
