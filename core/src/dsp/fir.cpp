// Windowed-sinc FIR design (as scipy.signal.firwin), streaming FIR and decimating FIR.
#include "locus/dsp/fir.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include "locus/numbers.hpp"

namespace locus::dsp {
namespace {

double bessel_i0(double x) {
  // Power series; converges fast for the beta values of FIR design (< 50).
  double sum = 1.0, term = 1.0;
  const double q = x * x / 4.0;
  for (int k = 1; k < 500; ++k) {
    term *= q / (static_cast<double>(k) * k);
    sum += term;
    if (term < sum * 1e-17) break;
  }
  return sum;
}

double sinc(double x) { return x == 0.0 ? 1.0 : std::sin(kPi * x) / (kPi * x); }

void check_taps(std::size_t taps, const char* what) {
  if (taps < 1 || taps > (1u << 20))
    throw std::invalid_argument(std::string(what) + ": taps must be in 1..2^20, got " + std::to_string(taps));
}

void check_f(double f, double fs, const char* what, const char* name) {
  if (!(fs > 0.0) || !std::isfinite(fs))
    throw std::invalid_argument(std::string(what) + ": sample_rate_hz must be > 0");
  if (!(f > 0.0) || !(f < fs / 2.0))
    throw std::invalid_argument(std::string(what) + ": " + name + " must be in (0, fs/2 = " +
                                std::to_string(fs / 2.0) + ") Hz, got " + std::to_string(f));
}

// firwin: bands given as pairs of normalised edges (fraction of Nyquist), pass_zero implied by the
// first band starting at 0. Scaled to unit gain at `scale_freq` (fraction of Nyquist).
std::vector<double> firwin(std::size_t taps, const std::vector<std::pair<double, double>>& bands,
                           FirWindowSpec w) {
  const double alpha = 0.5 * (static_cast<double>(taps) - 1.0);
  std::vector<double> h(taps, 0.0);
  for (std::size_t i = 0; i < taps; ++i) {
    const double m = static_cast<double>(i) - alpha;
    for (const auto& [l, r] : bands) h[i] += r * sinc(r * m) - l * sinc(l * m);
  }
  const std::vector<double> win = fir_window(taps, w);
  for (std::size_t i = 0; i < taps; ++i) h[i] *= win[i];
  const auto& [l0, r0] = bands.front();
  double scale_freq;
  if (l0 == 0.0) scale_freq = 0.0;
  else if (r0 == 1.0) scale_freq = 1.0;
  else scale_freq = 0.5 * (l0 + r0);
  double s = 0.0;
  for (std::size_t i = 0; i < taps; ++i)
    s += h[i] * std::cos(kPi * (static_cast<double>(i) - alpha) * scale_freq);
  for (double& v : h) v /= s;
  return h;
}

}  // namespace

double kaiser_beta(double a) noexcept {
  if (a > 50.0) return 0.1102 * (a - 8.7);
  if (a > 21.0) return 0.5842 * std::pow(a - 21.0, 0.4) + 0.07886 * (a - 21.0);
  return 0.0;
}

std::vector<double> fir_window(std::size_t n, FirWindowSpec w) {
  std::vector<double> out(n, 1.0);
  if (n <= 1) return out;
  const double d = static_cast<double>(n - 1);
  for (std::size_t i = 0; i < n; ++i) {
    const double x = static_cast<double>(i);
    switch (w.type) {
      case FirWindow::hamming: out[i] = 0.54 - 0.46 * std::cos(2.0 * kPi * x / d); break;
      case FirWindow::blackman:
        out[i] = 0.42 - 0.5 * std::cos(2.0 * kPi * x / d) + 0.08 * std::cos(4.0 * kPi * x / d);
        break;
      case FirWindow::kaiser: {
        const double r = 2.0 * x / d - 1.0;
        out[i] = bessel_i0(w.kaiser_beta * std::sqrt(std::max(0.0, 1.0 - r * r))) / bessel_i0(w.kaiser_beta);
        break;
      }
    }
  }
  return out;
}

std::vector<double> fir_lowpass(std::size_t taps, double fc, double fs, FirWindowSpec w) {
  check_taps(taps, "fir_lowpass");
  check_f(fc, fs, "fir_lowpass", "cutoff_hz");
  return firwin(taps, {{0.0, fc / (fs / 2.0)}}, w);
}

std::vector<double> fir_highpass(std::size_t taps, double fc, double fs, FirWindowSpec w) {
  check_taps(taps, "fir_highpass");
  check_f(fc, fs, "fir_highpass", "cutoff_hz");
  if (taps % 2 == 0)
    throw std::invalid_argument("fir_highpass: taps must be odd (an even-length linear-phase filter has a zero at fs/2), got " +
                                std::to_string(taps));
  return firwin(taps, {{fc / (fs / 2.0), 1.0}}, w);
}

std::vector<double> fir_bandpass(std::size_t taps, double lo, double hi, double fs, FirWindowSpec w) {
  check_taps(taps, "fir_bandpass");
  check_f(lo, fs, "fir_bandpass", "low_hz");
  check_f(hi, fs, "fir_bandpass", "high_hz");
  if (!(lo < hi)) throw std::invalid_argument("fir_bandpass: low_hz must be below high_hz");
  return firwin(taps, {{lo / (fs / 2.0), hi / (fs / 2.0)}}, w);
}

std::vector<double> fir_bandstop(std::size_t taps, double lo, double hi, double fs, FirWindowSpec w) {
  check_taps(taps, "fir_bandstop");
  check_f(lo, fs, "fir_bandstop", "low_hz");
  check_f(hi, fs, "fir_bandstop", "high_hz");
  if (!(lo < hi)) throw std::invalid_argument("fir_bandstop: low_hz must be below high_hz");
  if (taps % 2 == 0) throw std::invalid_argument("fir_bandstop: taps must be odd, got " + std::to_string(taps));
  return firwin(taps, {{0.0, lo / (fs / 2.0)}, {hi / (fs / 2.0), 1.0}}, w);
}

// --- FirFilter ----------------------------------------------------------------------------------

FirFilter::FirFilter(std::vector<double> taps) {
  if (taps.empty()) throw std::invalid_argument("FirFilter: no taps");
  taps_.resize(taps.size());
  // Stored reversed: output = Σ taps_[k]·hist[pos+k] where hist[pos..pos+N-1] is oldest..newest.
  for (std::size_t k = 0; k < taps.size(); ++k) taps_[k] = static_cast<float>(taps[taps.size() - 1 - k]);
  history_.assign(2 * taps_.size(), 0.0f);
}

float FirFilter::process(float x) noexcept {
  const std::size_t n = taps_.size();
  // Newest sample at index pos_+n-1 of the mirrored line; write it twice.
  history_[pos_] = x;
  history_[pos_ + n] = x;
  pos_ = pos_ + 1 == n ? 0 : pos_ + 1;
  const float* h = history_.data() + pos_;  // oldest..newest
  float acc = 0.0f;
  for (std::size_t k = 0; k < n; ++k) acc += taps_[k] * h[k];
  return acc;
}

void FirFilter::process(const float* in, float* out, std::size_t n) noexcept {
  for (std::size_t i = 0; i < n; ++i) out[i] = process(in[i]);
}

void FirFilter::reset() noexcept {
  std::fill(history_.begin(), history_.end(), 0.0f);
  pos_ = 0;
}

// --- FirDecimator -------------------------------------------------------------------------------

FirDecimator::FirDecimator(std::vector<double> taps, std::size_t factor) : factor_(factor) {
  if (taps.empty()) throw std::invalid_argument("FirDecimator: no taps");
  if (factor < 1) throw std::invalid_argument("FirDecimator: factor must be >= 1");
  taps_.resize(taps.size());
  for (std::size_t k = 0; k < taps.size(); ++k) taps_[k] = static_cast<float>(taps[taps.size() - 1 - k]);
  history_.assign(2 * taps_.size(), 0.0f);
}

std::size_t FirDecimator::process(const float* in, std::size_t n, float* out) noexcept {
  const std::size_t len = taps_.size();
  std::size_t produced = 0;
  for (std::size_t i = 0; i < n; ++i) {
    history_[pos_] = in[i];
    history_[pos_ + len] = in[i];
    pos_ = pos_ + 1 == len ? 0 : pos_ + 1;
    if (phase_ == 0) {
      const float* h = history_.data() + pos_;
      float acc = 0.0f;
      for (std::size_t k = 0; k < len; ++k) acc += taps_[k] * h[k];
      out[produced++] = acc;
    }
    phase_ = phase_ + 1 == factor_ ? 0 : phase_ + 1;
  }
  return produced;
}

void FirDecimator::reset() noexcept {
  std::fill(history_.begin(), history_.end(), 0.0f);
  pos_ = 0;
  phase_ = 0;
}

}  // namespace locus::dsp
