// `multitone`: SpyLoc's beep receiver (paper 001, §II-A and §V): beeps made of a subset of a fixed
// set of tones (default 10 tones, 18000 + 250·k Hz); the subset is the beacon's identity, bit k of
// the identity (the low ten bits of its MAC address) switching tone f_k on.
//
// Why this design (issue 16): beacons beep in turn every 0.25-0.35 s, 60 ms each, with reverberant
// tails; the walker moves (Doppler up to ±0.4 %, i.e. ±75 Hz: a 60 ms coherent matched filter loses
// its gain); all tones are multiples of the 250 Hz grid, so any steady-state (full-beep) matched
// filter envelope repeats every 4 ms and the echoes alias into it. Only the beep's start (its fade-in
// transient) tells where the first path is. So:
//
// Per channel, streaming:
//   1. tone bank: every hop_s, the Hann-windowed Goertzel power of each tone over the last frame_s
//      (short frames: tolerant of Doppler). Per-tone noise floors learn only while no tone is active
//      and hold_s has passed since the last activity (so they never learn beeps or their tails),
//      or slowly during a long activity (> max_active_s: music, not a beep);
//   2. opening: a beep opens when the tone set becomes active (min_tones tones threshold_db above
//      their floors, or the summed normalised power beyond K + 7·sqrt(K)) after being inactive, or
//      when the summed power rises by rise_db within 3 hops (a beep on top of the previous one's
//      tail). A new body opens a beep's length after the last one opened (its own tail must not open
//      another), sooner on such a rise when the last body was a blip active for less than half a beep
//      (an interferer's burst just before a beep). A beep's body closes after two quiet hops or
//      duration_s + frame_s; closed beeps queue (up to 8) for analysis, so a new beep opens however
//      close the previous one;
//   2b. interferers (with candidate identities): a babble or music burst raises every tone alike and
//      keeps the set active for seconds, so bodies open on the burst back to back. Per hop and
//      candidate, the contrast of its tones over the others (mean dB over the floors) marks a beep's
//      start: over pattern_db for two hops after being under pattern_low_db. A body that showed no
//      candidate's pattern in its first hops yields to such a start (it is dropped, the beep gets its
//      own body), and a body may open on one within a beep's length after such a body. Inside a
//      long activity the floors learn in bodies too, each hop clipped at 6 dB over the floor;
//      digital silence (every tone exactly 0: a live stream before its source is connected)
//      teaches the floors nothing;
//   3. identity: per tone, the median tone-bank power over the body frames; tone k is on when it
//      exceeds its floor by identity_db (a mean over many frames, so lower than threshold_db) and
//      lies within relative_db of the strongest tone. With
//      `identities` (or from_scene: the scene's multitone emitters) the identity is the candidate
//      that best explains the levels: score = Σ_k ±(L_k − L_max/2) (+ for tones in the candidate),
//      L_k in dB over the floor; a measured mask that no candidate explains is rejected: every tone
//      within 10 dB of the strongest must be in the candidate unless it is within 6 dB of the median
//      of the tones outside it (the background: a burst), and the candidate's own tones must stand
//      6 dB over that background. When the body fails, its first half is tried (a burst that
//      starts during the beep covers the rest);
//   4. first path: onset statistic c(τ) = |<y, o(·−τ)>|² with o the identity's first 1/Δf seconds
//      (Δf the tone spacing: one period of the tone grid, cos and sin parts), by FFT over the search
//      range; its noise level from the 20 ms before the search range; the earliest lag where c
//      exceeds onset_threshold_db above that noise, and stays within 6 dB of it over at least half
//      of the next 3 onset lengths (a blip in the search window is not a beep's start), marks the
//      leading edge (so a weak diffracted first path, 20-30 dB under later echoes, is still found
//      when it clears the noise). When that finds nothing under a burst (the identity's background
//      over 3 dB, or the body opened while the tone set was already active and is not the last
//      reported beep's own tail: the noise reference holds the burst), a second pass at
//      weak_onset_threshold_db. Then a
//      least-squares fit of the beep's onset a·s(t−τ) (complex amplitude: cos and sin templates,
//      template zero before τ) over a window fixed for all candidates τ of a pass, ending
//      fit_window_s after the current estimate: maximise the projected (explained) energy over τ on a
//      1/8-sample grid (a coarse pass over ±1 grid period around the edge, then two recentred
//      passes), parabolic interpolation. A τ too late leaves the signal before it unexplained, a τ
//      too early misplaces the fade-in; only the first fit_window_s of the beep enter, before most
//      echoes (3 ms: floor and ceiling images arrive 1.3-2.5 ms after the direct path at 7-15 m);
//      then (max_paths > 1, default 3) the multipath onset fit (dsp::OnsetPathsFit, design there):
//      the single-path fit is pulled onto those images when they are strong and early (measured on
//      simulated walks: 27 % of the LoS beeps timed on the first image, err ≈ its extra delay; a
//      further 29 % biased by 1-5 samples), so the window from path_search_s before the single-path
//      estimate to path_window_s after it (5 ms: the fade-in) is fitted as up to max_paths delayed
//      beeps, each with a free complex amplitude, the template time-scaled by the beep's Doppler
//      (`doppler`: 1 + η, η from the phase advance of each identity tone between windows of two
//      grid periods over the body, power-weighted); the earliest path that is needed (removing it
//      loses more than path_threshold_db over the in-band noise power, measured on the noise
//      reference, plus path_tolerance of the window's energy) is the first path. With
//      `carrier_phase` its delay is refined by the carrier phase of its fitted amplitude (centroid of
//      the identity's tones), the carrier cycle nearest its envelope delay: the phase alone is good to
//      ~0.1 sample; what is left are whole-cycle slips (2.3 samples) where the envelope is > 1.1
//      samples off (noise: the onset holds little energy);
//   5. decay features (SpyLoc §V-B): the energy of the band-passed signal (Butterworth over the
//      tone band), smoothed by a centred moving average of smoothing_s, from the arrival to
//      duration_s + tail_s later; reference = its peak during the direct sound; T_x = time from the
//      END of the direct sound (arrival + duration_s) to the first sample after the peak where the
//      envelope is x dB below the reference, x = 5, 10, ..., 30. Non-decreasing in x; NaN when not
//      reached inside the window (noise).
// Events per beep: AudioDetection (frame = fractional frame of the beep's first sample (first path),
// snr_db = mean over the identity's tones of their level over floor, confidence = fraction of the
// identity's tones more than 2×threshold_db above their floors (with candidates: times the score
// margin over the runner-up, clipped to 0..1), and no more than the multipath fit's lobe-choice
// confidence (how firmly the first path clears its threshold), amplitude = onset fit amplitude
// estimate; with carrier_phase: envelope_frame = the first path's envelope delay, carrier_period =
// the carrier period in samples: `frame` is the carrier-phase zero nearest envelope_frame) followed by
// DecayFeatures (same frame and template_index).
// Latency: duration_s + tail_s + ~0.1 s after the beep's start.
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
