#include "locus/json_events.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace locus {
namespace {

TEST(JsonEvents, AudioDetectionShape) {
  AudioDetection d;
  d.device = "A";
  d.detector = "onset_a";
  d.channel = 1;
  d.frame = 44100.5;
  d.sample_rate_hz = 44100;
  d.snr_db = 20;
  d.confidence = 0.5f;
  const auto j = event_to_json(d);
  EXPECT_EQ(j["type"], "audio_detection");
  EXPECT_EQ(j["device"], "A");
  EXPECT_EQ(j["detector"], "onset_a");
  EXPECT_EQ(j["channel"], 1);
  EXPECT_DOUBLE_EQ(j["frame"].get<double>(), 44100.5);
  EXPECT_NEAR(j["t_s"].get<double>(), 1.0 + 0.5 / 44100, 1e-12);
}

TEST(JsonEvents, EstimateWritesNullForUnknownAndDimsComponents) {
  Estimate e;
  e.plugin = "amil";
  e.target = "L3";
  e.position_m = {1.0, 2.0, 99.0};
  e.dims = 2;
  e.distance_m = 2.236;
  const auto j = event_to_json(e);
  EXPECT_EQ(j["type"], "estimate");
  ASSERT_EQ(j["position_m"].size(), 2u);
  EXPECT_EQ(j["position_m"][1], 2.0);
  EXPECT_TRUE(j["direction_rad"].is_null());
  EXPECT_TRUE(j["std_m"].is_null());
  EXPECT_DOUBLE_EQ(j["distance_m"].get<double>(), 2.236);
}

TEST(JsonEvents, BleAddressAndOptionalFields) {
  BleAdvertisement b;
  b.address = {0xC4, 0x2C, 0x03, 0x3A, 0x2C, 0xA1};
  b.rssi_dbm = -71;
  const auto j = event_to_json(b);
  EXPECT_EQ(j["address"], "C4:2C:03:3A:2C:A1");
  EXPECT_TRUE(j["tx_power_dbm"].is_null());
  EXPECT_TRUE(j["channel"].is_null());
}

TEST(JsonLinesWriter, OneObjectPerLineFlushedAsWritten) {
  const auto path = std::filesystem::temp_directory_path() / ("locus-jsonl-" + std::to_string(::getpid()));
  {
    JsonLinesWriter w(path.string());
    w.write(Estimate{});
    w.write(RadioSync{});
    // Flushed already: readable while the writer is still open.
    std::ifstream in(path);
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
      EXPECT_NO_THROW((void)nlohmann::ordered_json::parse(line));
      ++n;
    }
    EXPECT_EQ(n, 2);
    EXPECT_EQ(w.lines(), 2u);
  }
  std::filesystem::remove(path);
}

TEST(JsonLinesWriter, UnopenablePathNamesIt) {
  try {
    JsonLinesWriter w("/nonexistent-dir/out.jsonl");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/out.jsonl"), std::string::npos);
  }
}

}  // namespace
}  // namespace locus
