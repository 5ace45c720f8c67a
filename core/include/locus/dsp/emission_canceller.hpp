// Own-emission canceller: finds a device's own (known) emission in its recording, fits it, subtracts it.
//
// Why: a device that emits hears itself through its own speaker a few centimetres from its
// microphones, tens of dB above anyone else (TUM: the working pair's chirps overlap under loose sync;
// Montage: every user emits a Gold code while listening to the others). Matched filters for the
// OTHER signals then see the own emission's cross-correlation terms (~1/sqrt(BT) of its peak, i.e.
// still far above a weak arrival) and its energy ruins every normalised statistic (correlation
// coefficient, Pearson). A mask (zeroing the own emission's span) would delete the overlapping
// arrival with it. This canceller does fitted subtraction instead: the recording around the own
// emission is modelled as the known template h passed through a short FIR g (the speaker -> mic
// path: gain, fractional delay, transducer responses and the earliest reflections),
//
//     x[n] ~ sum_{i=-P}^{Q} g_i h[n - k - i]      (k = integer start of the emission),
//
// g is the least-squares fit, and the model is subtracted sample by sample. Other signals survive
// (their projection onto the few shifted copies of h is tiny, ~M/(BT) of their energy).
//
// Method, per channel and per window (overlap-save, dsp::Correlator with the template padded by P
// zeros before and Q after, so that every lag of a window has the whole fit support inside it):
//   1. matched filter of the padded template (decimated complex baseband first; the full-rate
//      analytic correlation only when something may cross the threshold);
//   2. candidates: the strongest lag with |z|^2 above threshold_db over the window's noise power
//      (median |z|^2 / ln 2) and correlation coefficient |z| / (|h| |x|) >= min_coefficient (a
//      strong, clean match: the own emission; anything else is left alone); lags within one padded
//      template of a candidate are not candidates again (up to max_per_window per window);
//   3. fit: the normal equations (R + lambda r0 I) g = b. R_ij = r_hh(i - j) is the template's
//      autocorrelation (every shifted copy lies wholly in the support), so R's Cholesky factor is
//      computed once in configure(); b_i = sum_j x[k + i + j] h[j] is a direct sum (M x L);
//   4. subtraction of sum_i g_i h[n - k - i] over [k - P, k + L + Q) in the correlator's window; the
//      samples the next window keeps are already clean.
// A window's first hop() samples are then final (no later emission can reach them): output().
// Latency: up to one window (fft_size samples). Signal-agnostic: any template (LFM chirp, Gold-code
// BPSK, multitone); the FIR spans fractional delays and transducer responses within the template's band.
// Limits: the model is linear and time-invariant over one emission: a clipped self-recording, or a
// speaker->mic path that changes within an emission, leaves a residual (reported per fit).
//
// Real time: configure() plans the FFTs (host FftPlanner) and allocates everything; push, process,
// advance, flush and reset never allocate, lock or block ([RT]).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "locus/dsp/correlator.hpp"

namespace locus {
class FftPlanner;
}

namespace locus::dsp {

class EmissionCanceller {
 public:
  struct Options {
    std::size_t channels = 1;
    std::size_t fft_size = 0;         ///< 0 = bit_ceil(4 x padded template length), at least 256
    std::size_t taps_before = 4;      ///< P: FIR taps before the integer start (fractional delay, pre-ringing)
    std::size_t taps_after = 24;      ///< Q: taps after it (transducer responses, earliest reflections)
    double threshold_db = 20.0;       ///< matched-filter peak power over its noise power
    double min_coefficient = 0.5;     ///< |z| / (|h| |x|) of a match to cancel (1 = the template alone)
    double regularization = 1e-6;     ///< lambda: Tikhonov weight relative to sum h^2 (out-of-band taps)
    std::size_t max_per_window = 4;   ///< emissions cancelled per window at most
  };

  /// One cancelled emission.
  struct Fit {
    std::uint64_t start = 0;      ///< integer start k of the template (input index since the last reset)
    double peak_lag = 0.0;        ///< envelope peak of the matched filter (fractional, same index)
    double amplitude = 0.0;       ///< received amplitude relative to the template (|z_peak| / sum h^2)
    double coefficient = 0.0;     ///< |z| / (|h| |x|) at the peak
    double cancelled_db = 0.0;    ///< energy over the support before / after the subtraction
  };

  EmissionCanceller();
  ~EmissionCanceller();
  EmissionCanceller(EmissionCanceller&&) noexcept;
  EmissionCanceller& operator=(EmissionCanceller&&) noexcept;

  /// [main] Plans the FFTs, factors the fit's normal equations and allocates every buffer. Throws
  /// std::invalid_argument on an empty template, channels == 0, a fixed fft_size not larger than the
  /// padded template, or a non-finite / negative option.
  void configure(const std::vector<float>& h, FftPlanner& planner, const Options& options);

  const Options& options() const noexcept { return opt_; }
  std::size_t fft_size() const noexcept { return corr_.fft_size(); }
  /// Final samples per full window.
  std::size_t hop() const noexcept { return corr_.hop(); }
  std::size_t template_length() const noexcept { return len_; }
  std::size_t taps() const noexcept { return taps_; }

  /// [RT] Appends up to n samples to channel ch's window; returns how many were taken (fewer when the
  /// window became full: call process() then advance()).
  std::size_t push(std::size_t ch, const float* x, std::size_t n) noexcept { return corr_.push(ch, x, n); }
  /// [RT] Channel ch's window is full.
  bool full(std::size_t ch) const noexcept { return corr_.full(ch); }
  /// [RT] Finds, fits and subtracts the own emissions of channel ch's full window; returns the number
  /// of final samples (hop()), readable at output(ch) until advance(ch).
  std::size_t process(std::size_t ch) noexcept;
  /// First final sample of channel ch (input index output_start(ch) + i for output(ch)[i]).
  const float* output(std::size_t ch) const noexcept { return corr_.samples(ch); }
  std::uint64_t output_start(std::size_t ch) const noexcept { return corr_.window_start(ch); }
  /// [RT] Drops the final samples of a processed full window.
  void advance(std::size_t ch) noexcept { corr_.advance(ch); }
  /// [RT] End of the contiguous input (end of stream, or a gap): cancels the emissions wholly inside
  /// the pushed samples and returns how many samples (all of them) are final at output(ch). Call
  /// reset() afterwards.
  std::size_t flush(std::size_t ch) noexcept;
  /// [RT] Forgets channel ch's samples; the next pushed sample has input index next_index.
  void reset(std::size_t ch, std::uint64_t next_index = 0) noexcept;

  /// Emissions cancelled on channel ch since configure() (a counter), and the most recent ones
  /// (up to kHistory, newest last; recent(ch, 0) = the newest).
  static constexpr std::size_t kHistory = 16;
  std::uint64_t cancelled(std::size_t ch) const noexcept { return count_[ch]; }
  const Fit& recent(std::size_t ch, std::size_t age) const noexcept {
    return history_[ch * kHistory + (count_[ch] - 1 - age) % kHistory];
  }

 private:
  void search(std::size_t ch, std::size_t lags) noexcept;
  static bool median_at_least(const float* x, std::size_t n, std::size_t stride, float v) noexcept;
  double median(const float* x, std::size_t n, std::size_t stride) noexcept;
  void fit_and_subtract(std::size_t ch, std::size_t i0, double pz, double coefficient) noexcept;

  Options opt_;
  Correlator corr_;
  std::size_t len_ = 0, taps_ = 0, padded_ = 0;
  double energy_ = 0.0;
  double threshold_ = 100.0, min_rho2_ = 0.25;
  std::vector<double> h_;         // the template
  std::vector<float> hf_;         // the template in float (the subtraction)
  std::vector<double> wd_;        // the fit support in double (padded length)
  std::vector<double> chol_;      // taps x taps lower Cholesky factor of R + lambda r0 I
  std::vector<double> cholt_;     // its transpose (the back substitution reads rows)
  std::vector<double> b_, g_;     // taps
  std::vector<float> pow_, sorted_;
  std::vector<std::uint8_t> masked_;  // per lag of a window: not a candidate
  std::vector<std::uint64_t> count_;
  std::vector<Fit> history_;
};

}  // namespace locus::dsp
