// Family `montage`: multi-user formation walking (paper 002, Montage).
//
// Paper setup reproduced: several users (default four) walk together in formation, each holding a
// phone; on every ranging round (period_s, "dt") all phones emit their own Gold-coded tone at once
// (r = 5, BPSK on a 19 kHz carrier, 100 samples per chip: ~70 ms, the paper's example), each records
// all of them, and each logs its IMU (accelerometer, gyroscope, magnetometer) for stride, step and
// heading estimation. Walkers differ in height, step frequency (1.7-2.1 Hz) and stride model;
// formation: pairs side by side (spacing_m apart), pairs one behind the other (row_gap_m).
// Truth: truth.csv (every phone), truth_steps.csv (heel strikes and stride lengths).
// The protocol's radio start signal: W1 broadcasts it once, 20 ms before the first round's command
// (every phone's sync.csv holds its reception, radio latency and jitter as the engine models them);
// every phone then emits once per period_s after it, plus its own speaker latency, as in the foreign
// Montage world. Deviation: outdoors = free field (no ground reflection).
#include <stdexcept>
#include <cmath>
#include <numbers>

#include "locus/sim/families.hpp"
#include "locus/sim/motion/walking.hpp"

namespace locus::sim {

Simulation make_montage(const FamilyOptions& opts) {
  using namespace motion;
  const DifficultyProfile prof = difficulty_profile(opts.difficulty);
  const int walkers = static_cast<int>(opts.get_int("walkers", 4, 2, 8));
  const std::string shape = opts.get_choice("path", "L", {"straight", "L", "loop"});
  const double period_s = opts.get_double("period_s", 1.0, 0.1, 30.0);
  const double spacing_m = opts.get_double("spacing_m", 1.5, 0.5, 10.0);
  const double row_gap_m = opts.get_double("row_gap_m", 2.0, 0.5, 10.0);
  const int chip_samples = static_cast<int>(opts.get_int("chip_samples", 100, 4, 1000));
  const double carrier_hz = opts.get_double("carrier_hz", 19000.0, 15000.0, 21000.0);
  const std::string room = opts.get_choice("room", "none", {"none", "hall"});
  const int degree = static_cast<int>(opts.get_int("degree", 5, 5, 11));
  const std::string formation = opts.get_choice("formation", "pairs", {"pairs", "free"});
  const double amplitude = opts.get_double("amplitude", 1.0, 0.001, 1.0);
  opts.finish("montage");
  if (degree == 8) throw std::invalid_argument("montage: degree 8 has no preferred Gold pair (5, 6, 7, 9, 10, 11)");
  if (formation == "free" && room != "hall")
    throw std::invalid_argument("montage: formation=free walks in the hall: add -o room=hall");

  Simulation sim;
  sim.name = "montage-formation";
  sim.family = "montage";
  sim.seed = opts.seed;
  if (room == "hall") {
    sim.acoustics.room = Room{};
    sim.acoustics.room->size_m = {40.0, 30.0, 6.0};
  }
  apply_profile(prof, sim.acoustics);
  Rng layout = Rng::derive(opts.seed, "montage/layout");
  Rng clocks = Rng::derive(opts.seed, "montage/clocks");
  Rng latency = Rng::derive(opts.seed, "montage/latency");
  const double decl = layout.uniform(0.0, 2.0 * std::numbers::pi);
  sim.magnetic_field_world_ut = Eigen::Vector3d(19.0 * std::cos(decl), 19.0 * std::sin(decl), -44.0);

  std::vector<Eigen::Vector2d> path;
  if (shape == "straight") path = {{5, 5}, {30, 5}};
  else if (shape == "L") path = {{5, 5}, {21, 5}, {21, 17}};
  else path = {{8, 8}, {24, 8}, {24, 20}, {8, 20}, {8, 8.5}};

  const double t_start = prof.offset_s_max + 1.0;
  std::vector<std::pair<std::string, const PedestrianTrajectory*>> step_truth;
  double t_end = 0.0;
  for (int i = 0; i < walkers; ++i) {
    const int row = i / 2, col = i % 2;
    const double lateral = (col == 0 ? 0.5 : -0.5) * spacing_m;
    PedestrianParams pp;
    if (formation == "free") {
      // Each walker on its own route through the middle of the hall (4 random waypoints in a 16x12 m
      // area): the group spreads 1-20 m apart and walkers approach and leave each other at up to ~3 m/s
      // (Doppler up to ~±160 Hz at 19 kHz), as in the foreign Montage world.
      std::vector<Eigen::Vector2d> own;
      for (int k = 0; k < 4; ++k) own.emplace_back(layout.uniform(12.0, 28.0), layout.uniform(9.0, 21.0));
      pp.path_m = own;
    } else {
      pp.path_m = offset_polyline(path, lateral);
    }
    pp.height_m = layout.uniform(1.60, 1.90);
    pp.step_freq_hz = layout.uniform(1.7, 2.1);
    pp.stride_a_m_s = 0.143 * pp.height_m * layout.uniform(0.9, 1.1);
    pp.stride_b_m = 0.143 * pp.height_m * layout.uniform(0.9, 1.1);
    // The rear row starts later by the time it takes to walk row_gap_m.
    const double speed = (*pp.stride_a_m_s * pp.step_freq_hz + *pp.stride_b_m) * pp.step_freq_hz;
    pp.start_rest_s = formation == "free" ? layout.uniform(0.5, 1.5) : 1.0 + row * row_gap_m / speed;
    auto traj = std::make_shared<PedestrianTrajectory>(pp, t_start - 1.0, Rng::derive(opts.seed, "montage/walk" + std::to_string(i)).next_u64());
    t_end = std::max(t_end, traj->end_s());

    DeviceModel d;
    d.id = "W" + std::to_string(i + 1);
    d.mics_body_m = {{0.0, -0.070, 0.0}};
    d.speaker_body_m = Eigen::Vector3d(0.0, -0.075, 0.0);
    dsp::SignalSpec gold;
    gold.type = "gold";
    gold.degree = degree;
    gold.index = 2 + i;
    gold.carrier_hz = carrier_hz;
    gold.chip_samples = chip_samples;
    gold.amplitude = amplitude;
    d.emits = {gold};
    d.trajectory = traj;
    d.clock = draw_clock(prof, clocks);
    d.speaker_response = {300.0, 0.0, 2};
    d.mic_response = {60.0, 0.0, 2};
    d.imu = std::make_shared<PhoneImu>(phone_imu_config(100.0, prof.imu_noise_scale, true));
    d.record_sync = true;
    // Recording level: the phone's own tone (its speaker 5 mm from the mic) peaks at half full scale,
    // as a phone sets its input level; at unit gain the 1/r self-path clipped it (TUM does the same).
    {
      const double r_self = std::max(1e-3, (d.mics_body_m[0] - *d.speaker_body_m).norm());
      d.mic_gain = 0.5 * r_self / (sim.acoustics.level_at_1m * d.source_level * d.self_gain * amplitude);
    }
    step_truth.emplace_back(d.id, traj.get());
    sim.devices.push_back(std::move(d));
  }
  for (std::size_t a = 0; a < sim.devices.size(); ++a)
    for (std::size_t b = a + 1; b < sim.devices.size(); ++b)
      if (layout.bernoulli(prof.obstruction_probability))  // a body between two phones
        sim.acoustics.obstructions.push_back(Obstruction{sim.devices[a].id, sim.devices[b].id, prof.obstruction_db});

  sim.duration_s = opts.duration_s.value_or(t_end + 0.5);
  sim.radio_broadcasts.emplace_back(t_start - 0.5 - 0.02, sim.devices.front().id);
  for (double t = t_start - 0.5; t + 0.2 < sim.duration_s; t += period_s) {
    for (const auto& d : sim.devices) {
      Emission e;
      e.source_id = d.id;
      e.t_command_true_s = t;
      e.latency_s = prof.latency.draw(latency);
      sim.emissions.push_back(e);
    }
  }
  sim.extra_files["truth_steps.csv"] = truth_steps_csv(step_truth, sim.duration_s);
  sim.environment_yaml = "path: " + shape + ", walkers: " + std::to_string(walkers) +
                         ", truth_steps: truth_steps.csv, outdoor: " + (room == "none" ? "true" : "false");
  return sim;
}

}  // namespace locus::sim

// ------------------------------------------------------------------------------------------ registration
// The family's entry in the table of `locus simulate` (generated from this folder, families.hpp).
namespace locus::sim::registered_families {

const Family& montage() {
  static const Family family{
      "montage",
      "Montage (paper 002): 2-8 walkers in formation (pairs side by side), every phone emits its Gold code "
      "(r=5) on 19 kHz at once each round; IMU with magnetometer; truth_steps.csv",
      {{"walkers", "int", "4", "number of walkers (2..8)"},
       {"path", "straight|L|loop", "L", "the formation's route"},
       {"period_s", "double", "1.0", "ranging round period (all phones emit together)"},
       {"spacing_m", "double", "1.5", "side-by-side spacing in a pair"},
       {"row_gap_m", "double", "2.0", "distance between pairs (one behind the other)"},
       {"chip_samples", "int", "100", "samples per Gold chip (paper example: 100)"},
       {"carrier_hz", "double", "19000", "BPSK carrier"},
       {"room", "none|hall", "none", "free field (outdoor) or a 40x30x6 m hall"},
       {"degree", "int", "5", "Gold code degree r (5, 6, 7, 9, 10, 11; the foreign Montage world: 7)"},
       {"amplitude", "double", "1.0", "Gold tone amplitude a (0..1; 1 clips the own tone at the phone's mic 5 mm "
        "from its speaker in the hall)"},
       {"formation", "pairs|free", "pairs", "pairs side by side on one route, or free: every walker on its own "
        "random route in the hall (1-20 m apart, relative speeds up to ~3 m/s; needs room=hall)"}},
      make_montage};
  return family;
}

}  // namespace locus::sim::registered_families
