// Family `locble`: locating BLE tags from RSS while the observer walks an L (paper 003, LocBLE).
//
// Paper setup reproduced: the observer walks an L (first leg 2-3 m, a 90° turn, second leg
// 1.5-2.5 m: 3.5-5 m in total, Sec. 5.2) holding a phone that scans BLE (10 Hz advertising, Sec. 7)
// and logs its IMU with magnetometer; 1-6 tags (iBeacon-like, tx power −65..−55 dBm at 1 m) sit
// 4-9 m away, the target to the side of the first leg, `clustered` of the others within 0.3-1 m of
// it (Sec. 6: neighbouring beacons), the rest elsewhere. RSS follows the log-distance model with
// LOS / partial-LOS / NLOS exponents (motion/ble.hpp); env = los | plos | nlos | mixed (mixed: NLOS
// behind a wall for the first part of the walk, then LOS, with people crossing (p-LOS) at random).
// No audio. Truth: truth.csv (observer, tags), truth_steps.csv.
#include <cmath>
#include <numbers>

#include "locus/sim/families.hpp"
#include "locus/sim/motion/ble.hpp"
#include "locus/sim/motion/walking.hpp"

namespace locus::sim {

Simulation make_locble(const FamilyOptions& opts) {
  using namespace motion;
  const DifficultyProfile prof = difficulty_profile(opts.difficulty);
  const int tags = static_cast<int>(opts.get_int("tags", 3, 1, 6));
  const int clustered = static_cast<int>(opts.get_int("clustered", std::min(2, tags - 1), 0, 5));
  if (clustered > tags - 1)
    throw std::invalid_argument("option 'clustered': at most tags − 1 = " + std::to_string(tags - 1) + ", got " +
                                std::to_string(clustered));
  const std::string env = opts.get_choice("env", "los", {"los", "plos", "nlos", "mixed"});
  const std::string turn = opts.get_choice("turn", "left", {"left", "right"});
  const double interval_s = opts.get_double("interval_s", 0.1, 0.02, 10.0);
  opts.finish("locble");

  Simulation sim;
  sim.name = "locble-lshape";
  sim.family = "locble";
  sim.seed = opts.seed;
  Rng layout = Rng::derive(opts.seed, "locble/layout");
  Rng clocks = Rng::derive(opts.seed, "locble/clocks");
  const double decl = layout.uniform(0.0, 2.0 * std::numbers::pi);
  sim.magnetic_field_world_ut = Eigen::Vector3d(19.0 * std::cos(decl), 19.0 * std::sin(decl), -44.0);

  // The L: start at (2, 2) heading +x, turn towards the target's side.
  const double leg1 = layout.uniform(2.0, 3.0), leg2 = layout.uniform(1.5, 2.5);
  const double side = turn == "left" ? 1.0 : -1.0;
  PedestrianParams pp;
  pp.path_m = {{2.0, 2.0}, {2.0 + leg1, 2.0}, {2.0 + leg1, 2.0 + side * leg2}};
  pp.height_m = layout.uniform(1.60, 1.90);
  pp.step_freq_hz = layout.uniform(1.6, 2.0);
  pp.turn_length_m = 0.6;
  pp.start_rest_s = 1.5;
  pp.end_rest_s = 1.5;
  const double t0 = prof.offset_s_max + 0.5;
  auto walk = std::make_shared<PedestrianTrajectory>(pp, t0, Rng::derive(opts.seed, "locble/walk").next_u64());

  // Tags: the target to the turn side of the first leg, 4-9 m from the start.
  const double d_target = layout.uniform(4.0, 9.0);
  const double ang = side * layout.uniform(20.0, 70.0) * std::numbers::pi / 180.0;
  const Eigen::Vector3d target(2.0 + d_target * std::cos(ang), 2.0 + d_target * std::sin(ang), layout.uniform(0.5, 1.5));
  for (int i = 0; i < tags; ++i) {
    Eigen::Vector3d pos = target;
    if (i >= 1 && i <= clustered) {
      const double r = layout.uniform(0.3, 1.0), a = layout.uniform(0.0, 2.0 * std::numbers::pi);
      pos += Eigen::Vector3d(r * std::cos(a), r * std::sin(a), layout.uniform(-0.3, 0.3));
    } else if (i > clustered) {
      const double r = layout.uniform(4.0, 9.0), a = layout.uniform(-std::numbers::pi, std::numbers::pi);
      pos = Eigen::Vector3d(2.0 + r * std::cos(a), 2.0 + r * std::sin(a), layout.uniform(0.3, 2.0));
    }
    EmitterModel e;
    e.id = "tag" + std::to_string(i + 1);
    dsp::SignalSpec s;
    s.type = "ble";
    char addr[24];
    std::snprintf(addr, sizeof addr, "C4:2C:03:%02X:%02X:%02X", static_cast<unsigned>(layout.integer(0, 255)),
                  static_cast<unsigned>(layout.integer(0, 255)), static_cast<unsigned>(i + 1));
    s.address = addr;
    s.tx_power_dbm = std::round(layout.uniform(-65.0, -55.0));
    s.interval_s = interval_s;
    e.emits = {s};
    e.trajectory = std::make_shared<StaticTrajectory>(pos);
    sim.emitters.push_back(e);
  }

  // Propagation: fixed class, or NLOS for the first 40 % of the walk then LOS; people crossing (p-LOS).
  const double t_switch = walk->walk_start_s() + 0.4 * (walk->walk_end_s() - walk->walk_start_s());
  std::vector<std::pair<double, double>> crossings;
  const double crossing_rate = env == "mixed" ? 0.15 + 0.1 * prof.imu_noise_scale : 0.0;  // per second
  for (double t = 0.0; t < walk->end_s() + 1.0; t += 1.0)
    if (layout.bernoulli(crossing_rate)) crossings.emplace_back(t, t + layout.uniform(0.5, 1.5));
  PropagationFn envfn = [env, t_switch, crossings](const std::string&, const Eigen::Vector3d&, const Eigen::Vector3d&,
                                                  double t) {
    if (env == "los") return Propagation::los;
    if (env == "plos") return Propagation::partial;
    if (env == "nlos") return Propagation::nlos;
    if (t < t_switch) return Propagation::nlos;
    for (const auto& [a, b] : crossings)
      if (t >= a && t < b) return Propagation::partial;
    return Propagation::los;
  };
  BleChannelParams bp;
  bp.rx_offset_db = layout.normal(0.0, 3.0);
  bp.loss_probability = 0.05 * prof.imu_noise_scale * 2.0;  // easy 5 %, normal 10 %, hard 20 %

  DeviceModel phone;
  phone.id = "O";
  phone.trajectory = walk;
  phone.clock = draw_clock(prof, clocks);
  phone.record_audio = false;
  phone.imu = std::make_shared<PhoneImu>(phone_imu_config(100.0, prof.imu_noise_scale, true));
  phone.ble = std::make_shared<BleRssiModel>(bp, envfn);
  sim.devices.push_back(phone);

  sim.duration_s = opts.duration_s.value_or(walk->end_s() + 0.5);
  sim.acoustics.noise.enabled = false;
  sim.extra_files["truth_steps.csv"] = truth_steps_csv({{phone.id, walk.get()}});
  sim.environment_yaml = "propagation: " + env + ", turn: " + turn + ", truth_steps: truth_steps.csv";
  return sim;
}

}  // namespace locus::sim

// ------------------------------------------------------------------------------------------ registration
// The family's entry in the table of `locus simulate` (generated from this folder, families.hpp).
namespace locus::sim::registered_families {

const Family& locble() {
  static const Family family{
      "locble",
      "LocBLE (paper 003): an observer walks an L (3.5-5 m) scanning BLE; 1-6 tags 4-9 m away, some clustered "
      "within 1 m of the target; log-distance RSS with LOS/p-LOS/NLOS exponents; IMU; no audio",
      {{"tags", "int", "3", "number of tags (1..6); tag1 is the target"},
       {"clustered", "int", "min(2, tags-1)", "tags placed within 0.3-1 m of the target"},
       {"env", "los|plos|nlos|mixed", "los", "propagation class (mixed: NLOS then LOS, people crossing)"},
       {"turn", "left|right", "left", "direction of the L's turn (the target is on that side)"},
       {"interval_s", "double", "0.1", "advertising interval (paper: 10 Hz)"}},
      make_locble};
  return family;
}

}  // namespace locus::sim::registered_families
