// Generators of the scene format's signals (see signals.hpp for the definitions and conventions).
#include "locus/dsp/signals.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace locus::dsp {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

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
    const std::vector<std::uint8_t> chips = gold_chips(spec);
    chip_sign_.reserve(chips.size());
    for (std::uint8_t c : chips) chip_sign_.push_back(c ? -1.0f : 1.0f);
    duration_s_ = static_cast<double>(chips.size()) * spec.chip_samples / fs_;
  } else {
    throw std::invalid_argument("signal type '" + spec.type + "' is not an acoustic signal this build can render "
                                "(expected lfm, gold or multitone)");
  }
}

double SignalEvaluator::value(double t_s) const noexcept {
  if (!(t_s >= 0.0) || !(t_s < duration_s_)) return 0.0;
  if (spec_.type == "lfm") return lfm_value(spec_, t_s);
  if (spec_.type == "multitone") return multitone_value(spec_, t_s);
  // gold: chip k covers samples [k·chip_samples, (k+1)·chip_samples)
  const auto chip = static_cast<std::size_t>(std::floor(t_s * fs_ / spec_.chip_samples));
  if (chip >= chip_sign_.size()) return 0.0;
  return spec_.amplitude * chip_sign_[chip] * std::cos(kTwoPi * spec_.carrier_hz * t_s);
}

std::vector<float> render_signal(const SignalSpec& spec, double sample_rate_hz) {
  const SignalEvaluator eval(spec, sample_rate_hz);
  const std::size_t n = signal_length(spec, sample_rate_hz);
  std::vector<float> out(n);
  if (spec.type == "gold") {
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
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(eval.value(static_cast<double>(i) / sample_rate_hz));
  return out;
}

}  // namespace locus::dsp
