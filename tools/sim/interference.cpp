// Babble and music interference waveforms (interference.hpp).
#include "locus/sim/interference.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include "locus/numbers.hpp"

namespace locus::sim {

namespace {

// Adds a decaying (or gated) differentiated-white-noise segment: energy rising +6 dB/octave to fs/2.
void add_bright_noise(std::vector<double>& out, std::size_t k0, std::size_t len, double level, double tau_s,
                      bool gated, double fs, Rng& rng) {
  double prev = 0.0;
  for (std::size_t i = 0; i < len && k0 + i < out.size(); ++i) {
    const double w = rng.normal();
    const double d = w - prev;  // first difference
    prev = w;
    double env;
    if (gated) {
      const double u = static_cast<double>(i) / static_cast<double>(len);
      env = std::sin(std::numbers::pi * u);
    } else {
      env = std::exp(-static_cast<double>(i) / (tau_s * fs));
    }
    out[k0 + i] += level * env * d;
  }
}

void babble(std::vector<double>& out, double fs, Rng& rng) {
  const std::size_t n = out.size();
  const int talkers = static_cast<int>(rng.integer(3, 6));
  for (int tk = 0; tk < talkers; ++tk) {
    const double f0 = rng.uniform(90.0, 250.0);
    const double vib_hz = rng.uniform(3.0, 6.0), vib_ph = rng.uniform(0.0, kTwoPi);
    const double lp_hz = rng.uniform(500.0, 900.0);
    const double a = std::exp(-kTwoPi * lp_hz / fs);
    const double level = rng.uniform(0.5, 1.0);
    // syllables: consecutive segments of 0.12-0.3 s, voiced with probability 0.75
    std::vector<double> env(n, 0.0);
    for (std::size_t k = 0; k < n;) {
      const auto len = static_cast<std::size_t>(rng.uniform(0.12, 0.3) * fs);
      if (rng.bernoulli(0.75))
        for (std::size_t i = 0; i < len && k + i < n; ++i)
          env[k + i] = std::sin(std::numbers::pi * static_cast<double>(i) / static_cast<double>(len));
      k += std::max<std::size_t>(len, 1);
    }
    double phase = rng.uniform(), y = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      const double f = f0 * (1.0 + 0.04 * std::sin(kTwoPi * vib_hz * static_cast<double>(k) / fs + vib_ph));
      phase += f / fs;
      double x = 0.0;
      if (phase >= 1.0) {
        phase -= 1.0;
        x = 1.0;  // glottal pulse
      }
      y = a * y + (1.0 - a) * x;
      out[k] += level * env[k] * y * 40.0;  // ~unit scale of a voiced talker before normalisation
    }
    // fricatives: Poisson, ~2 per second
    double t = rng.exponential(0.5);
    const double total = static_cast<double>(n) / fs;
    while (t < total) {
      const auto len = static_cast<std::size_t>(rng.uniform(0.06, 0.15) * fs);
      add_bright_noise(out, static_cast<std::size_t>(t * fs), len, level * rng.uniform(0.3, 1.0), 0.0, true, fs, rng);
      t += rng.exponential(0.5);
    }
  }
}

void music(std::vector<double>& out, double fs, Rng& rng) {
  const std::size_t n = out.size();
  const double beat_s = rng.uniform(0.2, 0.5);
  // notes
  for (std::size_t k = 0; k < n;) {
    const auto len = static_cast<std::size_t>(rng.uniform(0.15, 0.4) * fs);
    const double f = 130.0 * std::pow(2.0, rng.uniform(0.0, 3.0));
    const double tau = rng.uniform(0.1, 0.4);
    const double level = rng.uniform(0.5, 1.0);
    double ph = rng.uniform();
    for (std::size_t i = 0; i < len && k + i < n; ++i) {
      ph += f / fs;
      ph -= std::floor(ph);
      const double saw = 2.0 * ph - 1.0;  // every harmonic at 1/k
      out[k + i] += level * std::exp(-static_cast<double>(i) / (tau * fs)) * saw;
    }
    k += std::max<std::size_t>(len, 1);
  }
  // hi-hats on every beat
  const double hat_level = rng.uniform(0.5, 1.5);
  for (double t = rng.uniform(0.0, beat_s); t < static_cast<double>(n) / fs; t += beat_s) {
    const double tau = rng.uniform(0.015, 0.06);
    add_bright_noise(out, static_cast<std::size_t>(t * fs), static_cast<std::size_t>(6.0 * tau * fs),
                     hat_level, tau, false, fs, rng);
  }
}

}  // namespace

std::vector<double> synth_interference(InterferenceKind kind, std::size_t frames, double fs, Rng& rng) {
  if (!(fs > 0.0)) throw std::invalid_argument("synth_interference: sample rate must be > 0");
  std::vector<double> out(frames, 0.0);
  if (frames == 0) return out;
  if (kind == InterferenceKind::Babble)
    babble(out, fs, rng);
  else
    music(out, fs, rng);
  // remove DC, fade in/out, unit RMS
  double mean = 0.0;
  for (double v : out) mean += v;
  mean /= static_cast<double>(frames);
  const auto fade = std::min<std::size_t>(static_cast<std::size_t>(0.02 * fs), frames / 2);
  double e = 0.0;
  for (std::size_t k = 0; k < frames; ++k) {
    double v = out[k] - mean;
    if (fade > 0 && k < fade) v *= 0.5 - 0.5 * std::cos(std::numbers::pi * static_cast<double>(k) / fade);
    if (fade > 0 && frames - 1 - k < fade)
      v *= 0.5 - 0.5 * std::cos(std::numbers::pi * static_cast<double>(frames - 1 - k) / fade);
    out[k] = v;
    e += v * v;
  }
  const double rms = std::sqrt(e / static_cast<double>(frames));
  if (rms > 0.0)
    for (double& v : out) v /= rms;
  return out;
}

}  // namespace locus::sim
