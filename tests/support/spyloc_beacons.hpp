// Three anchored SpyLoc beacons for the spyloc tests and benchmark (tests/plugins/spyloc,
// tests/bench/bench_spyloc.cpp): positions, tone sets, the scene entries the localizer reads from its
// geometry, and each beacon's tone mask as the multitone detector reports it (tone i = bit
// (f - 18000) / 250). Header-only.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "locus/plugin.hpp"

namespace locus::test {

struct SpyLocBeacons {
  std::vector<std::array<double, 3>> anchors_m = {{1.5, 1.5, 2.5}, {22.5, 1.5, 2.5}, {12.0, 14.5, 2.5}};
  std::vector<std::vector<double>> tones_hz = {{18000, 19000, 20000}, {18250, 18750, 20250}, {18500, 19250, 19500, 19750}};
  std::vector<SceneSignal> scene;  ///< multitone emitters B1..B3, 60 ms, sync_delay 50 ms, anchored
  DeviceGeometry geometry;         ///< scene_emits = scene

  SpyLocBeacons() {
    for (std::size_t i = 0; i < anchors_m.size(); ++i) {
      SceneSignal s;
      s.id = id(i);
      s.signal.type = "multitone";
      s.signal.tones_hz = tones_hz[i];
      s.signal.duration_s = 0.06;
      s.signal.sync_delay_s = 0.05;
      s.has_anchor = true;
      s.anchor_m = anchors_m[i];
      scene.push_back(s);
    }
    geometry.scene_emits = scene;
  }
  SpyLocBeacons(const SpyLocBeacons&) = delete;  // geometry.scene_emits views `scene`
  SpyLocBeacons& operator=(const SpyLocBeacons&) = delete;

  static std::string id(std::size_t i) { return "B" + std::to_string(i + 1); }
  std::uint16_t mask(std::size_t i) const {
    std::uint16_t m = 0;
    for (double f : tones_hz[i]) m |= static_cast<std::uint16_t>(1u << static_cast<int>((f - 18000) / 250));
    return m;
  }
};

}  // namespace locus::test
