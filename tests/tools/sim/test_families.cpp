// Families: every family writes a scene that load_scene and validate_scene_streams accept, with the
// streams readable; determinism (same seed = same bytes); the truth files agree with the audio.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>

#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"
#include "locus/sim/families.hpp"
#include "locus/sim/motion/gesture.hpp"
#include "locus/sim/motion/imu.hpp"
#include "sim_test_util.hpp"

namespace locus::sim {
namespace {

namespace fs = std::filesystem;

std::string temp_dir(const std::string& name) {
  const fs::path p = fs::path(LOCUS_BINARY_DIR) / "test_tmp" / "sim" / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

Simulation make(const std::string& family, std::uint64_t seed, Difficulty d, std::optional<double> duration,
                std::vector<std::string> kv = {}) {
  FamilyOptions o;
  o.seed = seed;
  o.difficulty = d;
  o.duration_s = duration;
  for (const auto& x : kv) o.set_from_assignment(x);
  const Family* f = find_family(family);
  if (!f) throw std::runtime_error("no family " + family);
  return f->make(o);
}

// Reads every stream of a loaded scene end to end (the strict readers throw on any format error).
void read_all_streams(const scene::Scene& sc) {
  for (const auto& d : sc.devices) {
    if (!d.audio.empty()) {
      scene::WavReader r(sc.path(d.audio));
      EXPECT_EQ(r.info().channels, static_cast<int>(d.mics_m.size()));
      EXPECT_FALSE(r.truncated());
      EXPECT_GT(r.info().frames, 0u);
    }
    if (!d.imu.empty()) {
      scene::ImuCsvReader r(sc.path(d.imu), DeviceId(d.id));
      ImuSample s;
      std::size_t n = 0;
      while (r.next(s)) ++n;
      EXPECT_GT(n, 10u) << d.id;
    }
    if (!d.ble.empty()) {
      scene::BleCsvReader r(sc.path(d.ble), DeviceId(d.id));
      BleAdvertisement a;
      while (r.next(a)) {
      }
    }
    if (!d.sync.empty()) {
      scene::SyncCsvReader r(sc.path(d.sync), DeviceId(d.id));
      RadioSync s;
      while (r.next(s)) {
      }
    }
  }
  ASSERT_TRUE(sc.truth.has_value());
  const auto tt = scene::TruthTrajectories::load(sc.path(sc.truth->trajectories));
  for (const auto& d : sc.devices) EXPECT_TRUE(tt.has(d.id)) << d.id;
  for (const auto& e : sc.emitters) EXPECT_TRUE(tt.has(e.id)) << e.id;
}

TEST(SimFamilies, EveryFamilyWritesALoadableScene) {
  for (const Family* famp : families()) {
    const Family& fam = *famp;
    for (Difficulty d : {Difficulty::Easy, Difficulty::Hard}) {
      SCOPED_TRACE(fam.name + "/" + to_string(d));
      const std::string dir = temp_dir("family_" + fam.name + "_" + to_string(d));
      FamilyOptions o;
      o.seed = 11;
      o.difficulty = d;
      o.duration_s = 12.0;  // keeps the test short; families that need longer say so and get their default
      Simulation s;
      try {
        s = fam.make(o);
      } catch (const std::invalid_argument&) {
        o.duration_s.reset();
        s = fam.make(o);
      }
      SceneSimulator sim(std::move(s));
      sim.write(dir);
      const scene::Scene sc = scene::load_scene(dir);
      EXPECT_EQ(sc.devices.size(), sim.simulation().devices.size());
      EXPECT_NO_THROW(scene::validate_scene_streams(sc));
      read_all_streams(sc);
      EXPECT_TRUE(fs::exists(fs::path(dir) / "truth_emissions.csv"));
    }
  }
}

TEST(SimFamilies, SameSeedSameBytesOtherSeedOtherBytes) {
  const std::string a = temp_dir("det_a"), b = temp_dir("det_b"), c = temp_dir("det_c");
  SceneSimulator(make("tum", 5, Difficulty::Hard, 7.0, {"track=ellipse"})).write(a);
  SceneSimulator(make("tum", 5, Difficulty::Hard, 7.0, {"track=ellipse"})).write(b);
  SceneSimulator(make("tum", 6, Difficulty::Hard, 7.0, {"track=ellipse"})).write(c);
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), a);
    EXPECT_EQ(slurp(e.path()), slurp(fs::path(b) / rel)) << rel;
    ++files;
  }
  EXPECT_GE(files, 4u * 2 + 3);  // audio + imu per device, scene.yaml, truth.csv, truth_emissions.csv
  EXPECT_NE(slurp(fs::path(a) / "M" / "audio.wav"), slurp(fs::path(c) / "M" / "audio.wav"));
}

TEST(SimFamilies, AmilLayoutAndBeepsFollowThePaper) {
  // the paper's triangle (the easy default; normal draws a ~30 cm equilateral one, see below)
  const Simulation s1 = make("amil", 2, Difficulty::Normal, std::nullopt, {"shape=paper", "corner_jitter_m=0"});
  const Simulation s3 = make("amil", 2, Difficulty::Normal, std::nullopt, {"gestures=3"});
  EXPECT_EQ(s1.devices.size(), 13u);
  EXPECT_EQ(s1.emissions.size(), 5u);   // 5 beeps per triangle
  EXPECT_EQ(s3.emissions.size(), 13u);  // shared pauses: 1 + 4·3
  // listeners on the 1.22 m grid relative to the player's start
  const Eigen::Vector3d p0 = s1.devices[0].trajectory->pose(0.0).position_m;
  int on_grid = 0;
  for (std::size_t i = 1; i < s1.devices.size(); ++i) {
    const Eigen::Vector3d d = s1.devices[i].trajectory->pose(0.0).position_m - p0;
    const double gx = d.x() / 1.22, gy = d.y() / 1.22;
    if (std::abs(gx - std::round(gx)) < 1e-3 && std::abs(gy - std::round(gy)) < 1e-3 && std::abs(gx) <= 1.01 && gy >= 0.99 &&
        gy <= 4.01)
      ++on_grid;
  }
  EXPECT_EQ(on_grid, 12);
  // every beep is played while the player rests (pause: tremor only), at the triangle's corners
  const auto& tr = *s1.devices[0].trajectory;
  for (const auto& e : s1.emissions) {
    const double t = e.t_start_true_s();
    EXPECT_LT(tr.velocity(t).norm(), 0.01);
    EXPECT_LT(tr.velocity(t + 0.05).norm(), 0.01);
  }
  // Returns a Vector2d, not an Eigen expression: the expression would refer to the temporary pose.
  const auto corner = [&](std::size_t k) -> Eigen::Vector2d {
    return (tr.pose(s1.emissions[k].t_start_true_s()).position_m - p0).head<2>();
  };
  EXPECT_LT((corner(1) - Eigen::Vector2d(-0.305, 0)).norm(), 2e-3);
  EXPECT_LT((corner(2) - Eigen::Vector2d(0, 0.305)).norm(), 2e-3);
  EXPECT_LT((corner(3) - Eigen::Vector2d(0.305, 0)).norm(), 2e-3);
  EXPECT_THROW(make("amil", 2, Difficulty::Normal, std::nullopt, {"gestures=2"}), std::invalid_argument);
  EXPECT_THROW(make("amil", 2, Difficulty::Normal, std::nullopt, {"shape=circle"}), std::invalid_argument);
  EXPECT_THROW(make("amil", 2, Difficulty::Normal, std::nullopt, {"gesturez=3"}), std::invalid_argument);
}

// Normal is as hard as the reference generator's AMIL scenes (docs/simulator.md, "Calibration"): a
// ~30 cm equilateral triangle with corners missed by ~1 cm, pauses 0.3-0.5 s, every beep still in a
// pause, per-device transducer responses, babble/music bursts, self-noise, air absorption, the
// consumer IMU (16-bit ADC, random walk, cross-axis, stamp jitter).
TEST(SimFamilies, AmilNormalIsAsHardAsTheReferenceScenes) {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const Simulation s = make("amil", seed, Difficulty::Normal, std::nullopt);
    const DeviceModel& p = s.devices[0];
    const auto* g = dynamic_cast<const motion::GestureTrajectory*>(p.trajectory.get());
    ASSERT_NE(g, nullptr);
    const auto& pauses = g->pauses();
    ASSERT_EQ(pauses.size(), 5u);
    for (std::size_t k = 1; k + 1 < pauses.size(); ++k) {
      EXPECT_GE(pauses[k].end_s - pauses[k].start_s, 0.3 - 1e-12);
      EXPECT_LE(pauses[k].end_s - pauses[k].start_s, 0.5 + 1e-12);
    }
    // the triangle: base (corner 1 → corner 3) 0.27-0.33 m ± corner misses, apex about √3/2 of it up
    const Eigen::Vector3d base = pauses[3].position_m - pauses[1].position_m;
    EXPECT_GT(base.norm(), 0.27 - 0.07);
    EXPECT_LT(base.norm(), 0.33 + 0.07);
    EXPECT_NEAR((pauses[2].position_m - pauses[0].position_m).y(), base.norm() * std::sqrt(3.0) / 2.0, 0.08);
    for (const auto& e : s.emissions) {  // every beep (50 ms) inside a pause
      EXPECT_LT(p.trajectory->velocity(e.t_start_true_s()).norm(), 0.01);
      EXPECT_LT(p.trajectory->velocity(e.t_start_true_s() + 0.05).norm(), 0.01);
    }
    // per-device transducers: ripple + roll-off shelf, different between devices
    EXPECT_EQ(p.speaker_response.eq.size(), 7u);
    EXPECT_EQ(s.devices[1].mic_response.eq.size(), 7u);
    EXPECT_NE(s.devices[1].mic_response.eq[0].freq_hz, s.devices[2].mic_response.eq[0].freq_hz);
    EXPECT_EQ(s.acoustics.noise.burst_kind, NoiseModel::BurstKind::Mixed);
    EXPECT_TRUE(s.acoustics.noise.self_noise_snr_db.has_value());
    EXPECT_TRUE(s.acoustics.air_absorption);
    const auto* imu = dynamic_cast<const motion::PhoneImu*>(p.imu.get());
    ASSERT_NE(imu, nullptr);
    EXPECT_EQ(imu->config().adc_bits, 16);
    EXPECT_GE(imu->config().accel_bias_std_mps2, 0.04);
    EXPECT_GE(imu->config().gyro_bias_std_radps, 0.004);
    EXPECT_GE(imu->config().gyro_noise_density, 1.5e-4);
    EXPECT_GE(imu->config().stamp_jitter_std_s, 1.2e-4);
    EXPECT_GT(imu->config().accel_bias_rw, 0.0);
    EXPECT_GE(imu->config().accel_cross_axis_std_rad, 1.7e-3);
  }
  // easy keeps the paper's triangle and the longer pauses
  const Simulation e = make("amil", 1, Difficulty::Easy, std::nullopt);
  const auto* ge = dynamic_cast<const motion::GestureTrajectory*>(e.devices[0].trajectory.get());
  ASSERT_NE(ge, nullptr);
  EXPECT_NEAR((ge->pauses()[1].position_m - ge->pauses()[0].position_m).x(), -0.305, 0.03);
  for (std::size_t k = 1; k + 1 < ge->pauses().size(); ++k)
    EXPECT_GE(ge->pauses()[k].end_s - ge->pauses()[k].start_s, 0.4 - 1e-12);
}

// The emission schedule (truth) shows up in the player's self-recording and a listener's audio at the
// geometric delays: checked on the written int16 WAVs of a quiet amil scene.
TEST(SimFamilies, AmilTruthEmissionsMatchTheAudio) {
  Simulation s = make("amil", 9, Difficulty::Easy, std::nullopt);
  s.acoustics.noise.enabled = false;
  s.acoustics.band_limits = false;
  s.acoustics.room->max_order = 0;
  const std::string dir = temp_dir("amil_quiet");
  SceneSimulator sim(s);
  const WriteReport rep = sim.write(dir);
  EXPECT_GT(rep.clipped_samples, 0u);  // the player is deafened by its own speaker
  const scene::Scene sc = scene::load_scene(dir);
  scene::CsvReader em(dir + "/truth_emissions.csv");
  const auto ct = em.require_column("t_true"), cl = em.require_column("latency_s");
  std::vector<double> starts;
  while (em.next_row()) {
    starts.push_back(em.number(ct));
    const double lat = em.number(cl);
    EXPECT_GE(lat, 0.02);
    EXPECT_LE(lat, 0.05);
  }
  ASSERT_EQ(starts.size(), 5u);
  for (const std::string id : {"L5", "player"}) {
    const DeviceModel& d = *s.find_device(id);
    scene::WavReader r(sc.path(id + "/audio.wav"));
    std::vector<float> x(r.info().frames);
    r.read(x.data(), x.size());
    for (double te : starts) {
      const double ta = sim.direct_arrival_true_s("player", te, id, 0);
      const double expected = d.clock.local_from_true(ta) * 44100.0;
      const double fitted = test::fit_arrival_frame(x, s.devices[0].emits[0], 44100.0, expected, 3.0,
                                                     1.0 + d.clock.skew_ppm * 1e-6);
      if (id == "player") {
        EXPECT_NEAR(fitted, expected, 0.3);  // clipped: the fit still finds it, less precisely
      } else {
        EXPECT_NEAR(fitted, expected, 0.05);
      }
    }
  }
}

TEST(SimFamilies, TumEllipseFollowsTheTrack) {
  const Simulation s = make("tum", 4, Difficulty::Normal, 12.0, {"track=ellipse"});
  ASSERT_EQ(s.devices.size(), 4u);
  const auto& m = *s.find_device("M")->trajectory;
  // 5.9 s per round, 31 × 58 cm
  EXPECT_NEAR((m.pose(1.0).position_m - m.pose(6.9).position_m).norm(), 0.0, 1e-9);
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9;
  for (double t = 0; t < 5.9; t += 0.001) {
    const auto p = m.pose(t).position_m;
    xmin = std::min(xmin, p.x()), xmax = std::max(xmax, p.x()), ymin = std::min(ymin, p.y()), ymax = std::max(ymax, p.y());
  }
  EXPECT_NEAR(xmax - xmin, 0.31, 1e-4);
  EXPECT_NEAR(ymax - ymin, 0.58, 1e-4);
  for (const auto& d : s.devices) {
    EXPECT_EQ(d.mics_body_m.size(), 2u);
    ASSERT_EQ(d.emits.size(), 1u);
    EXPECT_EQ(d.emits[0].duration_s, 0.040);
  }
  // each device emits in turn: round-robin order N1, N2, N3, M
  for (std::size_t i = 0; i + 4 <= s.emissions.size(); i += 4) {
    EXPECT_EQ(s.emissions[i].source_id, "N1");
    EXPECT_EQ(s.emissions[i + 3].source_id, "M");
  }
}

}  // namespace
}  // namespace locus::sim
