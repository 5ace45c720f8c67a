// Family `locble`: locating BLE tags from RSS while the observer walks an L (paper 003, LocBLE).
//
// Paper setup reproduced: the observer walks an L (first leg 2-3 m, a 90° turn, second leg
// 1.5-2.5 m: 3.5-5 m in total, Sec. 5.2) holding a phone that scans BLE (10 Hz advertising, Sec. 7)
// and logs its IMU with magnetometer; 1-6 tags (iBeacon-like, tx power −65..−55 dBm at 1 m) sit
// 4-9 m away (either side of the first leg, from straight ahead to abeam: a tag near the first leg's
// line leaves that leg's mirror nearly on top of it, as in the foreign locble-105), `clustered` of the
// others within 0.3-1 m of it (Sec. 6: neighbouring beacons), the rest anywhere 4-14 m from the start
// (far tags: a few metres of walk barely move their RSS). RSS follows the log-distance model with
// LOS / partial-LOS / NLOS exponents (motion/ble.hpp); env = los | plos | nlos | mixed (mixed: NLOS
// behind a wall for the first part of the walk, then LOS, with people crossing (p-LOS) at random) |
// world (the default, as hard as the foreign generator of ../shared/scenes/README.md: the class of
// every packet from geometry — walls between some tags and the walk (NLOS while the wall cuts the
// line of sight), people standing near some lines of sight and bystanders walking through them
// (p-LOS) — plus per-link exponents, per-link static shadowing per class, per-tag channel offsets, a
// true 1 m power that is not the advertised one, spatially correlated shadowing over 2 m, Rician
// fading per packet, a per-receiver offset, bursty (Gilbert-Elliott) loss, whole dBm).
// `walk=long` walks 2.5-4.5 m per leg (the foreign scenes' 4-6 steps) instead of the paper's.
// No audio. Truth: truth.csv (observer, tags), truth_steps.csv, truth_ble_env.csv (class per tag, 0.1 s).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "locus/sim/families.hpp"
#include "locus/sim/motion/ble.hpp"
#include "locus/sim/motion/walking.hpp"

namespace locus::sim {

Simulation make_locble(const FamilyOptions& opts) {
  using namespace motion;
  const DifficultyProfile prof = difficulty_profile(opts.difficulty);
  const int tags = static_cast<int>(opts.get_int("tags", 3, 1, 6));
  const int clustered = static_cast<int>(opts.get_int("clustered", std::min(1, tags - 1), 0, 5));
  if (clustered > tags - 1)
    throw std::invalid_argument("option 'clustered': at most tags − 1 = " + std::to_string(tags - 1) + ", got " +
                                std::to_string(clustered));
  const std::string env = opts.get_choice("env", "world", {"los", "plos", "nlos", "mixed", "world"});
  const std::string walk_kind = opts.get_choice("walk", "paper", {"paper", "long"});
  // Each condition of env=world can be switched off alone (same layout and draws otherwise), to
  // measure what it costs a localizer (docs/locble.md, "Simulator").
  const bool c_walls = opts.get_bool("walls", true), c_people = opts.get_bool("people", true);
  const bool c_bystanders = opts.get_bool("bystanders", true), c_links = opts.get_bool("links", true);
  const bool c_bursts = opts.get_bool("bursts", true), c_fading = opts.get_bool("fading", true);
  const bool c_shadowing = opts.get_bool("shadowing", true), c_rx_offset = opts.get_bool("rx_offset", true);
  const bool c_loss = opts.get_bool("loss", true), c_quantize = opts.get_bool("quantize", true);
  const std::string turn = opts.get_choice("turn", "left", {"left", "right"});
  const double interval_s = opts.get_double("interval_s", 0.1, 0.02, 10.0);
  const bool target_any = opts.get_choice("target_side", env == "world" ? "any" : "turn", {"turn", "any"}) == "any";
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
  const bool long_walk = walk_kind == "long";
  const double leg1 = long_walk ? layout.uniform(2.5, 4.5) : layout.uniform(2.0, 3.0);
  const double leg2 = long_walk ? layout.uniform(2.5, 4.5) : layout.uniform(1.5, 2.5);
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

  // Tags: the target 4-9 m from the start, 0-80° either side of the first leg (`target_side`: turn =
  // the paper's layout, the turn's side 20-70°; any = the world's, the foreign scenes put tags ahead
  // and on the far side of the turn too).
  const double d_target = layout.uniform(4.0, 9.0);
  const double ang = target_any ? (layout.bernoulli(0.5) ? 1.0 : -1.0) * layout.uniform(0.0, 80.0) * std::numbers::pi / 180.0
                                : side * layout.uniform(20.0, 70.0) * std::numbers::pi / 180.0;
  const Eigen::Vector3d target(2.0 + d_target * std::cos(ang), 2.0 + d_target * std::sin(ang), layout.uniform(0.5, 1.5));
  for (int i = 0; i < tags; ++i) {
    Eigen::Vector3d pos = target;
    if (i >= 1 && i <= clustered) {
      const double r = layout.uniform(0.3, 1.0), a = layout.uniform(0.0, 2.0 * std::numbers::pi);
      pos += Eigen::Vector3d(r * std::cos(a), r * std::sin(a), layout.uniform(-0.3, 0.3));
    } else if (i > clustered) {
      const double r = layout.uniform(4.0, target_any ? 14.0 : 9.0), a = layout.uniform(-std::numbers::pi, std::numbers::pi);
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

  // Propagation: fixed class, or NLOS for the first 40 % of the walk then LOS; people crossing (p-LOS);
  // or (world) from the geometry of walls, standing people and walking bystanders.
  const double t_switch = walk->walk_start_s() + 0.4 * (walk->walk_end_s() - walk->walk_start_s());
  std::vector<std::pair<double, double>> crossings;
  const double crossing_rate = env == "mixed" ? 0.15 + 0.1 * prof.imu_noise_scale : 0.0;  // per second
  for (double t = 0.0; t < walk->end_s() + 1.0; t += 1.0)
    if (layout.bernoulli(crossing_rate)) crossings.emplace_back(t, t + layout.uniform(0.5, 1.5));
  using Seg = std::pair<Eigen::Vector2d, Eigen::Vector2d>;
  struct Walker {
    Eigen::Vector2d p0, v;
    double t0;
  };
  std::vector<Seg> walls, people;
  std::vector<Walker> bystanders;
  Rng world = Rng::derive(opts.seed, "locble/world");
  if (env == "world") {
    const double hard = prof.imu_noise_scale;  // easy 0.5, normal 1, hard 2 (difficulty_profile)
    const Eigen::Vector2d mid(2.0 + 0.5 * leg1, 2.0 + 0.5 * side * leg2);
    for (const auto& e : sim.emitters) {
      const Eigen::Vector2d tag = e.trajectory->pose(0.0).position_m.head<2>();
      const Eigen::Vector2d to_walk = mid - tag;
      if (to_walk.norm() < 1.5) continue;
      const Eigen::Vector2d u = to_walk.normalized(), perp(-u.y(), u.x());
      if (world.bernoulli(std::min(0.6, 0.3 * hard))) {  // a wall across part of the views to the walk
        const Eigen::Vector2d c = tag + world.uniform(0.3, 0.6) * to_walk + world.uniform(-1.5, 1.5) * perp;
        const double half = world.uniform(1.0, 2.5);
        if (c_walls) walls.push_back({c - half * perp, c + half * perp});
      }
      if (world.bernoulli(0.3)) {  // a person standing near the line of sight
        const Eigen::Vector2d c = tag + world.uniform(0.2, 0.8) * to_walk + world.uniform(-0.8, 0.8) * perp;
        if (c_people) people.push_back({c - 0.25 * perp, c + 0.25 * perp});
      }
    }
    const int nb = static_cast<int>(world.integer(1, 1 + static_cast<long long>(2 * hard)));
    for (int i = 0; i < nb; ++i) {
      const double a = world.uniform(0.0, 2.0 * std::numbers::pi), sp = world.uniform(0.7, 1.4);
      const Eigen::Vector2d p0 = mid + world.uniform(3.0, 10.0) * Eigen::Vector2d(std::cos(a), std::sin(a));
      const Eigen::Vector2d aim = mid + world.uniform(-3.0, 3.0) * Eigen::Vector2d(-std::sin(a), std::cos(a));
      const Walker b{p0, sp * (aim - p0).normalized(), walk->walk_start_s() + world.uniform(-3.0, 6.0)};
      if (c_bystanders) bystanders.push_back(b);
    }
  }
  auto crosses = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Seg& s) {
    auto cross = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q) { return p.x() * q.y() - p.y() * q.x(); };
    const Eigen::Vector2d r = b - a, q = s.second - s.first;
    const double den = cross(r, q);
    if (std::abs(den) < 1e-12) return false;
    const double t = cross(s.first - a, q) / den, v = cross(s.first - a, r) / den;
    return t > 0.0 && t < 1.0 && v > 0.0 && v < 1.0;
  };
  auto near_segment = [](const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b, double r) {
    const Eigen::Vector2d ab = b - a;
    const double f = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
    return (a + f * ab - p).norm() < r;
  };
  PropagationFn envfn = [env, t_switch, crossings, walls, people, bystanders, crosses, near_segment](
                            const std::string&, const Eigen::Vector3d& tag3, const Eigen::Vector3d& rx3, double t) {
    if (env == "los") return Propagation::los;
    if (env == "plos") return Propagation::partial;
    if (env == "nlos") return Propagation::nlos;
    if (env == "world") {
      const Eigen::Vector2d tag = tag3.head<2>(), rx = rx3.head<2>();
      for (const Seg& w : walls)
        if (crosses(tag, rx, w)) return Propagation::nlos;
      for (const Seg& p : people)
        if (crosses(tag, rx, p)) return Propagation::partial;
      for (const Walker& b : bystanders)
        if (t >= b.t0 && near_segment(b.p0 + (t - b.t0) * b.v, tag, rx, 0.3)) return Propagation::partial;
      return Propagation::los;
    }
    if (t < t_switch) return Propagation::nlos;
    for (const auto& [a, b] : crossings)
      if (t >= a && t < b) return Propagation::partial;
    return Propagation::los;
  };
  BleChannelParams bp;
  bp.rx_offset_db = layout.normal(0.0, 3.0);
  // easy 5 %, normal 10 %, hard 20 %; env=world 3x that (easy 15 %, normal 30 %: the foreign
  // generator's target_loss 0.3 at normal), before the bursts.
  bp.loss_probability = std::min(0.6, 0.05 * prof.imu_noise_scale * 2.0 * (env == "world" ? 3.0 : 1.0));
  if (!c_rx_offset) bp.rx_offset_db = 0.0;
  if (!c_loss) bp.loss_probability = 0.0;
  bp.fading = c_fading;
  bp.quantize = c_quantize;
  if (env == "world") {
    // Exponents and losses of the indoor 2.4 GHz literature; the per-link spread is what makes every
    // tag's effective (Γ, n) unknown to the localizer.
    bp.exponent = {2.0, 2.5, 3.0};
    bp.extra_loss_db = {0.0, 2.0, 6.0};
    bp.shadowing_std_db = {1.5, 2.0, 2.5};
    bp.decorrelation_m = 2.0;
    bp.channel_offset_db = {0.0, 0.0, 0.0};
    bp.burst_enter_probability = 0.04 * prof.imu_noise_scale;
    bp.burst_exit_probability = 0.3;
    if (!c_bursts) bp.burst_enter_probability = 0.0;
    if (!c_shadowing) bp.shadowing_std_db = {0.0, 0.0, 0.0};
    for (const auto& e : sim.emitters) {
      BleTagChannel c;
      for (std::size_t k = 0; k < 3; ++k) {
        c.exponent_offset[k] = world.uniform(-0.25, 0.25);
        // σ 4 dB at normal: the foreign generator's per-class offsets of locble-105 (-8.9 to +4.4 dB
        // over 2 tags x 3 classes) have a spread of ~4.5 dB.
        c.static_offset_db[k] = world.normal(0.0, 2.0 + 2.0 * prof.imu_noise_scale);
        c.channel_offset_db[k] = world.normal(0.0, 1.5);
      }
      c.tx_bias_db = world.normal(2.0, 2.0);
      if (c_links) bp.tags[e.id] = c;
    }
  }

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
  sim.extra_files["truth_steps.csv"] = truth_steps_csv({{phone.id, walk.get()}}, sim.duration_s);
  // The propagation class of every tag's link every 0.1 s (true time): labels for EnvAware training
  // (`locus train locble`) and for measuring it; never read by a localizer.
  {
    std::string csv = "t_true,tag,env\n";
    static const char* kLabel[3] = {"LOS", "pLOS", "NLOS"};
    for (double t = 0.0; t < walk->end_s() + 0.5; t += 0.1)
      for (const auto& e : sim.emitters) {
        const Propagation pr = envfn(e.id, e.trajectory->pose(t).position_m, walk->pose(t).position_m, t);
        char line[96];
        std::snprintf(line, sizeof line, "%.3f,%s,%s\n", t, e.id.c_str(), kLabel[static_cast<int>(pr)]);
        csv += line;
      }
    sim.extra_files["truth_ble_env.csv"] = csv;
  }
  sim.environment_yaml = "propagation: " + env + ", turn: " + turn +
                         ", truth_steps: truth_steps.csv, truth_ble_env: truth_ble_env.csv";
  return sim;
}

}  // namespace locus::sim

// ------------------------------------------------------------------------------------------ registration
// The family's entry in the table of `locus simulate` (generated from this folder, families.hpp).
namespace locus::sim::registered_families {

const Family& locble() {
  static const Family family{
      "locble",
      "LocBLE (paper 003): an observer walks an L (3.5-5 m) scanning BLE; 1-6 tags 4-14 m away, either side, some clustered "
      "within 1 m of the target; log-distance RSS with LOS/p-LOS/NLOS exponents; IMU; no audio",
      {{"tags", "int", "3", "number of tags (1..6); tag1 is the target"},
       {"clustered", "int", "min(1, tags-1)", "tags placed within 0.3-1 m of the target (the rest: 4-14 m from the start, any direction)"},
       {"target_side", "turn|any", "env=world: any, else turn",
        "turn: the target 20-70 deg to the turn's side of the first leg (paper); any: 0-80 deg either side (world)"},
       {"env", "los|plos|nlos|mixed|world", "world",
        "propagation (mixed: NLOS then LOS, people crossing; world: walls, people, bystanders, per-link channels)"},
       {"walk", "paper|long", "paper", "leg lengths: paper 2-3 m + 1.5-2.5 m; long 2.5-4.5 m each (foreign scenes)"},
       {"walls", "bool", "1", "env=world: walls (0 = none; every condition below can be switched off alone)"},
       {"people", "bool", "1", "env=world: people standing near lines of sight"},
       {"bystanders", "bool", "1", "env=world: walking bystanders"},
       {"links", "bool", "1", "env=world: per-link exponents, static shadowing, channel offsets, tx bias"},
       {"bursts", "bool", "1", "env=world: bursty loss"},
       {"fading", "bool", "1", "Rician fading per packet"},
       {"shadowing", "bool", "1", "env=world: spatially correlated shadowing"},
       {"rx_offset", "bool", "1", "receiver offset"},
       {"loss", "bool", "1", "random packet loss"},
       {"quantize", "bool", "1", "whole dBm"},
       {"turn", "left|right", "left", "direction of the L's turn (the target is on that side)"},
       {"interval_s", "double", "0.1", "advertising interval (paper: 10 Hz)"}},
      make_locble};
  return family;
}

}  // namespace locus::sim::registered_families
