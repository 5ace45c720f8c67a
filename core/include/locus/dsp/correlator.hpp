// Streaming FFT cross-correlation of audio against MANY templates at once (overlap-save).
//
// Why: matched filtering (chirps, Gold codes, multitone beeps) is the hot loop of every acoustic
// detector. Direct correlation costs L multiply-adds per output sample (L = template length, ~2000);
// overlap-save costs one forward FFT per window, shared by all templates, plus one spectrum multiply
// and one (real) or two (analytic) inverse FFTs per template, i.e. O(log N) per output sample.
//
// Definition. For template h[0..L-1] and input x (samples counted from the last reset), output i of a
// window is the correlation at lag k = window_start() + i:
//
//     y[k] = sum_{j=0}^{L-1} x[k + j] * h[j]
//
// so a copy of the template that STARTS at sample k produces its peak at output k. With
// `analytic = true` the correlator also produces the Hilbert transform of y (the product spectrum
// with the negative frequencies zeroed, i.e. -j*sign(f) applied), so that z[k] = y[k] + j*H{y}[k] is
// the analytic correlation: |z| is the envelope, arg z is ~0 at the true delay and turns at the
// template's centre frequency around it (see peak.hpp, phase_refine()).
//
// Streaming: the correlator keeps, per channel, a window of N = fft_size() input samples. push()
// appends samples until the window is full; then the caller runs transform() (forward FFT of that
// window, spectrum() becomes valid; a pre-screen may inspect it), correlate(t) for the templates it
// wants (outputs valid for hop() = N - L_max + 1 lags), and advance() (keeps the last L_max - 1
// samples). Every output lag is produced exactly once; nothing depends on how the input is cut into
// blocks. flush() correlates a partly filled window (zero padded) for the lags whose template lies
// entirely in the samples pushed so far (end of stream, or before a gap).
//
// Real time: configure() plans every FFT through the host's FftPlanner and allocates every buffer;
// push/transform/correlate/advance/flush/reset never allocate, lock or block ([RT]).
#pragma once

#include <complex>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "locus/fft.hpp"

namespace locus::dsp {

class Correlator {
 public:
  struct Options {
    std::size_t channels = 1;   ///< independent input streams sharing the templates and plans
    std::size_t fft_size = 0;   ///< N; 0 = automatic (bit_ceil(4 * longest template), at least 256)
    bool analytic = true;       ///< also produce the Hilbert (quadrature) part of every output
  };

  Correlator();
  ~Correlator();
  Correlator(Correlator&&) noexcept;
  Correlator& operator=(Correlator&&) noexcept;

  /// [main] Plans the FFTs and precomputes the template spectra (conjugated). Throws
  /// std::invalid_argument when there is no template, a template is empty, a fixed fft_size is not
  /// larger than the longest template, or channels == 0.
  void configure(const std::vector<std::vector<float>>& templates, FftPlanner& planner, const Options& options);

  std::size_t fft_size() const noexcept { return n_; }
  /// Output lags produced per full window: N - L_max + 1.
  std::size_t hop() const noexcept { return hop_; }
  std::size_t channels() const noexcept { return channels_; }
  std::size_t template_count() const noexcept { return templates_; }
  std::size_t template_length(std::size_t t) const noexcept { return lengths_[t]; }
  std::size_t max_template_length() const noexcept { return lmax_; }
  /// Energy sum h[j]^2 of template t (the peak of its autocorrelation).
  double template_energy(std::size_t t) const noexcept { return energy_[t]; }
  /// Spectral centroid of template t's energy spectrum |H(f)|^2 in radians per sample
  /// (2 pi f_c / fs): the rate at which the phase of the analytic correlation turns around its peak.
  double centroid_omega(std::size_t t) const noexcept { return centroid_[t]; }
  bool analytic() const noexcept { return analytic_; }

  /// [RT] Appends up to n samples (stride between consecutive samples: `stride` floats) to channel
  /// ch's window; returns how many were taken (fewer than n when the window became full).
  std::size_t push(std::size_t ch, const float* x, std::size_t n, std::size_t stride = 1) noexcept;
  /// [RT] True when channel ch's window holds N samples (transform/correlate/advance are due).
  bool full(std::size_t ch) const noexcept { return fill_[ch] == n_; }
  /// Samples currently in channel ch's window.
  std::size_t filled(std::size_t ch) const noexcept { return fill_[ch]; }
  /// Channel ch's window: sample i is input sample window_start(ch) + i (filled(ch) of them), so the
  /// samples under output i are samples(ch)[i .. i + L - 1]. Valid until the next push/advance.
  const float* samples(std::size_t ch) const noexcept { return &window_[ch * n_]; }
  /// Lag (input sample index since the last reset) of output 0 of channel ch's current window.
  std::uint64_t window_start(std::size_t ch) const noexcept { return start_[ch]; }

  /// [RT] Forward FFT of channel ch's window (zero padded past filled()). spectrum() then holds its
  /// N/2 + 1 bins until the next transform (of any channel).
  void transform(std::size_t ch) noexcept;
  const std::complex<float>* spectrum() const noexcept { return spec_; }
  std::size_t bins() const noexcept { return n_ / 2 + 1; }

  /// [RT] Correlates the last transformed window with template t. real(t)[i] (and imag(t)[i] when
  /// analytic) is the output at lag window_start + i, for i < hop() (after a full window) or
  /// i < valid lags (after flush()).
  void correlate(std::size_t t) noexcept;
  const float* real(std::size_t t) const noexcept { return &out_re_[t * n_]; }
  const float* imag(std::size_t t) const noexcept { return analytic_ ? &out_im_[t * n_] : nullptr; }

  /// [RT] Drops the first hop() samples of a full window (keeps the last L_max - 1).
  void advance(std::size_t ch) noexcept;

  /// [RT] For a partly filled window: transform() it zero padded and return how many lags have
  /// their whole (longest) template inside the pushed samples (0 when none); the caller then runs
  /// correlate() and uses that many outputs. Call reset() afterwards (the window is consumed).
  std::size_t flush(std::size_t ch) noexcept;

  /// [RT] Forgets channel ch's samples (a gap in the stream): the next pushed sample is lag
  /// `next_index` (default 0) of the new segment.
  void reset(std::size_t ch, std::uint64_t next_index = 0) noexcept;

 private:
  std::size_t n_ = 0, hop_ = 0, lmax_ = 0, channels_ = 0, templates_ = 0;
  bool analytic_ = true;
  std::unique_ptr<RealFft> fft_;
  std::vector<std::size_t> lengths_;
  std::vector<double> energy_;
  std::vector<double> centroid_;
  std::vector<std::complex<float>> tmpl_spec_;  // templates x bins, conj(H)/N (normalised)
  std::vector<float> window_;                   // channels x N
  std::vector<std::size_t> fill_;
  std::vector<std::uint64_t> start_;
  std::vector<std::complex<float>> spec_buf_;   // bins
  std::vector<std::complex<float>> prod_;       // bins
  std::vector<float> out_re_, out_im_;          // templates x N
  std::complex<float>* spec_ = nullptr;
};

/// Direct time-domain correlation y[k] = sum_j x[k+j] h[j] for k = 0..n_x - n_h (reference and
/// baseline; O(n_x * n_h)). `out` must hold n_x - n_h + 1 values; does nothing when n_x < n_h.
void correlate_direct(const float* x, std::size_t n_x, const float* h, std::size_t n_h, float* out) noexcept;

}  // namespace locus::dsp
