// Transducer (speaker / microphone) magnitude responses for the simulator: the Butterworth band edges
// and equaliser sections of a BandLimit (engine.hpp) as biquads, and random per-device responses.
//
// Why: no two phones sound alike. A real speaker and microphone have a ripple of a dB or two across
// the band and roll off near 20 kHz, right where AMIL's 18-22 kHz chirp lives, so the correlation
// peak a detector sees is not the ideal chirp's; the independent reference generator draws such
// responses per device (../shared/scenes/README.md: "ripple ±1-1.5 dB, roll-off near 20 kHz").
//
// A random response = the given Butterworth edges + `ripple_sections` RBJ peaking sections (centres
// log-uniform over [ripple_lo_hz, 12 kHz] plus two uniform in [12 kHz, ripple_hi_hz], Q in
// [0.7, 3], gains scaled so that the largest |ripple| over [ripple_lo_hz, ripple_hi_hz] is a
// level drawn uniformly in [ripple_min_db, ripple_max_db]) + a high shelf of −[rolloff_min_db,
// rolloff_max_db] dB above a corner drawn in [rolloff_min_hz, rolloff_max_hz]. Every section is a
// causal IIR biquad (minimum-phase-like small group delays: < 1 sample in the chirp band).
#pragma once

#include <vector>

#include "locus/dsp/iir.hpp"
#include "locus/sim/engine.hpp"
#include "locus/sim/rng.hpp"

namespace locus::sim {

/// Biquads of a response (Butterworth edges, then the equaliser sections) at sample rate fs.
/// Throws std::invalid_argument for a section frequency outside (0, fs/2) or q <= 0.
std::vector<dsp::Biquad> design_response(const BandLimit& response, double fs_hz);

/// Magnitude of the response at f, in dB.
double response_db(const BandLimit& response, double freq_hz, double fs_hz);

/// The spread of random per-device responses (defaults: the reference generator's phone).
struct TransducerSpread {
  double ripple_min_db = 1.0, ripple_max_db = 1.5;  ///< largest |ripple| of a device, drawn uniformly
  int ripple_sections = 6;                          ///< peaking sections (>= 2)
  double ripple_lo_hz = 150.0, ripple_hi_hz = 20000.0;
  double rolloff_min_hz = 19500.0, rolloff_max_hz = 21000.0;  ///< high-shelf corner
  double rolloff_min_db = 3.0, rolloff_max_db = 8.0;          ///< high-shelf depth (attenuation)
  bool rolloff = true;
};

/// `edges` (its Butterworth band limits; its eq is replaced) with a random ripple and roll-off drawn
/// from `rng`. Deterministic for the rng state.
BandLimit random_transducer_response(const BandLimit& edges, const TransducerSpread& spread, double fs_hz, Rng& rng);

/// Largest |ripple| in dB of the PEAKING sections alone over [lo_hz, hi_hz] (400 log-spaced points).
double ripple_peak_db(const BandLimit& response, double lo_hz, double hi_hz, double fs_hz);

}  // namespace locus::sim
