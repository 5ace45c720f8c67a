// Real-time safety of the room's process callback body (tools/room RoomRenderer::process and skip,
// what `locus room`'s JACK callback runs on the port buffers): a moving speaker beeping into three
// devices' microphones with first-order reflections, clock skew and noise, the layout starting while
// it runs, onsets queued and skipped cycles must not allocate, free or lock after construction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include "locus/room/renderer.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus {
namespace {

room::Layout small_layout() {
  room::Layout l;
  l.sample_rate_hz = 44100.0;
  l.speed_of_sound_mps = 343.2;
  l.room_size_m = Eigen::Vector3d(4.0, 5.0, 3.0);
  std::vector<double> t;
  std::vector<sim::Pose> poses;
  for (int i = 0; i <= 100; ++i) {  // a slow stroke over 1 s
    t.push_back(0.01 * i);
    sim::Pose p;
    p.position_m = Eigen::Vector3d(1.0 + 0.003 * i, 1.0, 0.75);
    poses.push_back(p);
  }
  room::LayoutDevice player;
  player.id = "P";
  player.mics_body_m = {Eigen::Vector3d(0.0, -0.07, 0.0)};
  player.speaker_body_m = Eigen::Vector3d(0.02, -0.07, 0.0);
  player.trajectory = std::make_shared<sim::SampledTrajectory>(t, poses);
  l.devices.push_back(player);
  for (int k = 0; k < 2; ++k) {
    room::LayoutDevice d;
    d.id = "L" + std::to_string(k);
    d.mics_body_m = {Eigen::Vector3d(0.0, 0.0, 0.0), Eigen::Vector3d(0.1, 0.0, 0.0)};
    d.trajectory = std::make_shared<sim::StaticTrajectory>(Eigen::Vector3d(2.0 + k, 3.0, 0.75));
    l.devices.push_back(d);
  }
  l.t_begin_s = 0.0;
  l.t_end_s = 1.0;
  return l;
}

TEST(RtSafety, RoomRendererDoesNotAllocateOrLock) {
  room::RendererConfig cfg;
  cfg.reflection_order = 1;
  cfg.room_size_m = Eigen::Vector3d(4.0, 5.0, 3.0);
  cfg.skew_ppm = {20.0, -35.0, 0.0};
  cfg.max_block_frames = 1024;
  const room::Layout layout = small_layout();
  room::RoomRenderer r(layout, cfg);
  constexpr std::uint32_t kN = 1024;
  std::vector<std::vector<float>> spk(layout.devices.size(), std::vector<float>(kN, 0.0f));
  std::vector<std::vector<float>> mic(r.total_mics(), std::vector<float>(kN, 0.0f));
  std::vector<const float*> spk_ptrs;
  std::vector<float*> mic_ptrs;
  for (auto& v : spk) spk_ptrs.push_back(v.data());
  for (auto& v : mic) mic_ptrs.push_back(v.data());
  room::Onset onset;
  float loudest = 0.0f;  // what the listeners heard (far above the -63 dB noise when the beeps reach them)

  RtSection rt;
  for (int cycle = 0; cycle < 200; ++cycle) {
    // a 50 ms beep every 0.5 s on the player's speaker
    for (std::uint32_t j = 0; j < kN; ++j) {
      const double t = static_cast<double>(static_cast<std::uint64_t>(cycle) * kN + j) / 44100.0;
      const double u = std::fmod(t, 0.5);
      spk[0][j] = u < 0.05 ? static_cast<float>(0.8 * std::sin(2.0 * M_PI * 18000.0 * u)) : 0.0f;
    }
    if (cycle == 20) r.start_layout_at(1.0);
    if (cycle % 50 == 49) r.skip(3 * kN);  // an xrun
    r.process(spk_ptrs.data(), mic_ptrs.data(), kN);
    while (r.pop_onset(onset)) {
    }
    for (std::size_t i = 1; i < mic.size(); ++i)
      for (float v : mic[i]) loudest = std::max(loudest, std::abs(v));
  }
  rt.end();
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
  EXPECT_GT(r.path_blocks(), 0u);  // the paths were rendered, not skipped
  EXPECT_GT(loudest, 0.01f);
}

}  // namespace
}  // namespace locus
