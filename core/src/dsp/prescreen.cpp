// FFT band-energy pre-screen (interface and rationale in prescreen.hpp).
#include "locus/dsp/prescreen.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace locus::dsp {

void BandPrescreen::configure(std::size_t fft_size, double sample_rate_hz, double band_lo_hz, double band_hi_hz,
                              double threshold_db, double min_hz, double baseline_alpha) {
  if (fft_size < 4 || !(sample_rate_hz > 0.0))
    throw std::invalid_argument("BandPrescreen: fft_size must be >= 4 and the sample rate > 0");
  if (!(band_lo_hz < band_hi_hz))
    throw std::invalid_argument("BandPrescreen: band low edge " + std::to_string(band_lo_hz) +
                                " Hz must be below the high edge " + std::to_string(band_hi_hz) + " Hz");
  bins_ = fft_size / 2 + 1;
  const double hz_per_bin = sample_rate_hz / static_cast<double>(fft_size);
  lo_bin_ = static_cast<std::size_t>(std::max(0.0, std::ceil(band_lo_hz / hz_per_bin)));
  hi_bin_ = std::min(bins_ - 1, static_cast<std::size_t>(std::max(0.0, std::floor(band_hi_hz / hz_per_bin))));
  min_bin_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(std::max(0.0, min_hz) / hz_per_bin)));
  if (lo_bin_ > hi_bin_)
    throw std::invalid_argument("BandPrescreen: the band [" + std::to_string(band_lo_hz) + ", " +
                                std::to_string(band_hi_hz) + "] Hz holds no FFT bin");
  const std::size_t below = lo_bin_ > min_bin_ ? lo_bin_ - min_bin_ : 0;
  const std::size_t above = bins_ - 1 - hi_bin_;
  if (below + above == 0)
    throw std::invalid_argument("BandPrescreen: the band covers the whole spectrum; nothing to compare it with");
  threshold_db_ = threshold_db;
  alpha_ = std::clamp(baseline_alpha, 0.0, 1.0);
  reset();
}

double BandPrescreen::ratio_db(const std::complex<float>* s) const noexcept {
  double in = 0.0, out = 0.0;
  std::size_t n_in = 0, n_out = 0;
  for (std::size_t k = min_bin_; k < lo_bin_; ++k, ++n_out) out += std::norm(s[k]);
  for (std::size_t k = lo_bin_; k <= hi_bin_; ++k, ++n_in) in += std::norm(s[k]);
  for (std::size_t k = hi_bin_ + 1; k < bins_; ++k, ++n_out) out += std::norm(s[k]);
  if (n_in == 0 || n_out == 0) return 0.0;
  in /= static_cast<double>(n_in);
  out /= static_cast<double>(n_out);
  if (!(out > 0.0)) return in > 0.0 ? 300.0 : 0.0;
  if (!(in > 0.0)) return -300.0;
  return 10.0 * std::log10(in / out);
}

bool BandPrescreen::pass(const std::complex<float>* spectrum) noexcept {
  last_db_ = ratio_db(spectrum);
  return last_db_ - baseline_db_ >= threshold_db_;
}

void BandPrescreen::note_quiet(bool skipped) noexcept {
  if (last_db_ < baseline_db_)
    baseline_db_ = last_db_;
  else
    baseline_db_ += (skipped ? alpha_ : 0.1 * alpha_) * (last_db_ - baseline_db_);
  baseline_db_ = std::clamp(baseline_db_, -120.0, 120.0);
}

void BandPrescreen::reset() noexcept {
  baseline_db_ = 0.0;
  last_db_ = 0.0;
}

}  // namespace locus::dsp
