// MapState: events in the JSON-lines shape folded into tracks (latest estimate + trace) and device
// rows (health, link, last SNR); what is not an event is refused and changes nothing.
#include <gtest/gtest.h>

#include "map_state.hpp"

namespace locus::map {
namespace {

nlohmann::ordered_json estimate(const char* target, double x, double y, std::vector<std::string> flags = {}) {
  return {{"type", "estimate"}, {"plugin", "amil"}, {"reference", "P"}, {"frame", "P_start"}, {"target", target},
          {"t_s", 1.0},         {"position_m", {x, y}}, {"direction_rad", 0.5}, {"distance_m", 2.0},
          {"std_m", 0.1},       {"confidence", 0.9}, {"flags", flags}};
}

TEST(MapState, EstimatesMakeTracksWithCappedTraces) {
  MapState s(3);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(s.add_event("n", estimate("B", i, -i)));
  ASSERT_TRUE(s.add_event("n", estimate("C", 7, 8)));
  const auto snap = s.snapshot();
  ASSERT_EQ(snap["tracks"].size(), 2u);
  const auto& b = snap["tracks"][0];
  EXPECT_EQ(b["key"], "amil|P|P_start|B");
  EXPECT_EQ(b["count"], 5);
  EXPECT_EQ(b["estimate"]["position_m"][0], 4.0);
  ASSERT_EQ(b["trace"].size(), 3u);  // trace_points = 3: the last three positions
  EXPECT_EQ(b["trace"][0][0], 2.0);
  EXPECT_EQ(b["trace"][2][1], -4.0);
  // The reference device is listed.
  ASSERT_EQ(snap["devices"].size(), 1u);
  EXPECT_EQ(snap["devices"][0]["id"], "P");
  EXPECT_EQ(snap["events"], 6);
  EXPECT_EQ(snap["recent"].size(), 6u);
}

TEST(MapState, DirectionOnlyEstimatesHaveNoTrace) {
  MapState s;
  auto e = estimate("L4", 0, 0, {"direction_only"});
  e["position_m"] = nullptr;
  ASSERT_TRUE(s.add_event("n", e));
  const auto snap = s.snapshot();
  ASSERT_EQ(snap["tracks"].size(), 1u);
  EXPECT_TRUE(snap["tracks"][0]["trace"].empty());
  EXPECT_EQ(snap["tracks"][0]["estimate"]["direction_rad"], 0.5);
}

TEST(MapState, DetectionsGiveTheLastSnrAndHealthAndLinkFillTheRow) {
  MapState s;
  s.set_link("n1", "online");
  s.add_device("n1", "A");
  ASSERT_TRUE(s.add_event("n1", {{"type", "audio_detection"}, {"device", "A"}, {"snr_db", 20.5}, {"t_s", 2.0}}));
  ASSERT_TRUE(s.add_event("n1", {{"type", "audio_detection"}, {"device", "A"}, {"snr_db", 31.0}, {"t_s", 3.0}}));
  DeviceStats st;
  st.id = "A";
  st.frames_lost = 512;
  st.playback_xruns = 2;
  s.set_health("n1", {st});
  auto rows = s.devices_json();
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0]["link"], "online");
  EXPECT_EQ(rows[0]["detections"], 2);
  EXPECT_EQ(rows[0]["last_snr_db"], 31.0);
  EXPECT_EQ(rows[0]["frames_lost"], 512);
  EXPECT_EQ(rows[0]["xruns"], 2);
  s.set_link("n1", "offline");
  EXPECT_EQ(s.devices_json()[0]["link"], "offline");
}

TEST(MapState, WhatIsNotAnEventIsRefused) {
  MapState s;
  EXPECT_FALSE(s.add_event("n", nlohmann::ordered_json::array()));
  EXPECT_FALSE(s.add_event("n", {{"x", 1}}));
  EXPECT_FALSE(s.add_event("n", {{"type", 3}}));
  EXPECT_FALSE(s.add_event("n", {{"type", "estimate"}}));            // no target
  EXPECT_FALSE(s.add_event("n", {{"type", "estimate"}, {"target", 1}}));
  EXPECT_EQ(s.events(), 0u);
  EXPECT_EQ(s.track_count(), 0u);
  // An estimate with a malformed position is kept (the page shows it in the log) but draws no trace.
  auto e = estimate("B", 0, 0);
  e["position_m"] = "nowhere";
  EXPECT_TRUE(s.add_event("n", e));
  EXPECT_TRUE(s.snapshot()["tracks"][0]["trace"].empty());
}

}  // namespace
}  // namespace locus::map
