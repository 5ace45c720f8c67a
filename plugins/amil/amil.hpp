// `amil`: the AMIL localizer (paper 004): one device (the player) draws a gesture while beeping; every
// other device (a listener) reports when it heard each beep; the player turns its own IMU-tracked beep
// positions, its own recording of the beeps and the listeners' arrival times into the position of
// every listener in its start frame. Documentation: docs/amil.md (Plugin, Messages, Config).
//
// One instance runs on every node (locus replay: one node per scene device, HostContext::device = that
// device). Its role:
//   - `role: player|listener` as configured; `auto` (default): the device named by `player`, else the
//     device whose scene geometry emits an acoustic signal (HostContext::geometry->emits), else
//     a device with an emitter (a live node with a `playback:` section) is the player; every other
//     device listens.
// Listener: every AudioDetection of its device on channel `channel` (of detector `detector`, any when
// empty) is one beep arrival (the chirp detector's earliest path), published at once on
// <topic>/arrivals/<device>; a hello at configure() and a done message at finish() (messages.hpp).
// Player:
//   - ImuSample -> GestureTracker (tracker.hpp): motion bins, gyro rotation into the start frame,
//     double integration with the paper's velocity de-drift at each pause; sessions (one or more
//     gestures without a long rest);
//   - its own AudioDetections (self-recording, channel `channel`) are the beeps: local time e_k =
//     frame / rate (the speaker latency is in it, the software schedule never is); beep k's position
//     is the speaker's tracked position when the beep sounded (in a pause);
//   - live (HostContext::emitter set): at every pause the tracker reports (and once at the first rest)
//     it schedules a beep `beep_delay_s` ahead (signal: the geometry's emits entry, else the beep_*
//     parameters); the beep's time still comes from the self-recording;
//   - listener arrivals from the link are paired with the session's beeps (match_arrivals: the clock
//     offset that pairs the most beeps within `match_tolerance_s`), solver.hpp positions each
//     listener (method, skew, direction-only fallbacks), and one Estimate per listener is published:
//     reference = player, target = listener, frame "player_start@T", t_s = T (the session's start on
//     the player's clock), position/direction/distance/std/confidence; position null when the solver
//     only gives a direction.
//   - when: `estimates: finish` at finish() (everything has arrived; replay), `gesture` as soon as a
//     session has closed and every known listener has reported its last beep (or `listener_wait_s`
//     of host time passed; live), then at finish() for what was not published yet; `auto` = gesture
//     when the node has an emitter, else finish.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::amil {

/// The `amil` localizer plugin (static storage).
const locus_plugin_descriptor* descriptor();
/// Its parameter schema.
const ParamSchema& schema();

}  // namespace locus::plugins::amil
