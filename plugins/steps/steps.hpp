// `steps`: step detection and stride length from a walker's IMU (papers 001 SpyLoc and 002 Montage).
//
// Signal: the vertical acceleration in the reference frame, a_v = (q·a_body).z − g, with q from the
// plugin's own AHRS (so the phone may be held in any orientation), resampled by linear interpolation
// onto a regular grid of `grid_rate_hz` (IMU rates jitter; the IIR filters need a fixed rate), then
// low-passed (Butterworth, `lowpass_order`, `lowpass_hz`; Montage: "passband below 5 Hz").
//
// mode `montage` (002 Sec. 4.1): on the low-passed signal, a maximum peak followed by a minimum
// valley whose connecting line crosses the "zero" (the running mean of the signal, time constant
// `mean_time_constant_s`) is a step, if peak − valley >= min_peak_valley_mps2 and the peak is at
// least min_step_s after the previous step. Hysteresis of a quarter of that threshold around the
// mean keeps noise from splitting a cycle. The step time is the peak (heel strike ≈ the vertical
// acceleration peak); it is emitted when the valley is confirmed (~half a step later). A peak that
// is both weak (peak−valley < secondary_ratio × the largest of the last 3 steps') and early (<
// secondary_early × their median interval) is a gait harmonic's mid-stride bump, not a step.
//
// mode `spyloc` (001 Sec. III): windows of m_max = max_step_s·rate samples of the low-passed signal
// are z-scored and matched against a one-step template (default: one cycle of a cosine starting at
// the peak, `template_s` long; or `template` values resampled) by open-end DTW: the prefix length m
// in [m_min, m_max] of lowest cost/(n+m) (locus/dsp/dtw.hpp). A cost below `dtw_threshold` is a
// step of m samples at the window start, and the next window starts m samples later (re-aligned on
// the largest sample within ±dtw_window_s, a deviation that keeps the windows locked on the peaks);
// otherwise the window moves by `search_hop_s` (the paper moves by m_max, which loses the step phase
// whenever a walk starts inside a window). Windows whose standard deviation is below
// min_accel_std_mps2 are not walking (SpyLoc gates on gyro activity for the same purpose); nor is
// a match whose own m samples have a lower deviation or do not start on their peak (the first
// sample at least 0.7 standard deviations above their mean): a window of standing still with a walk
// starting at its end would otherwise match once it is z-scored.
//
// Stride (the length of one step, heel strike to heel strike of the other foot):
//   `linear` (SpyLoc): s = stride_a·f + stride_b, f the step frequency;
//   `bounce` (Montage, inverted pendulum): the vertical acceleration band-passed at the walking
//     frequency ([3f/4, 3f/2], Eq. 5; a bank of band-passes 6 % apart runs all along and every band's
//     output is kept, so each step integrates the band nearest its own f, already settled — Montage
//     switches one filter when f moves, which left the strides after a switch short) is integrated twice over
//     the last step period (velocity and displacement with their mean / linear trend removed), the
//     bounce h = max − min displacement gives s = bounce_k · 2·sqrt(2·l·h − h²), l = leg_length_m.
// frequency_hz: 1 / time since the previous step of the same walk; for the first step of a walk,
// twice the peak-to-valley frequency (montage) or rate/m (spyloc).
//
// Everything is preallocated in configure(); process_imu never allocates [RT].
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::steps {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::steps
