// RoomRenderer (tools/room/renderer.hpp) against closed forms: a band-limited burst (3 kHz, far below
// the converters' low-pass) played into a speaker port must come out of a microphone port as
// gain · x(te), te solving the model's equations: the delay r/c plus the fixed latency, 1/r spreading,
// a skewed microphone clock resampled, each first-order image at its mirrored distance times the wall's
// coefficient, the device's own speaker times self_gain. Also: the layout reader's errors.
#include <gtest/gtest.h>

#include <csignal>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

#include "locus/room/layout.hpp"
#include "locus/room/renderer.hpp"
#include "locus/room/room.hpp"

namespace locus::room {
namespace {

constexpr double kFs = 44100.0, kC = 343.2;

/// A 3 kHz burst with a Hann envelope over 10 ms starting at t0 (closed form, any real t).
double burst(double t, double t0) {
  const double u = (t - t0) / 0.01;
  if (u <= 0.0 || u >= 1.0) return 0.0;
  return 0.5 * std::sin(2.0 * M_PI * 3000.0 * (t - t0)) * (0.5 - 0.5 * std::cos(2.0 * M_PI * u));
}

Layout two_devices(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  Layout l;
  l.sample_rate_hz = kFs;
  l.speed_of_sound_mps = kC;
  l.room_size_m = Eigen::Vector3d(5.0, 6.0, 3.0);
  for (int k = 0; k < 2; ++k) {
    LayoutDevice d;
    d.id = k == 0 ? "S" : "R";
    d.mics_body_m = {Eigen::Vector3d::Zero()};
    d.speaker_body_m = Eigen::Vector3d::Zero();
    d.trajectory = std::make_shared<sim::StaticTrajectory>(k == 0 ? a : b);
    l.devices.push_back(d);
  }
  return l;
}

/// Renders 1.5 s with the burst on S's speaker at t0 (S plays on room time), returns the mics.
std::vector<std::vector<float>> render(RoomRenderer& r, double t0) {
  constexpr std::uint32_t kN = 512;
  const std::size_t blocks = static_cast<std::size_t>(1.5 * kFs / kN);
  std::vector<std::vector<float>> out(r.total_mics());
  std::vector<float> spk(kN), silent(kN, 0.0f);
  std::vector<std::vector<float>> mic(r.total_mics(), std::vector<float>(kN));
  std::vector<float*> mic_ptrs;
  for (auto& m : mic) mic_ptrs.push_back(m.data());
  r.start_layout_at(0.0);
  for (std::size_t b = 0; b < blocks; ++b) {
    for (std::uint32_t j = 0; j < kN; ++j) spk[j] = static_cast<float>(burst(static_cast<double>(b * kN + j) / kFs, t0));
    const float* spk_ptrs[2] = {spk.data(), silent.data()};
    r.process(spk_ptrs, mic_ptrs.data(), kN);
    for (std::size_t i = 0; i < mic.size(); ++i) out[i].insert(out[i].end(), mic[i].begin(), mic[i].end());
  }
  return out;
}

/// The model's closed form at microphone sample k of device d for a static pair at distance(s) `paths`
/// (distance, gain factor).
double expected(const RoomRenderer& r, std::size_t d, double k, const std::vector<std::pair<double, double>>& paths, double t0) {
  const double t_rx = r.clock_rate(d) * k / kFs + r.clock_offset_s(d);
  double y = 0.0;
  for (const auto& [dist, g] : paths) y += g * 0.1 / dist * burst(t_rx - dist / kC, t0);
  return y;
}

double max_error(const RoomRenderer& r, const std::vector<float>& got, std::size_t d,
                 const std::vector<std::pair<double, double>>& paths, double t0, double* peak = nullptr) {
  double err = 0.0, pk = 0.0;
  for (std::size_t k = 0; k < got.size(); ++k) {
    const double e = expected(r, d, static_cast<double>(k), paths, t0);
    err = std::max(err, std::abs(got[k] - e));
    pk = std::max(pk, std::abs(e));
  }
  if (peak) *peak = pk;
  return err;
}

TEST(RoomRenderer, DirectPathDelayAndSpreadingMatchTheClosedForm) {
  const Layout l = two_devices({1.0, 1.0, 1.0}, {3.1, 1.7, 1.2});
  RendererConfig cfg;
  cfg.noise_rms = 0.0;
  RoomRenderer r(l, cfg);
  const auto mics = render(r, 0.5);
  const double dist = (Eigen::Vector3d(3.1, 1.7, 1.2) - Eigen::Vector3d(1.0, 1.0, 1.0)).norm();
  double peak = 0.0;
  const double err = max_error(r, mics[1], 1, {{dist, 1.0}}, 0.5, &peak);
  EXPECT_GT(peak, 0.02);           // 0.5 · 0.1 / 2.2 m
  EXPECT_LT(err, 2e-3 * peak);     // interpolation error only
  // S hears itself at min_distance (the same point): clipped at full scale, self_gain 1
  float self_peak = 0.0f;
  for (float v : mics[0]) self_peak = std::max(self_peak, std::abs(v));
  EXPECT_FLOAT_EQ(self_peak, 1.0f);
  EXPECT_GT(r.clipped(), 0u);
}

TEST(RoomRenderer, ASpeakerOnlyEmitterIsHeardAsTheClosedForm) {
  // A beacon: a speaker port at its body origin, no microphones (LayoutDevice::emitter).
  Layout l = two_devices({1.0, 1.0, 1.0}, {3.1, 1.7, 1.2});
  l.devices[0].mics_body_m.clear();
  l.devices[0].speaker_body_m.reset();
  l.devices[0].emitter = true;
  RendererConfig cfg;
  cfg.noise_rms = 0.0;
  RoomRenderer r(l, cfg);
  ASSERT_EQ(r.total_mics(), 1u);
  ASSERT_EQ(r.mic_count(0), 0u);
  const auto mics = render(r, 0.5);
  const double dist = (Eigen::Vector3d(3.1, 1.7, 1.2) - Eigen::Vector3d(1.0, 1.0, 1.0)).norm();
  double peak = 0.0;
  const double err = max_error(r, mics[0], 1, {{dist, 1.0}}, 0.5, &peak);
  EXPECT_GT(peak, 0.02);
  EXPECT_LT(err, 2e-3 * peak);
}

TEST(RoomRenderer, SkewedMicrophoneIsResampled) {
  const Layout l = two_devices({1.0, 1.0, 1.0}, {2.0, 1.0, 1.0});
  RendererConfig cfg;
  cfg.noise_rms = 0.0;
  cfg.skew_ppm = {0.0, 400.0};  // large, so that the shift (0.2 ms = 8.8 samples at 0.5 s) is obvious
  RoomRenderer r(l, cfg);
  const auto mics = render(r, 0.5);
  double peak = 0.0;
  const double err = max_error(r, mics[1], 1, {{1.0, 1.0}}, 0.5, &peak);
  EXPECT_GT(peak, 0.04);
  EXPECT_LT(err, 2e-3 * peak);
  // and the unskewed model would be far off
  RendererConfig plain = cfg;
  plain.skew_ppm.clear();
  RoomRenderer p(l, plain);
  EXPECT_GT(max_error(p, mics[1], 1, {{1.0, 1.0}}, 0.5), 0.2 * peak);
}

TEST(RoomRenderer, FirstOrderImagesAndSelfGain) {
  const Eigen::Vector3d a(1.0, 1.5, 1.0), b(3.0, 2.0, 1.4);
  const Layout l = two_devices(a, b);
  RendererConfig cfg;
  cfg.noise_rms = 0.0;
  cfg.reflection_order = 1;
  cfg.reflection = 0.6;
  cfg.self_gain = 0.0;
  cfg.room_size_m = Eigen::Vector3d(5.0, 6.0, 3.0);
  RoomRenderer r(l, cfg);
  const auto mics = render(r, 0.3);
  std::vector<std::pair<double, double>> paths{{(b - a).norm(), 1.0}};
  for (int axis = 0; axis < 3; ++axis) {
    for (int side = 0; side < 2; ++side) {
      Eigen::Vector3d img = a;
      img[axis] = side == 0 ? -a[axis] : 2.0 * (*cfg.room_size_m)[axis] - a[axis];
      paths.emplace_back((b - img).norm(), 0.6);
    }
  }
  double peak = 0.0;
  const double err = max_error(r, mics[1], 1, paths, 0.3, &peak);
  EXPECT_GT(peak, 0.02);
  EXPECT_LT(err, 3e-3 * peak);
  EXPECT_GT(max_error(r, mics[1], 1, {paths[0]}, 0.3), 0.05 * peak);  // the images are there
  // self_gain 0: S hears only its own reflections (quieter than the direct path to R would be at 1 m)
  float self_peak = 0.0f;
  for (float v : mics[0]) self_peak = std::max(self_peak, std::abs(v));
  EXPECT_LT(self_peak, 0.05f);
  EXPECT_GT(self_peak, 0.0f);
}

TEST(RoomRenderer, OnsetsAreTheSpeakersFirstSoundAfterSilence) {
  const Layout l = two_devices({1.0, 1.0, 1.0}, {2.0, 1.0, 1.0});
  RendererConfig cfg;
  RoomRenderer r(l, cfg);
  render(r, 0.25);
  Onset o;
  ASSERT_TRUE(r.pop_onset(o));
  EXPECT_EQ(o.device, 0u);
  EXPECT_NEAR(static_cast<double>(o.frame), 0.25 * kFs, 2.0);
  EXPECT_FALSE(r.pop_onset(o));
}

TEST(RoomRenderer, RefusesBadConfigs) {
  const Layout l = two_devices({1.0, 1.0, 1.0}, {2.0, 1.0, 1.0});
  RendererConfig cfg;
  cfg.reflection_order = 1;
  cfg.room_size_m.reset();
  EXPECT_THROW(RoomRenderer(l, cfg), std::invalid_argument);
  cfg.reflection_order = 0;
  cfg.skew_ppm = {1.0};
  EXPECT_THROW(RoomRenderer(l, cfg), std::invalid_argument);
  cfg.skew_ppm = {0.0, 2000.0};
  EXPECT_THROW(RoomRenderer(l, cfg), std::invalid_argument);
}

TEST(RoomLayout, ErrorsNameTheFileAndWhatWasExpected) {
  const auto dir = std::filesystem::temp_directory_path() / ("locus-room-layout-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.yaml") << "format: locus-scene/1\nname: x\nsample_rate: 44100\nspeed_of_sound: 343\n"
                                       "environment: {room: [3, 4, 2]}\ndevices:\n  - id: A\n    mics:\n      - [0, 0, 0]\n"
                                       "truth:\n  trajectories: truth.csv\n";
  std::ofstream(dir / "truth.csv") << "t,id,x,y,z,qw,qx,qy,qz\n0,A,5,1,1,1,0,0,0\n";
  try {
    load_layout(dir.string());
    FAIL() << "a device outside the room was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("outside environment.room"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "truth.csv") << "t,id,x,y,z,qw,qx,qy,qz\n0,B,1,1,1,1,0,0,0\n";
  try {
    load_layout(dir.string());
    FAIL() << "a device without a position was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("device 'A': no position"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(RoomOptions, MagnetometerNeedsTheLayoutsField) {
  // refused before any JACK server is asked for: exit 2 (a bad layout or option), the file named
  const auto dir = std::filesystem::temp_directory_path() / ("locus-room-mag-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.yaml") << "format: locus-scene/1\nname: x\nsample_rate: 44100\nspeed_of_sound: 343\n"
                                       "environment: {room: [3, 4, 2]}\ndevices:\n  - id: A\n    mics:\n      - [0, 0, 0]\n"
                                       "truth:\n  trajectories: truth.csv\n";
  std::ofstream(dir / "truth.csv") << "t,id,x,y,z,qw,qx,qy,qz\n0,A,1,1,1,1,0,0,0\n";
  RoomOptions o;
  o.layout_dir = dir.string();
  o.out_dir = (dir / "out").string();
  o.server = "locus_room_test_no_such_server";
  o.magnetometer = true;
  sigset_t mask;  // run_room blocks the stop signals (its own sigtimedwait): restored below
  pthread_sigmask(SIG_SETMASK, nullptr, &mask);
  testing::internal::CaptureStderr();
  EXPECT_EQ(run_room(o), 2);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_NE(err.find("scene.yaml has no truth.magnetic_field_world"), std::string::npos) << err;
  o.imu = false;
  testing::internal::CaptureStderr();
  EXPECT_EQ(run_room(o), 2);
  EXPECT_NE(testing::internal::GetCapturedStderr().find("--magnetometer needs the IMUs"), std::string::npos);
  pthread_sigmask(SIG_SETMASK, &mask, nullptr);
  std::filesystem::remove_all(dir);
}

TEST(RoomLayout, SoundingEmittersAreSpeakerOnlyDevices) {
  const auto dir = std::filesystem::temp_directory_path() / ("locus-room-emitters-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.yaml")
      << "format: locus-scene/1\nname: x\nsample_rate: 44100\nspeed_of_sound: 343\n"
         "environment: {room: [10, 10, 3]}\ndevices:\n  - id: A\n    mics:\n      - [0, 0, 0]\n"
         "emitters:\n"
         "  - id: B1\n    emits:\n      - {type: multitone, tones_hz: [18000, 19000], duration: 0.05, sync_delay_s: 0.05}\n"
         "    anchor: {position: [1, 2, 2.5]}\n"
         "  - id: T1\n    emits:\n      - {type: ble, address: 'AA:BB:CC:DD:EE:FF', tx_power_dbm: -59, interval_s: 0.1}\n"
         "    anchor: {position: [2, 2, 1]}\n"
         "  - id: M\n    emits:\n      - {type: lfm, f0: 18000, f1: 20000, duration: 0.05}\n"
         "truth:\n  trajectories: truth.csv\n";
  std::ofstream(dir / "truth.csv") << "t,id,x,y,z,qw,qx,qy,qz\n0,A,5,1,1,1,0,0,0\n0,M,1,1,1,1,0,0,0\n2,A,5,3,1,1,0,0,0\n"
                                       "2,M,3,1,1,1,0,0,0\n";
  const Layout l = load_layout(dir.string());
  ASSERT_EQ(l.devices.size(), 3u);  // A, B1, M: the BLE tag T1 makes no sound
  EXPECT_EQ(l.devices[0].id, "A");
  EXPECT_FALSE(l.devices[0].emitter);
  EXPECT_EQ(l.devices[1].id, "B1");
  EXPECT_TRUE(l.devices[1].emitter);
  EXPECT_TRUE(l.devices[1].mics_body_m.empty());
  EXPECT_TRUE(l.devices[1].trajectory->is_static());
  EXPECT_NEAR((l.devices[1].trajectory->pose(1.0).position_m - Eigen::Vector3d(1, 2, 2.5)).norm(), 0.0, 1e-12);
  EXPECT_EQ(l.devices[1].emits.size(), 1u);
  EXPECT_EQ(l.devices[2].id, "M");  // a moving emitter follows its truth rows
  EXPECT_FALSE(l.devices[2].trajectory->is_static());
  EXPECT_NEAR(l.devices[2].trajectory->pose(2.0).position_m.x(), 3.0, 1e-9);
  // an emitter with a sound and no position is an error naming it
  std::ofstream(dir / "truth.csv") << "t,id,x,y,z,qw,qx,qy,qz\n0,A,5,1,1,1,0,0,0\n";
  try {
    load_layout(dir.string());
    FAIL() << "an emitter without a position was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("emitter 'M': no position"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace locus::room
