// Family `spyloc`: a walker localised by fixed beacons' radio sync + multitone beeps (paper 001).
//
// Paper setup reproduced: 3 (or 4) beacon devices at known positions, 16-22 m apart, in a hall;
// every beep_period_s each beacon broadcasts a radio message (Wi-Fi beacon frame) and plays its beep
// sync_delay_s later (RF-Beep: kernel-integrated, so the delay is fixed and known: no speaker
// latency). A beep is the subset of 10 tones 18000 + 250·k Hz (k = 0..9) selected by the low ten
// bits of the beacon's MAC address, 50 ms. The user walks a loop with a phone (mic, IMU,
// sync.csv); an interior wall blocks the direct path to some beacons on parts of the loop (NLOS
// stretches: the first path is knife-edge diffracted around the wall's nearer end, longer and
// 20-30 dB down; diffraction=0: the direct path attenuated by nlos_db). The wall is a partition from
// floor to ceiling: the reflections whose route crosses it (floor and ceiling ones, in the direct
// path's vertical plane, and side-wall ones through it) lose the same, those around it are kept, as
// is the diffuse tail (issue 16: on the foreign spyloc-104 nothing above the noise arrives at an NLoS
// beep until ~9 ms after the direct path would have; with floor and ceiling reflections kept the
// simulator's NLoS beeps started 1-3 ms after it and decayed like LoS ones). Syncs are
// lost with probability sync_loss and jitter by ±sync_jitter_s. Step model s = a·f + b.
// Truth: truth.csv, truth_steps.csv, truth_los.csv (t_true,beacon,los: 1/0 per beep, geometric).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <sstream>

#include "locus/sim/families.hpp"
#include "locus/sim/motion/walking.hpp"

namespace locus::sim {

namespace {
// 2D segment intersection (proper or touching).
bool segments_cross(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& a,
                    const Eigen::Vector2d& b) {
  auto cross = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); };
  const double d1 = cross(q - p, a - p), d2 = cross(q - p, b - p);
  const double d3 = cross(b - a, p - a), d4 = cross(b - a, q - a);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
}
}  // namespace

Simulation make_spyloc(const FamilyOptions& opts) {
  using namespace motion;
  const DifficultyProfile prof = difficulty_profile(opts.difficulty);
  const int beacons = static_cast<int>(opts.get_int("beacons", 3, 3, 4));
  const double period_s = opts.get_double("beep_period_s", 1.0, 0.2, 30.0);
  const double sync_delay_s = opts.get_double("sync_delay_s", 0.05, 0.0, 1.0);
  const std::string pace = opts.get_choice("pace", "normal", {"normal", "fast"});
  const double nlos_db = opts.get_double("nlos_db", 20.0, 0.0, 60.0);
  const bool diffraction = opts.get_int("diffraction", 1, 0, 1) == 1;
  const double sync_loss = opts.get_double("sync_loss", 0.03, 0.0, 0.9);
  const double sync_jitter_s = opts.get_double("sync_jitter_s", 100e-6, 0.0, 0.01);
  const int laps = static_cast<int>(opts.get_int("laps", 1, 1, 5));
  const bool partition = opts.get_int("partition", 1, 0, 1) == 1;
  // Interferers by default, as the world has them (the foreign spyloc-104: babble and music, 3 in 40 s):
  // every difficulty but easy gets babble / music bursts at >= 4 a minute (AMIL's default is the same kind).
  const bool easy = opts.difficulty == Difficulty::Easy;
  const std::string bursts = opts.get_choice("bursts", easy ? "white" : "mixed", {"white", "babble", "music", "mixed"});
  const double bursts_per_minute =
      opts.get_double("bursts_per_minute", easy ? -1.0 : std::max(4.0, prof.bursts_per_minute), -1.0, 60.0);
  opts.finish("spyloc");

  Simulation sim;
  sim.name = "spyloc-walk";
  sim.family = "spyloc";
  sim.seed = opts.seed;
  sim.acoustics.room = Room{};
  sim.acoustics.room->size_m = {24.0, 16.0, 3.5};
  apply_profile(prof, sim.acoustics);
  // Interferers (the foreign spyloc-104: babble and music, 1.5-3 s, ~4 a minute, up to 20 kHz):
  // `bursts` babble / music / mixed instead of the profile's white bursts.
  if (bursts_per_minute >= 0.0) sim.acoustics.noise.bursts_per_minute = bursts_per_minute;
  set_burst_kind(sim.acoustics.noise, bursts, 0.3, 3.0);
  sim.radio_latency_s = 50e-6;  // receive latency unknown to the receiver (tens of µs)
  sim.radio_jitter_s = sync_jitter_s;
  sim.radio_loss_probability = sync_loss;
  Rng layout = Rng::derive(opts.seed, "spyloc/layout");
  Rng clocks = Rng::derive(opts.seed, "spyloc/clocks");
  const double decl = layout.uniform(0.0, 2.0 * std::numbers::pi);
  sim.magnetic_field_world_ut = Eigen::Vector3d(19.0 * std::cos(decl), 19.0 * std::sin(decl), -44.0);

  // Beacons: known positions, unique 10-bit tone masks with 3..6 tones.
  const std::vector<Eigen::Vector3d> spots = {{1.5, 1.5, 2.5}, {22.5, 1.5, 2.5}, {12.0, 14.5, 2.5}, {1.5, 14.5, 2.5}};
  std::set<unsigned> used_masks;
  for (int i = 0; i < beacons; ++i) {
    unsigned mask = 0;
    for (;;) {
      const unsigned low = static_cast<unsigned>(layout.integer(0, 1023));
      const int bits = __builtin_popcount(low);
      if (bits >= 3 && bits <= 6 && !used_masks.count(low)) {
        mask = low;
        break;
      }
    }
    used_masks.insert(mask);
    EmitterModel e;
    e.id = "B" + std::to_string(i + 1);
    dsp::SignalSpec beep;
    beep.type = "multitone";
    for (int k = 0; k < 10; ++k)
      if (mask & (1u << k)) beep.tones_hz.push_back(18000.0 + 250.0 * k);
    beep.duration_s = 0.050;
    beep.fade_s = 0.005;
    beep.amplitude = 1.0;
    beep.sync_delay_s = sync_delay_s;
    e.emits = {beep};
    e.trajectory = std::make_shared<StaticTrajectory>(spots[static_cast<std::size_t>(i)]);
    e.anchor_position_m = spots[static_cast<std::size_t>(i)];
    e.source_level = 3.0;  // an external loudspeaker (paper: Nokia MD-11)
    // No 20 kHz low-pass on the beacons: its causal group delay (~3 samples at 18-20 kHz) is a fixed
    // property of the beacon hardware that a deployment calibrates into sync_delay_s; the scenes
    // declare the delay to the start of the sound at the speaker, so the response keeps only the
    // 300 Hz high-pass (no group delay in the tone band).
    e.speaker_response = BandLimit{300.0, 0.0, 2};
    sim.emitters.push_back(e);
  }

  // The walker: laps of a loop around an interior wall.
  std::vector<Eigen::Vector2d> path = {{4, 4}};
  for (int l = 0; l < laps; ++l) path.insert(path.end(), {{20, 4}, {20, 12}, {4, 12}, {4, l + 1 == laps ? 4.5 : 4.0}});
  const Eigen::Vector2d wall_a(9.0, 8.0), wall_b(15.0, 8.0);
  PedestrianParams pp;
  pp.path_m = path;
  pp.height_m = layout.uniform(1.60, 1.90);
  pp.step_freq_hz = pace == "fast" ? 2.2 : 1.7;
  const double t0 = prof.offset_s_max + 0.5;
  auto walk = std::make_shared<PedestrianTrajectory>(pp, t0, Rng::derive(opts.seed, "spyloc/walk").next_u64());

  DeviceModel phone;
  phone.id = "P";
  phone.mics_body_m = {{0.0, -0.070, 0.0}};
  phone.trajectory = walk;
  phone.clock = draw_clock(prof, clocks);
  phone.mic_response = {60.0, 0.0, 2};
  phone.imu = std::make_shared<PhoneImu>(phone_imu_config(50.0, prof.imu_noise_scale, true));  // paper: f_a = 50 Hz
  phone.record_sync = true;
  sim.devices.push_back(phone);

  sim.duration_s = opts.duration_s.value_or(walk->end_s() + 0.5);
  std::ostringstream los;
  los << "t_true,beacon,los\n";
  const double c = sim.acoustics.speed_of_sound_mps;
  for (double t = t0 + 0.2; t + sync_delay_s + 0.3 < sim.duration_s; t += period_s) {
    for (int i = 0; i < beacons; ++i) {
      Emission e;
      e.source_id = "B" + std::to_string(i + 1);
      e.t_command_true_s = t + i * period_s / beacons + sync_delay_s;  // staggered; radio at t_command − delay
      e.latency_s = 0.0;
      sim.emissions.push_back(e);
      const Eigen::Vector3d b = spots[static_cast<std::size_t>(i)];
      const double t_arr = e.t_start_true_s() + (walk->pose(e.t_start_true_s()).position_m - b).norm() / c;
      const Eigen::Vector3d w = walk->pose(t_arr).position_m;
      const bool blocked = segments_cross(b.head<2>(), w.head<2>(), wall_a, wall_b);
      if (blocked && diffraction) {
        // Knife-edge diffraction around the nearer end of the wall (a vertical edge): the first path
        // bends around it, longer by Δ; loss J(ν) = 6.9 + 20·log10(sqrt((ν−0.1)² + 1) + ν − 0.1) dB
        // with ν = 2·sqrt(Δ/λ) (ITU-R P.526), λ at the beep's mean tone.
        const Eigen::Vector2d b2 = b.head<2>(), w2 = w.head<2>();
        const double dz = b.z() - w.z();
        double best = std::numeric_limits<double>::infinity();
        for (const Eigen::Vector2d& edge : {wall_a, wall_b}) best = std::min(best, (b2 - edge).norm() + (edge - w2).norm());
        const double around = std::hypot(best, dz), direct = (b - w).norm();
        const double excess = std::max(0.0, around - direct);
        double f_mean = 0.0;
        for (double f : sim.emitters[static_cast<std::size_t>(i)].emits[0].tones_hz) f_mean += f;
        f_mean /= static_cast<double>(sim.emitters[static_cast<std::size_t>(i)].emits[0].tones_hz.size());
        const double nu = 2.0 * std::sqrt(excess / (c / f_mean));
        const double loss_db = 6.9 + 20.0 * std::log10(std::sqrt((nu - 0.1) * (nu - 0.1) + 1.0) + nu - 0.1);
        Obstruction o{e.source_id, phone.id, loss_db, e.t_start_true_s() - 1e-3, e.t_start_true_s() + 1e-3};
        o.extra_path_m = excess;
        if (partition) o.wall_m = {{wall_a, wall_b}};
        sim.acoustics.obstructions.push_back(o);
      } else if (blocked && nlos_db > 0.0) {
        Obstruction o{e.source_id, phone.id, nlos_db, e.t_start_true_s() - 1e-3, e.t_start_true_s() + 1e-3};
        if (partition) o.wall_m = {{wall_a, wall_b}};
        sim.acoustics.obstructions.push_back(o);
      }
      los << scene::format_double(e.t_start_true_s()) << ',' << e.source_id << ',' << (blocked ? 0 : 1) << '\n';
    }
  }
  sim.extra_files["truth_steps.csv"] = truth_steps_csv({{phone.id, walk.get()}}, sim.duration_s);
  sim.extra_files["truth_los.csv"] = los.str();
  sim.environment_yaml = "wall: [[9.0, 8.0], [15.0, 8.0]], pace: " + pace +
                         ", truth_steps: truth_steps.csv, truth_los: truth_los.csv";
  return sim;
}

}  // namespace locus::sim

// ------------------------------------------------------------------------------------------ registration
// The family's entry in the table of `locus simulate` (generated from this folder, families.hpp).
namespace locus::sim::registered_families {

const Family& spyloc() {
  static const Family family{
      "spyloc",
      "SpyLoc (paper 001): a walker with a phone, 3-4 anchored beacons sending radio sync + 10-tone 18-20.25 kHz "
      "beeps; an interior wall makes NLOS stretches; IMU 50 Hz; truth_steps.csv, truth_los.csv",
      {{"beacons", "int", "3", "number of beacons (3 or 4)"},
       {"beep_period_s", "double", "1.0", "time between beeps of one beacon"},
       {"sync_delay_s", "double", "0.05", "radio message to beep delay (known)"},
       {"pace", "normal|fast", "normal", "step frequency 1.7 or 2.2 Hz"},
       {"nlos_db", "double", "20", "direct-path attenuation behind the wall when diffraction=0"},
       {"diffraction", "int", "1", "1: the first path behind the wall is knife-edge diffracted around its nearer end "
                                   "(longer, J(nu) dB down); 0: the direct path only attenuated by nlos_db"},
       {"sync_loss", "double", "0.03", "probability that a beacon's radio sync is lost"},
       {"sync_jitter_s", "double", "1e-4", "uniform +- jitter of the sync reception time"},
       {"laps", "int", "1", "laps of the 16x8 m loop"},
       {"partition", "int", "1", "1: the wall is a floor-to-ceiling partition: reflections whose route crosses it "
                                 "lose what the direct path loses; 0: only the direct path is obstructed"},
       {"bursts", "white|babble|music|mixed", "mixed (easy: white)", "noise bursts: white (the difficulty's), or babble / music / "
                                                        "either (0.3-3 s, energy up to 20 kHz: the foreign spyloc-104's interferers)"},
       {"bursts_per_minute", "double", "max(4, the difficulty's) (easy: -1)", "noise bursts per minute; -1 = the difficulty's"}},
      make_spyloc};
  return family;
}

}  // namespace locus::sim::registered_families
