// Generators of the scene format's signals (see signals.hpp for the definitions and conventions).
#include "locus/dsp/signals.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include "locus/numbers.hpp"

namespace locus::dsp {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void check_timed(const SignalSpec& s) {
  require(std::isfinite(s.duration_s) && s.duration_s > 0.0,
          s.type + ": duration must be > 0 s (got " + std::to_string(s.duration_s) + ")");
  require(std::isfinite(s.fade_s) && s.fade_s >= 0.0, s.type + ": fade must be >= 0 s");
}

double lfm_value(const SignalSpec& s, double t) noexcept {
  const double k = (s.f1_hz - s.f0_hz) / s.duration_s;
  return s.amplitude * fade_weight(t, s.duration_s, s.fade_s) *
         std::sin(kTwoPi * (s.f0_hz * t + 0.5 * k * t * t));
}

double multitone_value(const SignalSpec& s, double t) noexcept {
  double sum = 0.0;
  for (double f : s.tones_hz) sum += std::sin(kTwoPi * f * t);
  return s.amplitude * fade_weight(t, s.duration_s, s.fade_s) * sum / static_cast<double>(s.tones_hz.size());
}

}  // namespace

double fade_weight(double t_s, double duration_s, double fade_s) noexcept {
  if (!(t_s >= 0.0) || !(t_s < duration_s)) return 0.0;
  if (fade_s <= 0.0) return 1.0;
  const double fade = std::min(fade_s, 0.5 * duration_s);
  if (t_s < fade) return 0.5 * (1.0 - std::cos(std::numbers::pi * t_s / fade));
  const double to_end = duration_s - t_s;
  if (to_end < fade) return 0.5 * (1.0 - std::cos(std::numbers::pi * to_end / fade));
  return 1.0;
}

std::vector<std::uint8_t> m_sequence(int degree, unsigned poly_octal_value) {
  require(degree >= 2 && degree <= 24, "m-sequence degree must be 2..24 (got " + std::to_string(degree) + ")");
  require((poly_octal_value >> degree) == 1u,
          "characteristic polynomial " + std::to_string(poly_octal_value) + " is not of degree " + std::to_string(degree));
  require((poly_octal_value & 1u) == 1u, "characteristic polynomial must have a constant term");
  const std::size_t length = (std::size_t{1} << degree) - 1;
  std::vector<std::uint8_t> a(length + static_cast<std::size_t>(degree), 0);
  for (int i = 0; i < degree; ++i) a[static_cast<std::size_t>(i)] = 1;  // seeded all-ones
  for (std::size_t n = 0; n + static_cast<std::size_t>(degree) < a.size(); ++n) {
    std::uint8_t bit = 0;
    for (int i = 0; i < degree; ++i) {
      if ((poly_octal_value >> i) & 1u) bit ^= a[n + static_cast<std::size_t>(i)];
    }
    a[n + static_cast<std::size_t>(degree)] = bit;
  }
  a.resize(length);
  return a;
}

std::pair<unsigned, unsigned> gold_preferred_pair(int degree) {
  switch (degree) {
    case 5: return {045, 075};
    case 6: return {0103, 0147};
    case 7: return {0211, 0217};
    case 9: return {01021, 01131};
    case 10: return {02011, 02415};
    case 11: return {04005, 04445};
    default:
      throw std::invalid_argument("gold: degree " + std::to_string(degree) +
                                  " has no preferred pair in the scene format (expected 5, 6, 7, 9, 10 or 11)");
  }
}

std::vector<std::uint8_t> gold_chips(const SignalSpec& spec) {
  if (!spec.chips.empty()) {
    std::vector<std::uint8_t> chips;
    chips.reserve(spec.chips.size());
    for (std::size_t i = 0; i < spec.chips.size(); ++i) {
      const char c = spec.chips[i];
      require(c == '0' || c == '1', "gold: chips[" + std::to_string(i) + "] is '" + std::string(1, c) +
                                        "', expected only '0' and '1'");
      chips.push_back(static_cast<std::uint8_t>(c - '0'));
    }
    return chips;
  }
  const auto [pu, pv] = gold_preferred_pair(spec.degree);
  const std::size_t length = (std::size_t{1} << spec.degree) - 1;
  require(spec.index >= 0 && static_cast<std::size_t>(spec.index) <= length + 1,
          "gold: index " + std::to_string(spec.index) + " out of range 0.." + std::to_string(length + 1) +
              " for degree " + std::to_string(spec.degree));
  const std::vector<std::uint8_t> u = m_sequence(spec.degree, pu);
  const std::vector<std::uint8_t> v = m_sequence(spec.degree, pv);
  if (spec.index == 0) return u;
  if (spec.index == 1) return v;
  const std::size_t shift = static_cast<std::size_t>(spec.index - 2);
  std::vector<std::uint8_t> out(length);
  for (std::size_t n = 0; n < length; ++n) out[n] = u[n] ^ v[(n + shift) % length];
  return out;
}

double doppler_timing_instant_s(const SignalSpec& spec, double sample_rate_hz) {
  if (!spec.acoustic()) return 0.0;
  // gold: constant amplitude over chips * chip_samples samples, no fades: its middle.
  if (spec.type == "gold") return 0.5 * static_cast<double>(signal_length(spec, sample_rate_hz)) / sample_rate_hz;
  const double duration = spec.duration_s;
  if (duration <= 0.0) return 0.0;
  // Midpoint rule on 4096 steps: the fades are smooth, the integrands polynomial in between.
  constexpr int kSteps = 4096;
  const double du = duration / kSteps;
  const bool lfm = spec.type == "lfm";
  double num = 0.0, den = 0.0;
  for (int i = 0; i < kSteps; ++i) {
    const double u = (i + 0.5) * du;
    const double w = fade_weight(u, duration, spec.fade_s);
    const double f = lfm ? spec.f0_hz + (spec.f1_hz - spec.f0_hz) * u / duration : 1.0;
    num += u * f * w * w;
    den += f * w * w;
  }
  return den > 0.0 ? num / den : 0.0;
}

std::size_t signal_length(const SignalSpec& spec, double sample_rate_hz) {
  if (spec.type == "lfm" || spec.type == "multitone") {
    return static_cast<std::size_t>(std::llround(spec.duration_s * sample_rate_hz));
  }
  if (spec.type == "gold") {
    const std::size_t chips = spec.chips.empty() ? (std::size_t{1} << spec.degree) - 1 : spec.chips.size();
    return chips * static_cast<std::size_t>(std::max(spec.chip_samples, 0));
  }
  return 0;
}

SignalEvaluator::SignalEvaluator(const SignalSpec& spec, double sample_rate_hz) : spec_(spec), fs_(sample_rate_hz) {
  require(std::isfinite(fs_) && fs_ > 0.0, "sample rate must be > 0 Hz");
  require(std::isfinite(spec.amplitude), spec.type + ": amplitude must be a number");
  if (spec.type == "lfm") {
    check_timed(spec);
    duration_s_ = spec.duration_s;
  } else if (spec.type == "multitone") {
    check_timed(spec);
    require(!spec.tones_hz.empty(), "multitone: tones_hz must list at least one frequency");
    duration_s_ = spec.duration_s;
  } else if (spec.type == "gold") {
    require(spec.chip_samples >= 1, "gold: chip_samples must be >= 1 (got " + std::to_string(spec.chip_samples) + ")");
    samples_ = render_signal(spec, fs_);
    duration_s_ = static_cast<double>(samples_.size()) / fs_;
    begin_s_ = -kInterpolationHalfWidth / fs_;
    end_s_ = duration_s_ + kInterpolationHalfWidth / fs_;
    // Kaiser window (beta 8.6: about -90 dB sidelobes), tabulated over |u| in [0, 1].
    constexpr int kTable = 4096;
    constexpr double kBeta = 8.6;
    auto bessel_i0 = [](double x) {
      double sum = 1.0, term = 1.0;
      for (int k = 1; k < 60; ++k) {
        term *= (x / (2.0 * k)) * (x / (2.0 * k));
        sum += term;
        if (term < 1e-17 * sum) break;
      }
      return sum;
    };
    window_table_.resize(kTable + 2);
    for (int i = 0; i <= kTable + 1; ++i) {
      const double u = std::min(1.0, static_cast<double>(i) / kTable);
      window_table_[static_cast<std::size_t>(i)] = bessel_i0(kBeta * std::sqrt(1.0 - u * u)) / bessel_i0(kBeta);
    }
    return;
  } else {
    throw std::invalid_argument("signal type '" + spec.type + "' is not an acoustic signal this build can render "
                                "(expected lfm, gold or multitone)");
  }
  end_s_ = duration_s_;
}

double SignalEvaluator::interpolate(double t_s) const noexcept {
  const double x = t_s * fs_;
  const double nearest = std::round(x);
  const double r = x - nearest;  // in [−0.5, 0.5]: sin(π·r) stays accurate when x is next to a sample
  const auto base = static_cast<std::int64_t>(nearest);
  const auto count = static_cast<std::int64_t>(samples_.size());
  if (r == 0.0) return (base >= 0 && base < count) ? samples_[static_cast<std::size_t>(base)] : 0.0;
  // sin(π(x − k)) = (−1)^(base−k)·sin(π·r)
  const double sin_pf = std::sin(std::numbers::pi * r);
  const double table_scale = static_cast<double>(window_table_.size() - 2) / kInterpolationHalfWidth;
  double sum = 0.0;
  const std::int64_t k_lo = std::max<std::int64_t>(base - kInterpolationHalfWidth + 1, 0);
  const std::int64_t k_hi = std::min<std::int64_t>(base + kInterpolationHalfWidth - 1, count - 1);
  for (std::int64_t k = k_lo; k <= k_hi; ++k) {
    const double d = x - static_cast<double>(k);  // in (−H, H)
    const double sign = ((base - k) & 1) ? -1.0 : 1.0;
    const double u = std::abs(d) * table_scale;
    const auto j = static_cast<std::size_t>(u);
    const double w = window_table_[j] + (u - static_cast<double>(j)) * (window_table_[j + 1] - window_table_[j]);
    sum += samples_[static_cast<std::size_t>(k)] * sign * sin_pf / (std::numbers::pi * d) * w;
  }
  return sum;
}

double SignalEvaluator::value(double t_s) const noexcept {
  if (!(t_s >= begin_s_) || !(t_s < end_s_)) return 0.0;
  if (spec_.type == "lfm") return lfm_value(spec_, t_s);
  if (spec_.type == "multitone") return multitone_value(spec_, t_s);
  return interpolate(t_s);
}

std::vector<float> render_signal(const SignalSpec& spec, double sample_rate_hz) {
  if (spec.type == "gold") {
    require(std::isfinite(sample_rate_hz) && sample_rate_hz > 0.0, "sample rate must be > 0 Hz");
    require(spec.chip_samples >= 1, "gold: chip_samples must be >= 1 (got " + std::to_string(spec.chip_samples) + ")");
    const std::size_t n = signal_length(spec, sample_rate_hz);
    std::vector<float> out(n);
    // Exactly the format's sample formula: a·c[n / chip_samples]·cos(2π·carrier·n/fs).
    const std::vector<std::uint8_t> chips = gold_chips(spec);
    const auto cs = static_cast<std::size_t>(spec.chip_samples);
    for (std::size_t i = 0; i < n; ++i) {
      const double sign = chips[i / cs] ? -1.0 : 1.0;
      out[i] = static_cast<float>(spec.amplitude * sign *
                                  std::cos(kTwoPi * spec.carrier_hz * static_cast<double>(i) / sample_rate_hz));
    }
    return out;
  }
  const SignalEvaluator eval(spec, sample_rate_hz);
  const std::size_t n = signal_length(spec, sample_rate_hz);
  std::vector<float> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(eval.value(static_cast<double>(i) / sample_rate_hz));
  return out;
}

}  // namespace locus::dsp
