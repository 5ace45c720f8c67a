// `sync_emitter`: the live emitting role of the sync-scheduled systems (SpyLoc's beacons, Montage's
// walkers): a sound is played a known delay after a radio sync arrives. Shared by both (configured,
// not copied): a SpyLoc beacon node runs it alone, a Montage walker node beside `montage`.
//
// Input: RadioSync events of the node's device (live: the `link` sync source, hal/radio/link_sync.hpp,
// which stamps each message's arrival; the pipeline puts it on the audio timeline, so t_s·fs is the
// capture frame at which the sync arrived). For every sync from one of `sources` (default: the device
// itself, a beacon that sends its own syncs) it schedules the device's signal (its first acoustic
// `emits` entry, `emits_index` to choose; from the layout, `locusd --layout`) with the host's Emitter at
//     frame(k) = round((t_s + delay_s + k·repeat_period_s)·fs),  k = 0 .. repeat_count−1
// where delay_s is the signal's `sync_delay_s` (param `delay_s` ≥ 0 overrides it). Capture frame F and
// playback frame F are the same instant on a node whose source and sink share one JACK client
// (hal/jack); on another backend the difference is the device's round-trip latency, which this does
// not know (see docs/room.md).
//
// An emission whose frame the playback stream has already passed when the sync reaches the plugin is
// not scheduled and is counted (`late`): the sync arrived less than the pipeline's delivery time (one
// audio period + the detector thread + the dispatcher) before it. finish() logs syncs, emissions
// scheduled, late and refused, the smallest and median lead (how far ahead of the playback position an
// emission was scheduled) and the emitter's own count of cut emissions.
//
// Needs the device's emitter (a `playback:` section): configure() refuses a node without one (a
// replay has none: the scene already holds what was played).
#pragma once

#include <cstdint>

#include "locus/plugin.hpp"

namespace locus::plugins::sync_emitter {

/// Playback frame of emission k of a sync that arrived at device-local time `sync_t_s` (audio
/// timeline: frame 0 at 0 s): round((sync_t_s + delay_s + k·period_s)·fs). Negative when before frame 0.
std::int64_t emission_frame(double sync_t_s, double delay_s, double period_s, std::int64_t k, double fs_hz) noexcept;

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::sync_emitter
