// Multipath least-squares fit of a known waveform's ONSET: where does its first path start?
//
// Why (issue 16, SpyLoc multitone beeps): a beep with a slow fade-in reaches an indoor receiver over
// its direct path and, tens of samples later, over the floor and ceiling images (at 3-15 m, 1-4 ms
// later; with walls reflecting 0.7 in amplitude those are only 3-6 dB weaker). A single-path fit of
// the onset (one delayed copy of the waveform with a free complex amplitude) over a window that holds
// both the direct path's fade-in and the echoes is pulled towards the echoes: measured on simulated
// walks, 27 % of the LoS beeps were timed > 20 samples late or early, the late ones on the first
// image (error / that image's extra delay: median 1.14), and a further 29 % off by 1-5 samples
// (docs/spyloc.md "First-path timing", tools/scripts/spyloc_timing_breakdown.py). The direct path's own fade-in
// carries too little energy before the echo arrives to be fitted alone at these SNRs.
//
// So the window is modelled as the sum of up to kMaxPaths delayed copies of the waveform,
//   y[n] ≈ Σ_p ( a_p·c(n − τ_p) + b_p·s(n − τ_p) ),   c, s = the waveform's cos and sin parts (zero
// before their start), a_p, b_p free (a complex amplitude per path: any phase shift on the path); with
// `known_phase` only b_p (the waveform's own phase, carrier-resolved). For given delays the amplitudes
// are linear least squares; the delays are searched greedily: starting from the caller's single-path
// estimate τ_0, the path that explains most of the remaining energy is added (a scan over
// [τ_0 − back, τ_0 + ahead] every scan_step samples, at least min_separation from the others, their
// amplitudes re-solved jointly; the fixed paths' Gram terms are computed once per scan), then every
// delay is refined in turn with the others fixed (±4 samples by 1/2, then 1/4, then 1/oversample
// sample; once after each added path and once at the end, also for a lone path), parabolic vertex at
// the end. A path is kept only when it explains more than the threshold (noise: `threshold`·σ², σ²
// the in-band noise power from noise_power(); model mismatch: `tolerance` of the window's energy).
// The FIRST path is the earliest one that is needed: removing it (the others' amplitudes re-fitted,
// delays kept) loses more than the threshold. min_separation (12 samples, about half the envelope's
// mainlobe for 2 kHz of tones) keeps one path from being split in two, which drags the first.
// Optionally (carrier_rad) the first path's delay is then taken from the carrier phase of its fitted
// amplitude: the phase zero nearest its envelope delay (phase_refine_near, locus/dsp/peak.hpp).
// Doppler: `time_scale` stretches the templates' time axis.
//
// Lobe-choice confidence: the first path's need (energy lost without it) over the threshold, as
// 1 − threshold/need in [0, 1]: near 0 when the earliest path barely clears the noise (the choice
// between "a weak direct path" and "noise before the echo" is doubtful), near 1 when it is firm.
//
// Cost: O(window·paths²) per evaluated delay set; a scan is (back + ahead)/scan_step sets. No
// allocation in fit() (work buffers reserved by reserve()).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace locus::dsp {

class OnsetPathsFit {
 public:
  static constexpr std::size_t kMaxPaths = 5;

  struct Options {
    std::size_t oversample = 8;     ///< template table points per sample (the 1/kOs delay grid)
    std::size_t max_paths = 3;      ///< <= kMaxPaths
    double back = 200.0;            ///< samples before τ_0 a path may start
    double ahead = 120.0;           ///< samples after τ_0 a path may start
    double min_separation = 12.0;   ///< samples between two paths' starts (about half the envelope mainlobe)
    double scan_step = 2.0;         ///< samples between scanned delays
    double threshold = 40.0;        ///< a path must explain threshold·σ² (σ² = noise power per sample)
    double tolerance = 0.02;        ///< ... plus this fraction of the window's energy (model mismatch)
    bool known_phase = false;       ///< one real amplitude per path (sine part only)
    double time_scale = 1.0;        ///< the received waveform is c(time_scale·(n − τ)): Doppler
                                    ///< (1 + radial speed / c, > 1 approaching), e.g. from the beep body
    double carrier_rad = 0.0;       ///< > 0: the first path's delay from its carrier phase (rad/sample:
                                    ///< the waveform's centroid), the cycle nearest its envelope delay
    bool known_phase_cycle = false; ///< with carrier_rad: the cycle chosen instead by the fit with the
                                    ///< first path's phase known (the waveform's own), the others free:
                                    ///< the candidates 0, ±1, ±2 carrier periods from the carrier-refined
                                    ///< delay, the one whose model explains most energy
    std::size_t cycle_paths = 4;    ///< ... with more echoes added on the noise threshold, up to this many paths
  };

  struct Result {
    std::size_t paths = 0;                  ///< paths kept (0: nothing fitted, invalid input)
    std::array<double, kMaxPaths> delay{};  ///< window sample units, sorted ascending
    std::array<double, kMaxPaths> amplitude{};
    double first = 0.0;       ///< the first needed path's delay (carrier-refined with carrier_rad)
    double envelope_first = 0.0;  ///< ... from the envelope (the free-phase fit) alone
    double first_amplitude = 0.0;
    double confidence = 0.0;  ///< lobe-choice confidence of `first`, [0, 1]
    double explained = 0.0;   ///< energy the final model explains
    double energy = 0.0;      ///< window energy
  };

  /// [RT] In-band noise power per sample σ² of a noise-only stretch y[0..n): the mean energy one
  /// path explains there (template stretches of a fifth of n at starts 16 samples apart), per fitted
  /// amplitude. Unlike the raw variance
  /// it counts only the noise the model can take for signal (coloured noise). 0 when n is too short.
  double noise_power(const float* y, std::size_t n, const float* c, const float* s, std::size_t fine_n,
                     const Options& o) noexcept;

  /// [main] Work space for windows of up to max_window samples.
  void reserve(std::size_t max_window);

  /// [RT] Fits y[0..n) with the templates c, s tabulated every 1/o.oversample sample from the
  /// waveform's start (fine_n points; zero beyond). tau0: the single-path estimate (window units).
  /// noise_var: noise power per sample of y. n beyond the reserved size is clipped.
  Result fit(const float* y, std::size_t n, const float* c, const float* s, std::size_t fine_n, double tau0,
             double noise_var, const Options& o) noexcept;

 private:
  // Energy explained by the paths at delays tau[0..p) (in 1/oversample units), least squares.
  double explained(const std::int64_t* tau8, std::size_t p, double* coef) const noexcept;
  // Best delay for path `which` within ±range8 (1/oversample units, step step8), others fixed.
  std::int64_t refine(std::int64_t* tau8, std::size_t p, std::size_t which, std::int64_t range8, std::int64_t step8,
                      double& best_e) noexcept;

  // The window (copied), templates and options of one call.
  void bind(const float* y, std::size_t n, const float* c, const float* s, std::size_t fine_n, const Options& o,
            double time_scale) noexcept;
  // The carrier cycle of the first path (delay: its carrier-refined delay, window samples) by the
  // known-phase fit; tau8 restored.
  double choose_cycle(std::int64_t* tau8, std::size_t p, std::size_t first, double delay, double carrier_rad) noexcept;
  // The columns of the paths at tau8[0..p) for window sample n into v (returns how many; any: a path
  // is on at n).
  std::size_t columns(const std::int64_t* tau8, std::size_t p, std::size_t n, double* v, bool* any) const noexcept;
  std::int64_t scan_add(const std::int64_t* tau8, std::size_t p, std::int64_t lo8, std::int64_t hi8, std::int64_t step8,
                        std::int64_t sep8, double& best_e) noexcept;

  // Template index of a (1/oversample) offset u under the Doppler time scale, rounded (no libm call).
  std::int64_t scaled(std::int64_t u) const noexcept {
    const double v = static_cast<double>(u) * scale_;
    return static_cast<std::int64_t>(v >= 0.0 ? v + 0.5 : v - 0.5);
  }

  std::vector<double> y_, fixed_;
  std::size_t n_ = 0;
  const float* c_ = nullptr;
  const float* s_ = nullptr;
  std::size_t fine_n_ = 0, os_ = 8;
  bool known_ = false;
  bool scaled_ = false;
  std::int64_t sep8_ = 0;  // min_separation in 1/oversample units (refinements keep it too)
  double scale_ = 1.0;
  std::size_t kp_ = kMaxPaths;  // the path given a known phase in explained() (kMaxPaths: none)
  double kp_cos_ = 1.0, kp_sin_ = 0.0;  // ... rotated by its sub-grid delay
};

}  // namespace locus::dsp
