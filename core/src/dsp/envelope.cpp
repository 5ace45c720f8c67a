// Block analytic envelope (interface in envelope.hpp).
#include "locus/dsp/envelope.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>

namespace locus::dsp {

EnvelopeFft::EnvelopeFft() = default;
EnvelopeFft::~EnvelopeFft() = default;
EnvelopeFft::EnvelopeFft(EnvelopeFft&&) noexcept = default;
EnvelopeFft& EnvelopeFft::operator=(EnvelopeFft&&) noexcept = default;

void EnvelopeFft::configure(std::size_t max_frames, FftPlanner& planner) {
  if (max_frames == 0) throw std::invalid_argument("EnvelopeFft: max_frames must be >= 1");
  max_frames_ = max_frames;
  n_ = std::max<std::size_t>(4, std::bit_ceil(2 * max_frames));
  fft_ = planner.plan_real(n_);
  time_.assign(n_, 0.0f);
  hil_.assign(n_, 0.0f);
  spec_.assign(n_ / 2 + 1, {});
}

void EnvelopeFft::hilbert(const float* x, std::size_t n, float* out) noexcept {
  n = std::min(n, max_frames_);
  std::copy(x, x + n, time_.begin());
  std::fill(time_.begin() + static_cast<std::ptrdiff_t>(n), time_.end(), 0.0f);
  fft_->forward(time_.data(), spec_.data());
  const std::size_t nb = n_ / 2 + 1;
  const float scale = 1.0f / static_cast<float>(n_);
  spec_[0] = {0.0f, 0.0f};
  for (std::size_t k = 1; k + 1 < nb; ++k) spec_[k] = {spec_[k].imag() * scale, -spec_[k].real() * scale};
  spec_[nb - 1] = {0.0f, 0.0f};
  fft_->inverse(spec_.data(), hil_.data());
  std::copy(hil_.begin(), hil_.begin() + static_cast<std::ptrdiff_t>(n), out);
}

void EnvelopeFft::envelope(const float* x, std::size_t n, float* env) noexcept {
  n = std::min(n, max_frames_);
  hilbert(x, n, hil_.data());  // hil_ holds H{x} in [0, n); x is still intact (time_ has a copy)
  for (std::size_t i = 0; i < n; ++i) {
    const float re = time_[i], im = hil_[i];
    env[i] = std::sqrt(re * re + im * im);
  }
}

void magnitude(const float* re, const float* im, std::size_t n, float* env) noexcept {
  for (std::size_t i = 0; i < n; ++i) env[i] = std::sqrt(re[i] * re[i] + im[i] * im[i]);
}

void magnitude_squared(const float* re, const float* im, std::size_t n, float* pow) noexcept {
  for (std::size_t i = 0; i < n; ++i) pow[i] = re[i] * re[i] + im[i] * im[i];
}

}  // namespace locus::dsp
