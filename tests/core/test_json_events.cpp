#include "locus/json_events.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <vector>
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
      EXPECT_NO_THROW({ const auto parsed = nlohmann::ordered_json::parse(line); (void)parsed; });
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


struct Problems {
  std::vector<std::pair<std::string, bool>> seen;
  JsonLinesWriter::ProblemHandler handler() {
    return [this](const std::string& m, bool error) { seen.emplace_back(m, error); };
  }
};

TEST(JsonLinesWriter, FullDiskIsCountedAndReportedOnceNotThrown) {
  Problems p;
  JsonLinesWriter w("/dev/full", p.handler());  // every write: ENOSPC
  for (int i = 0; i < 3; ++i) EXPECT_NO_THROW(w.write(Estimate{}));
  EXPECT_EQ(w.lines(), 0u);
  EXPECT_EQ(w.lines_failed(), 3u);
  EXPECT_EQ(w.error(), std::strerror(ENOSPC));
  ASSERT_EQ(p.seen.size(), 1u) << "one message per run of failures";
  EXPECT_TRUE(p.seen[0].second);
  EXPECT_NE(p.seen[0].first.find("output '/dev/full': write failed (" + std::string(std::strerror(ENOSPC)) + ")"),
            std::string::npos)
      << p.seen[0].first;
}

TEST(JsonLinesWriter, ConsumerThatGoesAwayAndComesBack) {
  // locusd ignores SIGPIPE (tools/app/app.cpp); so does this test, so EPIPE comes back as an error.
  const auto old = std::signal(SIGPIPE, SIG_IGN);
  const auto fifo = std::filesystem::temp_directory_path() / ("locus-jsonl-fifo-" + std::to_string(::getpid()));
  std::filesystem::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(reader, 0);
  Problems p;
  {
    JsonLinesWriter w(fifo.string(), p.handler());
    w.write(Estimate{});
    char buf[4096];
    EXPECT_GT(::read(reader, buf, sizeof buf), 0);
    ::close(reader);  // the consumer goes away
    w.write(Estimate{});
    w.write(RadioSync{});
    EXPECT_EQ(w.lines(), 1u);
    EXPECT_EQ(w.lines_failed(), 2u);
    EXPECT_EQ(w.error(), std::strerror(EPIPE));
    reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK);  // a consumer again
    ASSERT_GE(reader, 0);
    w.write(RadioSync{});
    EXPECT_EQ(w.lines(), 2u);
    const ssize_t n = ::read(reader, buf, sizeof buf);
    ASSERT_GT(n, 0);
    EXPECT_EQ(std::string(buf, static_cast<std::size_t>(n)).rfind("{\"type\":\"radio_sync\"", 0), 0u)
        << "the next whole line, no fragment of a failed one";
  }
  ::close(reader);
  std::filesystem::remove(fifo);
  std::signal(SIGPIPE, old);
  ASSERT_EQ(p.seen.size(), 2u);
  EXPECT_TRUE(p.seen[0].second);
  EXPECT_NE(p.seen[0].first.find("after 1 lines"), std::string::npos) << p.seen[0].first;
  EXPECT_FALSE(p.seen[1].second);
  EXPECT_NE(p.seen[1].first.find("writing again after 2 lines not written"), std::string::npos) << p.seen[1].first;
}

}  // namespace
}  // namespace locus
