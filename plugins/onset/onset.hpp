// `onset`: a per-channel energy-onset detector (any sound that rises above the noise floor).
//
// Per channel, per sample (sample-major across channels, so events come out in stream order and the
// result does not depend on how the stream is cut into blocks):
//   - short-term energy  e += a * (x^2 - e), a = 1 - exp(-1 / (window_s * fs))          (one-pole);
//   - noise floor        f += b * (x^2 - f), b = 1 - exp(-1 / (floor_time_constant_s * fs)), with
//     b = max(b, 1/(n+1)) over the first samples (a running mean, so the floor is usable after
//     warmup_s); the floor is frozen while an event is in progress (from the trigger until hold_off_s
//     after the onset) and never taken below min_floor_dbfs;
//   - trigger            e > f * 10^(threshold_db / 10), once warmup_s of floor has been seen;
//   - onset refinement   walk back from the trigger sample (at most lookback_s) to the first sample of
//     the burst whose |x| exceeds onset_k * sqrt(f) (the walk stops at a run of onset_gap_s of samples
//     below that level), and place the onset by linear interpolation of |x| between that sample and
//     the one before it, at the exact crossing of onset_k * sqrt(f). Bias: the estimate is LATE by the
//     time the signal needs to rise to onset_k noise RMS. For a signal that starts as a sine of
//     amplitude A and frequency f (no fade) that is asin(k*sigma/A) / (2*pi*f) seconds: at 20 dB SNR
//     (A = 14.1 sigma), k = 4 and f = 2 kHz about 1.0 sample at 44.1 kHz (measured in
//     tests/plugins/test_onset.cpp: mean +1.06, sd 0.21, range +0.5..+1.5 samples). A faded onset
//     (raised-cosine fade T) is late by about T/pi * acos(1 - 2k*sigma/A) (T = 5 ms, 20 dB, k = 4:
//     1.8 ms = ~79 samples; measured +80, sd 6): use a matched-filter
//     detector (chirp) when the signal is known and sample accuracy matters;
//   - the detection (AudioDetection, template_index 0) is emitted when the burst ends (e falls back
//     below the trigger level) or hold_off_s after the onset, whichever comes first, with
//     snr_db = 10 log10(peak e / floor), amplitude = peak |x| of the burst (from the onset on),
//     confidence = 1 - 10^(-(snr_db - threshold_db) / 10) (0 at the threshold, 0.9 at 10 dB above);
//   - re-arming: once hold_off_s after the onset has passed and e is below the trigger level again.
//     The floor resumes tracking after hold_off_s even if the level stays high, so a permanent rise
//     of the noise becomes the new floor instead of blocking the detector.
// Overruns: a block with lost_before > 0 first emits a detection still pending (it was found on
// contiguous audio), then resets every sample-continuity state: short-term energy (restarted at the
// floor, its expected value), the look-back history (an onset is never placed before the gap), the
// event in progress and the hold-off. The noise-floor estimate is kept: a gap in the samples does not
// change the noise statistics, and keeping it avoids a second warm-up blind spot after every overrun.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::onset {

/// The `onset` detector plugin (static storage).
const locus_plugin_descriptor* descriptor();
/// Its parameter schema.
const ParamSchema& schema();

}  // namespace locus::plugins::onset
