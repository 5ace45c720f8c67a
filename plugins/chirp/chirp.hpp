// `chirp`: LFM matched-filter detector with the earliest-path rule (TUM, Sec. VII-C; AMIL, Sec. III-C).
//
// Per channel and per template (an LFM chirp rendered by dsp::render_signal exactly as the scene
// format defines it):
//   1. Analytic matched filter, streaming: dsp::Correlator (overlap-save; one forward FFT per window
//      shared by all templates, two real inverse FFTs per template) gives z[k] = y[k] + j H{y}[k],
//      y[k] = sum_j x[k+j] h[j]; a chirp STARTING at frame k peaks at lag k.
//   2. Pre-screen (AMIL's FFT trick, `prescreen`): a window whose in-band power per bin, relative to
//      out-of-band and to a baseline learnt on quiet windows, stays below `prescreen_db` is not
//      correlated at all (dsp::BandPrescreen).
//   3. Noise: P = max(tracked, median(|z|^2 over the window) / ln 2) (|z|^2 of noise is exponential,
//      its median is P ln 2; the median ignores the few lags a chirp occupies). The tracked value
//      follows windows without a threshold crossing, so a loud chirp's range sidelobes never
//      lower the detection threshold and a rising noise floor raises it at once.
//   4. Event: opens at the first lag with |z|^2 > P * 10^(threshold_db/10) (and at least
//      `min_spacing_s` after the previous detection) and collects lags until one template length
//      (plus a mainlobe guard) after its strongest lag, and at least `earliest_window_s` after the
//      opening: the range sidelobes of a strong chirp, and its cross-terms with other templates,
//      reach a template length before its mainlobe and may open the event early. It then reports the
//      EARLIEST local maximum of |z| within `earliest_window_s` before the strongest one that is
//      >= earliest_ratio * the strongest |z| and above the threshold (TUM: "the earliest peak instead
//      of the highest peak"; AMIL: "the first sidelobe that exceeds a threshold ratio to the maximum
//      peak"). A later, stronger echo does not hide the direct path.
//   5. Timing: Gaussian (log-parabolic) fit of |z| around that peak picks the carrier cycle; the phase
//      of z at the nearest lag refines it (refine = "phase", dsp::phase_refine_near; "gaussian" and
//      "parabolic" use the envelope alone). AudioDetection::frame = the fractional stream frame of the
//      chirp's START; snr_db = 10 log10(|z_peak|^2 / P) (envelope peak power over correlation noise
//      power; = received energy over 2 sigma^2 for white noise); amplitude = |z_peak| / sum h^2 (the
//      received chirp's amplitude relative to the template's); confidence = 1 - 10^(-(snr_db -
//      threshold_db)/10).
//   6. Own emission (`cancel_own`, TUM's overlapping exchanges): when the device emits one of the
//      templates itself (DeviceGeometry::emits) and no other source emits that signal, the audio
//      of each channel also goes through dsp::EmissionCanceller (matched filter, least-squares FIR fit
//      of the own emission, fitted subtraction) into a second correlator channel; the own template is
//      searched in the raw audio, every other template in the cleaned audio. Latency: + up to one
//      canceller window.
//   7. Wrong template: an event (or an earlier path candidate) of template X whose power is within
//      6 dB of the range cross-correlation that a strong arrival of another template Y searched in the
//      same audio predicts there (|xcorr(h_Y, analytic h_X)|^2 tabulated in configure, scaled by Y's
//      peak power) is Y's cross-term, not an arrival of X: the event is dropped / the candidate skipped.
// Streaming: every lag is produced by exactly one window, so detections that straddle block or window
// boundaries are found exactly once and nothing depends on the block size. Latency: up to one FFT
// window (fft_size frames) plus one template length after the strongest path.
// Gaps: a block with lost_before > 0 (or a first_frame that does not follow the previous block)
// first correlates what is left of the contiguous audio (zero padded, only lags whose whole template
// lies before the gap), reports events still open, then restarts the correlator, the events and the
// minimum spacing from the first frame after the gap. The noise estimate and pre-screen baselines are
// kept (a gap does not change the noise). finish() does the same at the end of the stream.
// Real time: everything (FFT plans, windows, rings, scratch) is allocated in configure().
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::chirp {

/// The `chirp` detector plugin (static storage).
const locus_plugin_descriptor* descriptor();
/// Its parameter schema.
const ParamSchema& schema();

}  // namespace locus::plugins::chirp
