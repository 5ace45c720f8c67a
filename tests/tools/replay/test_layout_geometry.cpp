// layout_geometry (tools/replay/replay.hpp): what `locusd --layout SCENE` gives a live node's plugins — a
// scene device's and a sounding emitter's declarations with the scene's signals, as a replay gives them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "locus/scene/scene.hpp"
#include "replay/replay.hpp"

namespace locus::app {
namespace {

TEST(LayoutGeometry, DevicesAndEmittersWithTheScenesSignals) {
  const auto dir = std::filesystem::temp_directory_path() / ("locus-layout-geometry-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "scene.yaml")
      << "format: locus-scene/1\nname: x\nsample_rate: 44100\nspeed_of_sound: 343\n"
         "devices:\n  - id: W\n    mics:\n      - [0, -0.07, 0]\n      - [0, 0.07, 0]\n    speaker: [0, -0.075, 0]\n"
         "emitters:\n"
         "  - id: B1\n    emits:\n      - {type: multitone, tones_hz: [18000, 19000], duration: 0.05, sync_delay_s: 0.06}\n"
         "    anchor: {position: [1, 2, 2.5]}\n";
  const std::map<std::string, GeometrySpec> g = layout_geometry(scene::load_scene(dir.string()));
  ASSERT_EQ(g.size(), 2u);
  const GeometrySpec& w = g.at("W");
  EXPECT_EQ(w.geometry.mic_count, 2u);
  EXPECT_TRUE(w.geometry.has_speaker);
  EXPECT_DOUBLE_EQ(w.geometry.speaker_m[1], -0.075);
  EXPECT_FALSE(w.geometry.has_anchor);
  EXPECT_TRUE(w.emits.empty());
  ASSERT_EQ(w.scene_emits.size(), 1u);  // the walker learns the beacon: its tones, delay and anchor
  EXPECT_EQ(w.scene_emits[0].id, "B1");
  EXPECT_TRUE(w.scene_emits[0].has_anchor);
  EXPECT_DOUBLE_EQ(*w.scene_emits[0].signal.sync_delay_s, 0.06);
  const GeometrySpec& b = g.at("B1");  // the beacon's own node: its signal, a speaker at its origin
  EXPECT_EQ(b.geometry.mic_count, 0u);
  EXPECT_TRUE(b.geometry.has_speaker);
  EXPECT_DOUBLE_EQ(b.geometry.speaker_m[0], 0.0);
  EXPECT_TRUE(b.geometry.has_anchor);
  EXPECT_DOUBLE_EQ(b.geometry.anchor_m[2], 2.5);
  ASSERT_EQ(b.emits.size(), 1u);
  EXPECT_EQ(b.emits[0].type, "multitone");
  EXPECT_EQ(b.scene_emits.size(), 1u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace locus::app
