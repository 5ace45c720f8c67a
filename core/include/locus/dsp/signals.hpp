// The acoustic and radio signals of the scene format (docs: ../shared/docs/scene-format.md, "Signals"),
// and their generators, bit for bit as the format defines them.
//
// One SignalSpec (locus/signal.hpp: the type, its parser and writer) describes one `emits` entry of a
// scene. The same generator feeds the simulator (which evaluates the continuous-time form at
// fractional, time-varying delays), the emitter (playback) and the detectors' matched-filter
// templates, so a template always matches what was sent.
//
//   lfm        a·w(t)·sin(2π(f0·t + (f1−f0)·t²/(2·duration)))          w: raised-cosine fade in and out
//   multitone  a·w(t)·(1/K)·Σ_k sin(2π·f_k·t)                          K tones, equal amplitudes a/K
//   gold       a·c[floor(n / chip_samples)]·cos(2π·carrier·n/fs)        c = ±1 (chip bit 0 → +1, 1 → −1)
//
// Gold codes: the preferred pairs of the format (octal characteristic polynomials), two Fibonacci
// LFSRs seeded all-ones give the m-sequences u and v; index 0 = u, 1 = v, k ≥ 2 = u XOR (v shifted
// cyclically left by k−2). The LFSR recurrence for a characteristic polynomial
// x^r + c_{r−1}x^{r−1} + … + c_1·x + 1 is a[n+r] = Σ_{i<r} c_i·a[n+i] (mod 2), a[0..r−1] = 1, and the
// sequence is a[0], a[1], …  (docs/signals.md shows the first chips of each pair).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "locus/signal.hpp"

namespace locus::dsp {

/// One `emits` entry: the typed signal description of the plugin API (locus/signal.hpp), named here
/// too because the generators below are its host-side half.
using SignalSpec = locus::SignalSpec;

/// Raised-cosine fade weight at time t of a signal of `duration_s` with fades of `fade_s` (0..1).
double fade_weight(double t_s, double duration_s, double fade_s) noexcept;

/// m-sequence of degree r from an octal characteristic polynomial (e.g. 045 for x^5+x^2+1), LFSR
/// seeded all-ones; bits 0/1, length 2^r − 1. Throws std::invalid_argument for a polynomial whose
/// degree is not r.
std::vector<std::uint8_t> m_sequence(int degree, unsigned poly_octal_value);

/// The format's preferred pair for degree r (octal values as written in the format, e.g. {045, 075}).
/// Throws std::invalid_argument for a degree the format does not list (5,6,7,9,10,11).
std::pair<unsigned, unsigned> gold_preferred_pair(int degree);

/// Gold code chips (bits 0/1) of a spec: `chips` when given, else generated from degree and index.
/// Throws std::invalid_argument with what is wrong (bad degree, index out of 0..2^r, bad chip string).
std::vector<std::uint8_t> gold_chips(const SignalSpec& spec);

/// Length in samples of the emitted signal at `sample_rate_hz` (lfm/multitone: round(duration·fs);
/// gold: chips·chip_samples). 0 for non-acoustic types.
std::size_t signal_length(const SignalSpec& spec, double sample_rate_hz);

/// Samples n = 0..signal_length−1 of the signal at n/fs. Throws std::invalid_argument for a
/// non-acoustic or unknown type, or a malformed spec.
std::vector<float> render_signal(const SignalSpec& spec, double sample_rate_hz);

/// Doppler timing instant of a signal (seconds after its start) for a matched filter timed by its
/// carrier phase (the `chirp` detector's `refine: phase`). A signal received over a range that changes
/// at rate rdot is time-scaled: its instant u arrives rdot/c * u later than its start does, and its
/// frequency is scaled too. For a linear chirp the two trade (the LFM's range-Doppler coupling: its
/// matched filter cannot tell a Doppler shift from a delay), and a phase-timed detector reports the
/// start late by rdot/c times the instants' mean weighted by their contribution to the phase: the
/// instantaneous frequency times the power, sum u f(u) w(u)^2 / sum f(u) w(u)^2. So
///   measured arrival = true arrival of the start + (rdot / c) * doppler_timing_instant_s(spec).
/// lfm 2->8 kHz over 40 ms: 0.60 of the duration; 8->2 kHz: 0.40; a signal of constant frequency
/// content (multitone, gold) is timed at its power centroid (half its duration when it has no fades).
/// 0 for non-acoustic types. Throws std::invalid_argument for a malformed gold spec (as signal_length).
double doppler_timing_instant_s(const SignalSpec& spec, double sample_rate_hz);

/// Continuous-time evaluator: the value of the emitted sound `t_s` seconds after its start, for
/// rendering it at fractional (and time-varying) delays. lfm and multitone are their exact closed
/// forms (0 outside [0, duration)). gold is defined only at the sample instants n/fs, so between them
/// it is what a sound card's DAC plays: the band-limited (Kaiser-windowed sinc, ±32 samples)
/// interpolation of the samples, exact at every n/fs; its support extends 32 samples beyond both ends
/// ([begin_s(), end_s())). Holding each chip instead would quantise the chip edges to whole samples
/// of the receiver and bias every arrival by up to a sample. Construct once (it precomputes what it
/// needs), then call value() at any t.
class SignalEvaluator {
 public:
  SignalEvaluator(const SignalSpec& spec, double sample_rate_hz);
  double value(double t_s) const noexcept;
  /// Nominal length of the signal (lfm/multitone: duration; gold: chips·chip_samples/fs).
  double duration_s() const noexcept { return duration_s_; }
  /// Where value() may be non-zero: [begin_s(), end_s()), begin_s() <= 0 <= duration_s() <= end_s().
  double begin_s() const noexcept { return begin_s_; }
  double end_s() const noexcept { return end_s_; }
  const SignalSpec& spec() const noexcept { return spec_; }

  static constexpr int kInterpolationHalfWidth = 32;  ///< gold: samples each side of t

 private:
  double interpolate(double t_s) const noexcept;

  SignalSpec spec_;
  double fs_;
  double duration_s_ = 0.0;
  double begin_s_ = 0.0;
  double end_s_ = 0.0;
  std::vector<float> samples_;         // gold: the sampled signal (render_signal)
  std::vector<double> window_table_;   // Kaiser window over |u| in [0, 1]
};

}  // namespace locus::dsp
