// Structured acoustic interference for the simulator's noise bursts (NoiseModel::burst_kind): babble
// (several talkers) and music (notes and hi-hats), with energy up to 20 kHz.
//
// Why: white-noise bursts are the easy kind of interference for a chirp detector: no structure, no
// transients, a flat spectrum the detector's band-pass cuts by its bandwidth. Rooms have people
// talking (fricatives /s/, /f/, /sh/ reach 8-20 kHz, 50-150 ms each) and music (bright harmonic
// notes, hi-hats and cymbals: decaying noise transients with most of their energy above 8 kHz). The
// independent reference generator models "babble and music bursts with energy up to 20 kHz"
// (../shared/scenes/README.md). These are cheap synthetic stand-ins with those properties:
//
//   babble: 3-6 talkers; each a glottal pulse train at f0 ∈ [90, 250] Hz (±4 % slow vibrato)
//           through a one-pole low-pass (−6 dB/octave above 500-900 Hz), gated by syllables
//           (4-6 Hz raised-sine envelopes with random gaps), plus fricatives: 60-150 ms of
//           differentiated white noise (+6 dB/octave: energy up to fs/2), about 2 per second per
//           talker, 0.3-1.0 of the voiced level.
//   music:  a note every 0.15-0.4 s: a sawtooth at 130-1050 Hz (all harmonics, 1/k: up to fs/2)
//           with an exponential decay; a hi-hat on every beat (0.2-0.5 s): differentiated white
//           noise decaying with τ 15-60 ms, 0.5-1.5 of the note level.
//
// A waveform is normalised to unit RMS over the burst and faded in and out (20 ms raised cosine);
// the engine scales it to the burst level. Deterministic for the rng state.
#pragma once

#include <vector>

#include "locus/sim/rng.hpp"

namespace locus::sim {

enum class InterferenceKind { Babble, Music };

/// `frames` samples at fs_hz of babble or music, unit RMS. Throws std::invalid_argument for fs <= 0.
std::vector<double> synth_interference(InterferenceKind kind, std::size_t frames, double fs_hz, Rng& rng);

}  // namespace locus::sim
