// Helpers for the simulator tests: a quiet free-field scene and a sub-sample arrival fit against
// the closed-form signal.
#pragma once

#include <cmath>
#include <memory>
#include <vector>

#include "locus/dsp/signals.hpp"
#include "locus/sim/engine.hpp"

namespace locus::sim::test {

inline dsp::SignalSpec test_chirp(double f0 = 2000, double f1 = 8000, double dur = 0.04) {
  dsp::SignalSpec c;
  c.type = "lfm";
  c.f0_hz = f0;
  c.f1_hz = f1;
  c.duration_s = dur;
  c.fade_s = 0.004;
  c.amplitude = 1.0;
  return c;
}

/// Free field, no noise, no band limits: the rendered audio is the pure propagation model.
inline Simulation quiet_simulation(double duration_s = 2.0) {
  Simulation s;
  s.name = "test";
  s.seed = 3;
  s.duration_s = duration_s;
  s.acoustics.noise.enabled = false;
  s.acoustics.band_limits = false;
  s.audio_format = scene::WavSampleFormat::Float32;
  return s;
}

inline DeviceModel listener(const std::string& id, const Eigen::Vector3d& pos, scene::ClockTruth clock = {}) {
  DeviceModel d;
  d.id = id;
  d.mics_body_m = {Eigen::Vector3d::Zero()};
  d.trajectory = std::make_shared<StaticTrajectory>(pos);
  d.clock = clock;
  return d;
}

inline EmitterModel emitter(const std::string& id, std::shared_ptr<const Trajectory> tr, dsp::SignalSpec sig) {
  EmitterModel e;
  e.id = id;
  e.emits = {sig};
  e.trajectory = std::move(tr);
  return e;
}

/// Fits the arrival (fractional local frame) of `spec` in `x` (frames from 0): maximises the
/// normalised correlation Σ x[k]·s((k − τ)/(fs·time_scale)) over τ (time_scale = 1 + skew·1e-6 of
/// the recording device: its sample grid stretches the received signal), coarse on a 0.05-sample grid around `guess_frame`
/// ± search, then golden-section to 1e-4 samples.
inline double fit_arrival_frame(const std::vector<float>& x, const dsp::SignalSpec& spec, double fs, double guess_frame,
                                double search_frames, double time_scale = 1.0) {
  const dsp::SignalEvaluator ev(spec, fs);
  const double len = ev.duration_s() * fs * time_scale;
  auto score = [&](double tau_frames) {
    double num = 0.0, den = 0.0;
    const auto k0 = static_cast<long>(std::floor(tau_frames)) - 1;
    const auto k1 = static_cast<long>(std::ceil(tau_frames + len)) + 1;
    for (long k = std::max(0L, k0); k <= k1 && k < static_cast<long>(x.size()); ++k) {
      const double s = ev.value((static_cast<double>(k) - tau_frames) / (fs * time_scale));
      num += x[static_cast<std::size_t>(k)] * s;
      den += s * s;
    }
    return den > 0 ? num / std::sqrt(den) : 0.0;
  };
  double best = guess_frame, best_v = -1e300;
  for (double t = guess_frame - search_frames; t <= guess_frame + search_frames; t += 0.05) {
    const double v = score(t);
    if (v > best_v) {
      best_v = v;
      best = t;
    }
  }
  double a = best - 0.05, b = best + 0.05;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  while (b - a > 1e-4) {
    const double c = b - g * (b - a), d = a + g * (b - a);
    if (score(c) > score(d))
      b = d;
    else
      a = c;
  }
  return 0.5 * (a + b);
}

}  // namespace locus::sim::test
