// Writes the scene checked by sim_reference.py (an independent numpy/scipy reproduction of a chirp
// arrival): two static devices in free field, skewed/offset clocks, a speaker latency, no noise, no
// reflections, no band limits, float32 WAV. Usage: locus_sim_reference_scene OUT_DIR
#include <iostream>

#include "locus/sim/engine.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: locus_sim_reference_scene OUT_DIR\n";
    return 2;
  }
  using namespace locus::sim;
  Simulation s;
  s.name = "scipy-reference";
  s.seed = 42;
  s.duration_s = 6.0;
  s.acoustics.noise.enabled = false;
  s.acoustics.band_limits = false;
  s.audio_format = locus::scene::WavSampleFormat::Float32;

  locus::dsp::SignalSpec chirp;
  chirp.type = "lfm";
  chirp.f0_hz = 2000;
  chirp.f1_hz = 8000;
  chirp.duration_s = 0.040;
  chirp.fade_s = 0.005;
  chirp.amplitude = 0.8;

  DeviceModel tx;
  tx.id = "TX";
  tx.mics_body_m = {{0.0, -0.07, 0.0}};
  tx.speaker_body_m = Eigen::Vector3d(0.02, -0.07, 0.0);
  tx.emits = {chirp};
  tx.trajectory = std::make_shared<StaticTrajectory>(Eigen::Vector3d(0.5, 0.8, 1.0), flat_attitude({1.0, 0.3}));
  tx.clock = {0.731, -23.0};
  DeviceModel rx;
  rx.id = "RX";
  rx.mics_body_m = {{0.0, 0.065, 0.0}, {0.0, -0.065, 0.0}};
  rx.trajectory = std::make_shared<StaticTrajectory>(Eigen::Vector3d(2.9, 2.2, 1.3), flat_attitude({-0.4, 1.0}));
  rx.clock = {2.113, 61.0};
  s.devices = {tx, rx};
  s.emissions = {Emission{"TX", 0, 1.5, 0.0731}, Emission{"TX", 0, 4.25, 0.1207}};
  try {
    SceneSimulator(s).write(argv[1]);
  } catch (const std::exception& e) {
    std::cerr << "locus_sim_reference_scene: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
