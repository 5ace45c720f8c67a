// `goldcode`: the Montage receiver (paper 002, §3.2.3) for Gold-coded BPSK tones of several users
// that overlap in time.
//
// Signal (docs/scene-format.md "gold"): a·c[n / chip_samples]·cos(2π·carrier·n/fs), c = ±1, one code
// of the degree-r family per user. Per channel, per sample, streaming:
//   1. band-pass around the carrier: Butterworth, `filter_order` prototype, carrier ± band_width_hz/2;
//   2. coherent I/Q demodulation: multiply by e^{−j2π·carrier·n/fs} on the stream's absolute frame
//      counter n (phase continuous across blocks), low-pass (windowed-sinc FIR) and decimate by D so
//      that decimated sample m is frame m·D;
//   3. correlation with each user's code: the template is the user's signal (dsp::render_signal)
//      passed through the same steps 1-2 offline, so filter distortion is matched; complex
//      correlation by FFT overlap-save at the decimated rate (|·| is independent of the unknown
//      carrier phase of the propagation delay); with the Doppler search every code has one template
//      per Doppler version (time-compressed, `doppler_*`), the window's complex spectrum is formed
//      once per hop and each version costs one complex multiply per bin plus one complex inverse FFT
//      (vector kernels in locus/dsp/simd.hpp); ρ per lag is the best version's;
//   4. Pearson normalisation: ρ(d) = |Σ_k (x[d+k] − x̄)·conj(T[k] − T̄)| / sqrt(Σ|x − x̄|² · Σ|T − T̄|²),
//      the window sums from exact prefix sums; 0..1, insensitive to level and to the other users;
//   5. candidates per code: runs of lags with ρ ≥ min_pearson_coarse and ρ²/mean ρ² ≥ min_snr_db;
//      the maxima of up to 4 runs within one code length after the first are kept (a weak user's
//      true peak can be lower than a strong user's cross-correlation sidelobe);
//   6. joint refinement at the full rate (successive interference cancellation): for the peak and
//      every other code whose emission overlaps it (open candidates and recent detections),
//      strongest first, 2 rounds: subtract the others' current reconstructions, hill-climb the
//      envelope of the analytic matched filter (band-passed template + its Hilbert transform) from
//      the estimate within ±(D/2 + 3) frames (±1 once refined), parabolic interpolation,
//      least-squares in-phase/quadrature amplitudes. A residual > 60 dB below the audio counts as
//      empty (refined Pearson 0: only the others' float rounding is left).
//      The refined Pearson coefficient of the residual with the template picks among the kept
//      peaks and must reach min_pearson: cross-correlation sidelobes fall to ~0.05 once the user
//      that caused them is subtracted, true users stay at 0.7..1 (measured in the tests).
// Every code is searched independently in every hop, so all users are found when their tones
// overlap; the cross-correlation of Gold codes bounds what the others add.
//
// Output: one AudioDetection per found code emission: template_index = the index in `codes` (not the
// code's family index), frame = fractional stream frame of the code's first sample,
// snr_db = 10·log10(ρ² / mean ρ² of that code over the surrounding hop) (coarse peak over
// correlation noise), confidence = the refined Pearson coefficient (step 6), amplitude =
// least-squares estimate of `a` of the received tone (matched filter output / template energy).
// Latency: about (code length + FFT hop) at the decimated rate, ~0.3 s with the defaults.
// Overrun (lost_before > 0 or a frame-counter jump): a final candidate is emitted, then all
// per-channel state restarts on the new frame grid.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::goldcode {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::goldcode
