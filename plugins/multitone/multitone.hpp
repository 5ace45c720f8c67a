// `multitone`: SpyLoc's beep receiver (paper 001, §II-A and §V): beeps made of a subset of a fixed
// set of tones (default 10 tones, 18000 + 250·k Hz); the subset is the beacon's identity, bit k of
// the identity (the low ten bits of its MAC address) switching tone f_k on.
//
// Per channel, streaming:
//   1. tone bank: every hop_s, the Hann-windowed Goertzel power of each tone over the last frame_s;
//      per-tone noise floors track while no beep is in progress;
//   2. beep: at least min_tones tones above their floor by threshold_db opens a beep; it closes when
//      fewer remain for two hops (or duration_s + frame_s after it opened). Identity = the tones whose
//      peak power during the beep exceeded their floor by threshold_db (bit k = tone k), reported as
//      AudioDetection::template_index (so the MAC bits 0..9);
//   3. arrival: matched filter (FFT) of the raw signal against the identified template (the tones of
//      the identity with the duration_s/fade_s envelope of the scene format's multitone), envelope of
//      the complex (analytic) correlation over ±(frame_s + 2·hop_s + fade_s) around the coarse onset,
//      global maximum, parabolic interpolation. A tone grid of spacing Δf has envelope lobes every
//      1/Δf (4 ms): the global maximum selects the right one while the SNR of the matched filter
//      output exceeds the lobes' loss (~1/Δf / duration). A single-tone identity has no time
//      resolution beyond its envelope: expect errors of tens of samples at low SNR;
//   4. decay features (SpyLoc §V-B): the energy of the band-passed signal (Butterworth over the
//      tone band), smoothed by a centred moving average of smoothing_s, from the arrival to
//      duration_s + tail_s later; reference = its peak during the direct sound; T_x = time from the
//      END of the direct sound (arrival + duration_s: the paper's reverberation time counts "after the
//      direct sound source stops") to the first sample after the peak where the envelope is x dB
//      below the reference, x = 5, 10, ..., 30. Non-decreasing in x by construction; NaN when not
//      reached inside the window (noise). A fade-out makes the no-reverberation values slightly
//      negative (the direct sound already decays during its fade).
// Events per beep: AudioDetection (frame = fractional frame of the beep's first sample, snr_db =
// mean over the identity's tones of their peak power over floor, confidence = fraction of the
// identity's tones whose power exceeds 2×threshold, amplitude = matched-filter estimate of the beep
// amplitude a) followed by DecayFeatures (same frame and template_index).
// Latency: duration_s + tail_s + frame_s after the beep's start.
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "locus/plugin.hpp"

namespace locus::plugins::multitone {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

/// The decay-feature computation of step 4 on a smoothed energy envelope `energy` (linear power):
/// reference = max of energy[peak_from, peak_to), times counted from index `end_index`, in samples of
/// `sample_rate_hz`. Returns T5..T30 in seconds (NaN when not reached). [RT]
std::array<float, 6> decay_times(std::span<const double> energy, std::size_t peak_from, std::size_t peak_to,
                                 std::size_t end_index, double sample_rate_hz) noexcept;

}  // namespace locus::plugins::multitone
