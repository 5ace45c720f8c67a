// Overlap-save multi-template correlator (interface and definitions in correlator.hpp).
#include "locus/dsp/correlator.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <string>

namespace locus::dsp {

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
  hop_ = n - lmax + 1;
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
  window_.assign(channels_ * n, 0.0f);
  fill_.assign(channels_, 0);
  start_.assign(channels_, 0);
  spec_buf_.assign(nb, {});
  prod_.assign(nb, {});
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
  fft_->forward(w, spec_);
}

void Correlator::correlate(std::size_t t) noexcept {
  const std::size_t nb = n_ / 2 + 1;
  const std::complex<float>* h = &tmpl_spec_[t * nb];
  std::complex<float>* p = prod_.data();
  for (std::size_t k = 0; k < nb; ++k) p[k] = spec_[k] * h[k];
  fft_->inverse(p, &out_re_[t * n_]);
  if (!analytic_) return;
  // Hilbert part: -j * sign(f) on the product (DC and Nyquist have no quadrature component).
  p[0] = {0.0f, 0.0f};
  for (std::size_t k = 1; k + 1 < nb; ++k) p[k] = {p[k].imag(), -p[k].real()};
  p[nb - 1] = {0.0f, 0.0f};
  fft_->inverse(p, &out_im_[t * n_]);
}

void Correlator::advance(std::size_t ch) noexcept {
  float* w = &window_[ch * n_];
  const std::size_t keep = lmax_ - 1;
  if (keep > 0) std::memmove(w, w + hop_, keep * sizeof(float));
  fill_[ch] = keep;
  start_[ch] += hop_;
}

std::size_t Correlator::flush(std::size_t ch) noexcept {
  const std::size_t have = fill_[ch];
  if (have < lmax_) return 0;
  transform(ch);
  return have - lmax_ + 1;
}

void Correlator::reset(std::size_t ch, std::uint64_t next_index) noexcept {
  fill_[ch] = 0;
  start_[ch] = next_index;
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
