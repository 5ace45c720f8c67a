// Family `amil`: the field test of AMIL (paper 004, Sec. V-D).
//
// Paper setup reproduced: one player and twelve listeners in a 2D plane; listeners on a grid of
// 122 cm cells, x ∈ {−122, 0, 122} cm, y ∈ {122, 244, 366, 488} cm from the player (the origin).
// The player draws the triangle gesture of Sec. III/V on a table: (0,0) → (−s,0) → (0,s) → (s,0) →
// (0,0), s = 30.5 cm, pausing at every corner; it beeps in each pause (5 beeps per triangle, shared
// pauses between repeated triangles: 1 + 4·gestures beeps). Beep: linear chirp 18-22 kHz, 50 ms,
// faded in/out, 44.1 kHz. The player records itself (self-recording reveals the speaker latency)
// and logs its IMU (accelerometer + gyroscope) during the gesture.
//
// The gesture is motion::GestureTrajectory (min-jerk strokes, random pauses, yaw wobble, tremor) and
// the IMU motion::PhoneImu (biases, scale errors, noise densities scaled by the difficulty).
// Deviation (documented in docs/simulator.md): the paper's hallway is 3 m × 5 m but the grid
// reaches 4.88 m from the player, so the simulated hallway is 3.0 × 5.4 × 2.7 m with the player
// 0.25 m from one end wall.
#include <cmath>

#include "locus/sim/families.hpp"
#include "locus/sim/motion/gesture.hpp"
#include "locus/sim/motion/imu.hpp"

namespace locus::sim {

namespace {
constexpr double kTableHeight_m = 0.75;
}  // namespace

Simulation make_amil(const FamilyOptions& opts) {
  const DifficultyProfile prof = difficulty_profile(opts.difficulty);
  const int gestures = static_cast<int>(opts.get_int("gestures", 1, 1, 3));
  if (gestures == 2) throw std::invalid_argument("option 'gestures': the paper uses 1 or 3 triangles, got 2");
  const double s = opts.get_double("side_m", 0.305, 0.05, 1.0);
  const double speed = opts.get_double("speed_mps", 0.45, 0.05, 3.0);
  const double pause_min = opts.get_double("pause_min_s", 0.4, 0.1, 5.0);
  const double pause_max = opts.get_double("pause_max_s", 0.7, 0.1, 5.0);
  if (pause_max < pause_min) throw std::invalid_argument("option 'pause_max_s' must be >= pause_min_s");
  opts.finish("amil");

  Simulation sim;
  sim.name = "amil-field-test";
  sim.family = "amil";
  sim.seed = opts.seed;
  sim.acoustics.room = Room{};
  sim.acoustics.room->size_m = {3.0, 5.4, 2.7};
  apply_profile(prof, sim.acoustics);

  const Eigen::Vector3d origin(1.5, 0.25, kTableHeight_m);  // the player's start, on the table
  Rng layout = Rng::derive(opts.seed, "amil/layout");
  Rng clocks = Rng::derive(opts.seed, "amil/clocks");
  Rng latency = Rng::derive(opts.seed, "amil/latency");

  dsp::SignalSpec chirp;
  chirp.type = "lfm";
  chirp.f0_hz = 18000.0;
  chirp.f1_hz = 22000.0;
  chirp.duration_s = 0.050;
  chirp.fade_s = 0.005;
  chirp.amplitude = 1.0;

  // ---- player: the triangle gesture(s) on the table, top of the phone towards the listeners
  motion::GestureParams g;
  g.waypoints_m = {{0.0, 0.0}};
  for (int k = 0; k < gestures; ++k) {
    g.waypoints_m.push_back({-s, 0.0});
    g.waypoints_m.push_back({0.0, s});
    g.waypoints_m.push_back({s, 0.0});
    g.waypoints_m.push_back({0.0, 0.0});
  }
  g.origin_m = origin;
  g.mean_speed_mps = speed;
  g.pause_min_s = pause_min;
  g.pause_max_s = pause_max;
  g.lifted = false;
  const double t0 = prof.offset_s_max + 1.0;  // every device records by then
  auto gesture = std::make_shared<motion::GestureTrajectory>(g, t0, opts.seed ^ 0xA311u);

  DeviceModel player;
  player.id = "player";
  player.mics_body_m = {{0.0, -0.068, 0.0}};
  player.speaker_body_m = Eigen::Vector3d(0.02, -0.072, 0.0);
  player.emits = {chirp};
  player.trajectory = gesture;
  player.clock = draw_clock(prof, clocks);
  player.speaker_response = {300.0, 0.0, 2};  // phone speaker: no low end; the 18-22 kHz band is kept
  player.mic_response = {60.0, 0.0, 2};
  motion::PhoneImuConfig imu;
  imu.rate_hz = 100.0;
  imu.magnetometer = false;  // AMIL uses the accelerometer and gyroscope
  imu.accel_noise_density *= prof.imu_noise_scale;
  imu.gyro_noise_density *= prof.imu_noise_scale;
  imu.accel_bias_std_mps2 *= prof.imu_noise_scale;
  imu.gyro_bias_std_radps *= prof.imu_noise_scale;
  player.imu = std::make_shared<motion::PhoneImu>(imu);
  sim.devices.push_back(player);

  // beeps: one per pause, commanded 50 ms into it (the latency delays the sound further)
  for (const auto& pause : gesture->pauses()) {
    Emission e;
    e.source_id = "player";
    e.signal_index = 0;
    e.t_command_true_s = pause.start_s + 0.05;
    e.latency_s = prof.latency.draw(latency);
    sim.emissions.push_back(e);
  }

  // ---- listeners: 3 × 4 grid, 1.22 m cells, phones flat at table height with random headings
  int n = 0;
  for (int row = 1; row <= 4; ++row) {
    for (int col = -1; col <= 1; ++col) {
      DeviceModel l;
      l.id = "L" + std::to_string(++n);
      l.mics_body_m = {{0.0, -0.068, 0.0}};
      const double heading = layout.uniform(0.0, 2.0 * M_PI);
      const Eigen::Vector3d pos = origin + Eigen::Vector3d(1.22 * col, 1.22 * row, 0.0);
      l.trajectory = std::make_shared<StaticTrajectory>(pos, flat_attitude({std::cos(heading), std::sin(heading)}));
      l.clock = draw_clock(prof, clocks);
      l.mic_response = {60.0, 0.0, 2};
      if (layout.bernoulli(prof.obstruction_probability))
        sim.acoustics.obstructions.push_back(Obstruction{"player", l.id, prof.obstruction_db});
      sim.devices.push_back(l);
    }
  }

  const double t_end_gesture = gesture->end_s();
  sim.duration_s = opts.duration_s.value_or(t_end_gesture + 1.0);
  if (sim.duration_s < t_end_gesture + 0.5)
    throw std::invalid_argument("duration " + scene::format_double(sim.duration_s) + " s is shorter than the gesture (" +
                                scene::format_double(t_end_gesture + 0.5) + " s needed)");
  sim.environment_yaml = "gestures: " + std::to_string(gestures) + ", triangle_side_m: " + scene::format_double(s);
  return sim;
}

}  // namespace locus::sim

// ------------------------------------------------------------------------------------------ registration
// The family's entry in the table of `locus simulate` (generated from this folder, families.hpp).
namespace locus::sim::registered_families {

const Family& amil() {
  static const Family family{
      "amil",
      "AMIL field test (paper 004): a player draws triangles on a table and beeps (18-22 kHz, 50 ms) at the "
      "pauses; 12 listeners on a 1.22 m grid in a 3x5 m hallway; player IMU",
      {{"gestures", "int", "1", "triangles drawn (1 or 3)"},
       {"side_m", "double", "0.305", "triangle half-base and height (paper: 30.5 cm)"},
       {"speed_mps", "double", "0.45", "mean stroke speed (min-jerk strokes)"},
       {"pause_min_s", "double", "0.4", "shortest pause at a corner (the beep is played in it)"},
       {"pause_max_s", "double", "0.7", "longest pause at a corner"}},
      make_amil};
  return family;
}

}  // namespace locus::sim::registered_families
