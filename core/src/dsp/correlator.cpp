// Overlap-save multi-template correlator (interface and definitions in correlator.hpp).
#include "locus/dsp/correlator.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

namespace locus::dsp {

namespace {
// Plain complex product (std::complex's operator* adds NaN/Inf recovery branches that do not
// vectorise; the inputs here are finite).
inline std::complex<float> mul(std::complex<float> a, std::complex<float> b) noexcept {
  return {a.real() * b.real() - a.imag() * b.imag(), a.real() * b.imag() + a.imag() * b.real()};
}
}  // namespace

Correlator::Correlator() = default;
Correlator::~Correlator() = default;
Correlator::Correlator(Correlator&&) noexcept = default;
Correlator& Correlator::operator=(Correlator&&) noexcept = default;

void Correlator::configure(const std::vector<std::vector<float>>& templates, FftPlanner& planner,
                           const Options& options) {
  if (templates.empty()) throw std::invalid_argument("Correlator: no template");
  if (options.channels == 0) throw std::invalid_argument("Correlator: channels must be >= 1");
  std::size_t lmax = 0;
  for (std::size_t t = 0; t < templates.size(); ++t) {
    if (templates[t].empty()) throw std::invalid_argument("Correlator: template " + std::to_string(t) + " is empty");
    lmax = std::max(lmax, templates[t].size());
  }
  std::size_t n = options.fft_size;
  if (n == 0) {
    n = std::max<std::size_t>(256, std::bit_ceil(4 * lmax));
  } else if (n < lmax + 1 || n % 2 != 0) {
    throw std::invalid_argument("Correlator: fft_size " + std::to_string(n) +
                                " must be even and larger than the longest template (" + std::to_string(lmax) +
                                " samples)");
  }
  n_ = n;
  lmax_ = lmax;
  hop_ = options.hop == 0 ? n - lmax + 1 : std::min(options.hop, n - lmax + 1);
  // Overlapped windows output their LAST hop valid lags (those whose template just became whole):
  // outputs start off_ lags into the window. A multiple of 4 keeps them on the baseband grid (D = 4, 2).
  off_ = n - lmax + 1 - hop_;
  if (off_ % 4 != 0) {
    const std::size_t up = 4 - off_ % 4;
    if (hop_ > up) {
      hop_ -= up;
      off_ += up;
    } else {
      hop_ += off_ % 4;
      off_ -= off_ % 4;
    }
  }
  channels_ = options.channels;
  templates_ = templates.size();
  analytic_ = options.analytic;
  fft_ = planner.plan_real(n);
  const std::size_t nb = n / 2 + 1;

  lengths_.resize(templates_);
  energy_.resize(templates_);
  centroid_.resize(templates_);
  tmpl_spec_.assign(templates_ * nb, {});
  std::vector<float> padded(n);
  const float scale = 1.0f / static_cast<float>(n);
  for (std::size_t t = 0; t < templates_; ++t) {
    const auto& h = templates[t];
    lengths_[t] = h.size();
    double e = 0.0;
    for (float v : h) e += static_cast<double>(v) * v;
    energy_[t] = e;
    std::fill(padded.begin(), padded.end(), 0.0f);
    std::copy(h.begin(), h.end(), padded.begin());
    std::complex<float>* spec = &tmpl_spec_[t * nb];
    fft_->forward(padded.data(), spec);
    double m0 = 0.0, m1 = 0.0;
    for (std::size_t k = 0; k < nb; ++k) {
      const double p = std::norm(std::complex<double>(spec[k]));
      m0 += p;
      m1 += p * static_cast<double>(k);
      spec[k] = std::conj(spec[k]) * scale;
    }
    centroid_[t] = m0 > 0.0 ? 2.0 * std::numbers::pi * (m1 / m0) / static_cast<double>(n) : 0.0;
  }
  bb_dec_.assign(templates_, 1);
  bb_k0_.assign(templates_, 0);
  bb_ratio_.assign(templates_, 1.0);
  bb_fft_.clear();
  bb_fft_.resize(templates_);
  bb_tw_.assign(templates_, {});
  if (options.baseband && analytic_) {
    for (std::size_t t = 0; t < templates_; ++t) {
      // |H|^2 from the stored conj(H)/N (the scale does not matter for relative levels).
      const std::complex<float>* spec = &tmpl_spec_[t * nb];
      double pmax = 0.0;
      for (std::size_t k = 0; k < nb; ++k) pmax = std::max(pmax, double(std::norm(spec[k])));
      std::size_t lo = nb, hi = 0;
      for (std::size_t k = 0; k < nb; ++k)
        if (double(std::norm(spec[k])) >= 1e-4 * pmax) lo = std::min(lo, k), hi = std::max(hi, k);
      if (lo > hi) continue;
      for (std::size_t d : {std::size_t{4}, std::size_t{2}}) {
        const std::size_t m = n / d;
        if (m > nb || m < 2) continue;
        const std::size_t centre = (lo + hi) / 2;
        const std::size_t k0 = std::min(centre > m / 2 ? centre - m / 2 : 0, nb - m);
        if (k0 > lo || k0 + m - 1 < hi) continue;
        bb_dec_[t] = d;
        bb_k0_[t] = k0;
        bb_fft_[t] = planner.plan_complex(m);
        // Envelope of the template's own analytic autocorrelation D/2 lags (or fewer) off its peak.
        auto r_at = [&](double off) {
          std::complex<double> acc = 0.0;
          for (std::size_t k = k0; k < k0 + m; ++k) {
            const double w = (k == 0 || 2 * k == n) ? 1.0 : 2.0;
            acc += w * double(std::norm(spec[k])) * std::polar(1.0, 2.0 * std::numbers::pi * double(k) * off / double(n));
          }
          return std::norm(acc);
        };
        const double r0 = r_at(0.0);
        double ratio = 1.0;
        for (std::size_t off = 1; off <= d / 2; ++off) ratio = std::min(ratio, r_at(double(off)) / r0);
        bb_ratio_[t] = ratio;
        // exp(2 pi j k (off + hop - 1) / N) over the band: the last lag of a full window (baseband_lag).
        bb_tw_[t].resize(m);
        for (std::size_t i = 0; i < m; ++i)
          bb_tw_[t][i] = std::complex<float>(std::polar(
              1.0, 2.0 * std::numbers::pi * double((k0 + i) * (off_ + hop_ - 1) % n) / double(n)));
        break;
      }
    }
  }
  window_.assign(channels_ * n, 0.0f);
  fill_.assign(channels_, off_);  // overlapped: off_ zeros before the first sample (see reset())
  start_.assign(channels_, 0);
  segment_.assign(channels_, 0);
  spec_buf_.assign(nb, {});
  prod_.assign(nb, {});
  prod_im_.assign(analytic_ ? nb : 0, {});
  out_re_.assign(templates_ * n, 0.0f);
  out_im_.assign(analytic_ ? templates_ * n : 0, 0.0f);
  spec_ = spec_buf_.data();
}

std::size_t Correlator::push(std::size_t ch, const float* x, std::size_t n, std::size_t stride) noexcept {
  const std::size_t take = std::min(n, n_ - fill_[ch]);
  float* w = &window_[ch * n_ + fill_[ch]];
  if (stride == 1) {
    std::memcpy(w, x, take * sizeof(float));
  } else {
    for (std::size_t i = 0; i < take; ++i) w[i] = x[i * stride];
  }
  fill_[ch] += take;
  return take;
}

void Correlator::transform(std::size_t ch) noexcept {
  float* w = &window_[ch * n_];
  if (fill_[ch] < n_) std::fill(w + fill_[ch], w + n_, 0.0f);
  fft_->forward_aligned(w, spec_);
}

void Correlator::correlate(std::size_t t) noexcept {
  const std::size_t nb = n_ / 2 + 1;
  const std::complex<float>* h = &tmpl_spec_[t * nb];
  std::complex<float>* p = prod_.data();
  if (!analytic_) {
    for (std::size_t k = 0; k < nb; ++k) p[k] = mul(spec_[k], h[k]);
    fft_->inverse_destroying(p, &out_re_[t * n_]);
    return;
  }
  // Hilbert part: -j * sign(f) on the product (DC and Nyquist have no quadrature component). Both
  // products are formed first because the inverse transforms consume their inputs.
  std::complex<float>* q = prod_im_.data();
  {
    // On interleaved floats so that the loop vectorises.
    const float* a = reinterpret_cast<const float*>(spec_);
    const float* b = reinterpret_cast<const float*>(h);
    float* pf = reinterpret_cast<float*>(p);
    float* qf = reinterpret_cast<float*>(q);
    for (std::size_t j = 0; j < 2 * nb; j += 2) {
      const float re = a[j] * b[j] - a[j + 1] * b[j + 1], im = a[j] * b[j + 1] + a[j + 1] * b[j];
      pf[j] = re;
      pf[j + 1] = im;
      qf[j] = im;
      qf[j + 1] = -re;
    }
  }
  q[0] = {0.0f, 0.0f};
  q[nb - 1] = {0.0f, 0.0f};
  fft_->inverse_destroying(p, &out_re_[t * n_]);
  fft_->inverse_destroying(q, &out_im_[t * n_]);
}

void Correlator::correlate_baseband(std::size_t t) noexcept {
  const std::size_t nb = n_ / 2 + 1;
  const std::size_t k0 = bb_k0_[t];
  ComplexFft& f = *bb_fft_[t];
  const std::size_t m = f.size();
  const std::complex<float>* h = &tmpl_spec_[t * nb + k0];
  const std::complex<float>* x = spec_ + k0;
  std::complex<float>* in = f.input();
  // z = y + j H{y}: bins 1..N/2-1 count twice, DC and Nyquist once.
  for (std::size_t i = 0; i < m; ++i) in[i] = mul(x[i], h[i]) * 2.0f;
  if (k0 == 0) in[0] *= 0.5f;
  if (k0 + m == nb) in[m - 1] *= 0.5f;
  f.inverse();
}

std::complex<float> Correlator::baseband_lag(std::size_t t, std::size_t i) const noexcept {
  const ComplexFft& f = *bb_fft_[t];
  const std::complex<float>* in = f.input();
  if (i + 1 == hop_) {  // the common case: a table of twiddles
    const float* a = reinterpret_cast<const float*>(in);
    const float* b = reinterpret_cast<const float*>(bb_tw_[t].data());
    // Eight interleaved partial sums (4 complex lanes) so that the loop vectorises.
    float rr[4] = {}, ii[4] = {};
    const std::size_t m = f.size();
    std::size_t k = 0;
    for (; k + 4 <= m; k += 4)
      for (std::size_t l = 0; l < 4; ++l) {
        const std::size_t j = 2 * (k + l);
        rr[l] += a[j] * b[j] - a[j + 1] * b[j + 1];
        ii[l] += a[j] * b[j + 1] + a[j + 1] * b[j];
      }
    float re = (rr[0] + rr[1]) + (rr[2] + rr[3]), im = (ii[0] + ii[1]) + (ii[2] + ii[3]);
    for (; k < m; ++k) {
      re += in[k].real() * bb_tw_[t][k].real() - in[k].imag() * bb_tw_[t][k].imag();
      im += in[k].real() * bb_tw_[t][k].imag() + in[k].imag() * bb_tw_[t][k].real();
    }
    return {re, im};
  }
  const double w = 2.0 * std::numbers::pi * static_cast<double>(i + off_) / static_cast<double>(n_);
  std::complex<double> rot = std::polar(1.0, w * static_cast<double>(bb_k0_[t]));
  const std::complex<double> step = std::polar(1.0, w);
  std::complex<double> acc = 0.0;
  for (std::size_t k = 0; k < f.size(); ++k) {
    acc += std::complex<double>(in[k]) * rot;
    rot *= step;
  }
  return {static_cast<float>(acc.real()), static_cast<float>(acc.imag())};
}

void Correlator::advance(std::size_t ch) noexcept {
  float* w = &window_[ch * n_];
  const std::size_t keep = n_ - hop_;  // lmax - 1 unless Options::hop overlaps the windows
  if (keep > 0) std::memmove(w, w + hop_, keep * sizeof(float));
  fill_[ch] = keep;
  start_[ch] += hop_;
}

std::size_t Correlator::flush(std::size_t ch) noexcept {
  const std::size_t have = fill_[ch];
  if (have < lmax_ + off_) return 0;  // no lag beyond those already output
  transform(ch);
  return have - lmax_ + 1 - off_;
}

void Correlator::reset(std::size_t ch, std::uint64_t next_index) noexcept {
  // Overlapped windows: off_ zeros stand before the first sample, so that the first window's
  // outputs are the lags from next_index on (no lag is skipped, none uses audio before the reset).
  std::fill(&window_[ch * n_], &window_[ch * n_] + off_, 0.0f);
  fill_[ch] = off_;
  start_[ch] = next_index;
  segment_[ch] = next_index;
}

void correlate_direct(const float* x, std::size_t n_x, const float* h, std::size_t n_h, float* out) noexcept {
  if (n_x < n_h || n_h == 0) return;
  const std::size_t n_out = n_x - n_h + 1;
  // Output tiles of 512 lags: the inner loop over lags has no reduction, so it vectorises, and the
  // tile of x it reads stays in cache across the template taps.
  constexpr std::size_t kTile = 512;
  for (std::size_t k0 = 0; k0 < n_out; k0 += kTile) {
    const std::size_t kn = std::min(kTile, n_out - k0);
    float* o = out + k0;
    std::fill(o, o + kn, 0.0f);
    for (std::size_t j = 0; j < n_h; ++j) {
      const float hj = h[j];
      const float* xs = x + k0 + j;
      for (std::size_t k = 0; k < kn; ++k) o[k] += hj * xs[k];
    }
  }
}

}  // namespace locus::dsp
