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
// wants (outputs valid for hop() = N - L_max + 1 lags, or fewer: Options::hop), and advance() (keeps
// the last N - hop() samples). Every output lag is produced exactly once; nothing depends on how the input is cut into
// blocks. flush() correlates a partly filled window (zero padded) for the lags whose template lies
// entirely in the samples pushed so far (end of stream, or before a gap).
//
// Real time: configure() plans every FFT through the host's FftPlanner and allocates every buffer;
// push/transform/correlate/advance/flush/reset never allocate, lock or block ([RT]).
#pragma once

#include <algorithm>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <vector>

#include "locus/fft.hpp"

namespace locus::dsp {

/// std::allocator with 64-byte alignment (FFT plans run directly on these buffers, see RealFft).
template <class T>
struct AlignedAllocator {
  using value_type = T;
  AlignedAllocator() = default;
  template <class U>
  AlignedAllocator(const AlignedAllocator<U>&) noexcept {}
  T* allocate(std::size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), std::align_val_t{64})); }
  void deallocate(T* p, std::size_t) noexcept { ::operator delete(p, std::align_val_t{64}); }
  template <class U>
  bool operator==(const AlignedAllocator<U>&) const noexcept { return true; }
};
template <class T>
using AlignedVector = std::vector<T, AlignedAllocator<T>>;

class Correlator {
 public:
  struct Options {
    std::size_t channels = 1;   ///< independent input streams sharing the templates and plans
    std::size_t fft_size = 0;   ///< N; 0 = automatic (bit_ceil(4 * longest template), at least 256)
    bool analytic = true;       ///< also produce the Hilbert (quadrature) part of every output
    bool baseband = false;      ///< also plan the decimated complex-baseband outputs (see correlate_baseband)
    /// Output lags per window; 0 (and anything larger) = N - L_max + 1, the plain overlap-save hop.
    /// A smaller hop overlaps the windows (advance() keeps N - hop samples) and outputs each window's
    /// LAST hop valid lags: a window is due after every `hop` new samples, so a lag is output at most
    /// hop samples after its template became whole, for (N - L_max + 1) / hop times the work. hop()
    /// may be up to 3 lower than asked (outputs stay on the baseband grid). Everything below
    /// (window_start, samples, real/imag, baseband, flush) is then relative to the first OUTPUT lag.
    std::size_t hop = 0;
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
  /// Output lags produced per full window: N - L_max + 1, or Options::hop when smaller.
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
  std::size_t filled(std::size_t ch) const noexcept { return fill_[ch] - off_; }
  /// Channel ch's window: sample i is input sample window_start(ch) + i (filled(ch) of them), so the
  /// samples under output i are samples(ch)[i .. i + L - 1]. Valid until the next push/advance.
  const float* samples(std::size_t ch) const noexcept { return &window_[ch * n_ + off_]; }
  /// [RT] The same window, writable: a caller may change samples after transform() (e.g. subtract a
  /// known signal, dsp::EmissionCanceller); what advance() keeps carries into the next window.
  float* samples_mutable(std::size_t ch) noexcept { return &window_[ch * n_ + off_]; }
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
  /// Overlapped windows (Options::hop): how many lags BEFORE output 0 the last correlate() of channel
  /// ch produced as well: real(t)[-i], imag(t)[-i] (and baseband(t)[-i / D]) for 0 < i <= lookback(ch)
  /// are lags earlier windows already output (the same values), back to the last reset. A statistic
  /// over a window's whole span (a noise median) can use them. 0 without Options::hop.
  std::size_t lookback(std::size_t ch) const noexcept {
    return static_cast<std::size_t>(std::min<std::uint64_t>(off_, start_[ch] - segment_[ch]));
  }
  const float* real(std::size_t t) const noexcept { return &out_re_[t * n_ + off_]; }
  const float* imag(std::size_t t) const noexcept { return analytic_ ? &out_im_[t * n_ + off_] : nullptr; }

  /// Complex-baseband decimation D of template t: 4 or 2 when its band (bins within -40 dB of its
  /// spectral peak) fits in N/D bins of the analytic spectrum, else 1 (no baseband output; also 1
  /// without Options::baseband).
  std::size_t baseband_decimation(std::size_t t) const noexcept { return bb_dec_.empty() ? 1 : bb_dec_[t]; }
  /// For template t alone (no noise): the smallest |z|^2 at a decimated lag relative to the peak
  /// |z|^2, i.e. the worst loss of a peak that falls between two decimated lags (D/2 lags off).
  double baseband_peak_ratio(std::size_t t) const noexcept { return bb_ratio_.empty() ? 1.0 : bb_ratio_[t]; }
  /// [RT] Analytic correlation of the last transformed window with template t at every D-th lag, by
  /// an N/D-point complex inverse FFT of the template's band (frequency-domain decimation, exact for
  /// the bins in the band): |baseband(t)[m]| = |z[window_start + m D]| for m < N/D (the phase is
  /// turned by a linear term; use baseband_lag() for the true value). Requires D > 1.
  void correlate_baseband(std::size_t t) noexcept;
  const std::complex<float>* baseband(std::size_t t) const noexcept { return bb_fft_[t]->output() + off_ / bb_dec_[t]; }
  /// [RT] The analytic output z = real + j imag at lag window_start + i from the last
  /// correlate_baseband(t) (direct sum over the N/D band bins, O(N/D)).
  std::complex<float> baseband_lag(std::size_t t, std::size_t i) const noexcept;

  /// [RT] Drops the first hop() samples of a full window (keeps the last N - hop(), i.e. L_max - 1
  /// without Options::hop).
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
  std::size_t off_ = 0;  // overlapped windows (Options::hop): outputs start this many lags in
  bool analytic_ = true;
  std::unique_ptr<RealFft> fft_;
  std::vector<std::size_t> lengths_;
  std::vector<double> energy_;
  std::vector<double> centroid_;
  std::vector<std::complex<float>> tmpl_spec_;  // templates x bins, conj(H)/N (normalised)
  AlignedVector<float> window_;                 // channels x N
  std::vector<std::size_t> fill_;
  std::vector<std::uint64_t> start_;
  std::vector<std::uint64_t> segment_;  // per channel: first lag since the last reset
  AlignedVector<std::complex<float>> spec_buf_;  // bins
  AlignedVector<std::complex<float>> prod_, prod_im_;  // bins (product, and its Hilbert part)
  AlignedVector<float> out_re_, out_im_;         // templates x N
  std::complex<float>* spec_ = nullptr;
  std::vector<std::size_t> bb_dec_, bb_k0_;          // per template: decimation, first band bin
  std::vector<double> bb_ratio_;
  std::vector<std::vector<std::complex<float>>> bb_tw_;  // per template: twiddles of lag hop - 1
  std::vector<std::unique_ptr<ComplexFft>> bb_fft_;  // per template (N/D points; input = band bins)
};

/// Direct time-domain correlation y[k] = sum_j x[k+j] h[j] for k = 0..n_x - n_h (reference and
/// baseline; O(n_x * n_h)). `out` must hold n_x - n_h + 1 values; does nothing when n_x < n_h.
void correlate_direct(const float* x, std::size_t n_x, const float* h, std::size_t n_h, float* out) noexcept;

}  // namespace locus::dsp
