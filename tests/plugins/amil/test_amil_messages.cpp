// AMIL link messages (plugins/amil/messages.hpp): round trips, every malformed case named, and the
// pairing of a listener's arrivals with the player's beeps across clock offset, skew, misses and
// spurious detections.
#include <gtest/gtest.h>

#include <cmath>

#include "amil/messages.hpp"

namespace {

using namespace locus::plugins::amil;

TEST(AmilMessages, RoundTrip) {
  ArrivalMessage a{"L7", 4, 123456.789012345, 44100.0, 1, 31.25};
  const Decoded da = decode("amil", topic_arrival("amil", "L7"), encode(a));
  ASSERT_TRUE(da.error.empty()) << da.error;
  ASSERT_TRUE(da.arrival);
  EXPECT_EQ(da.arrival->listener, "L7");
  EXPECT_EQ(da.arrival->seq, 4u);
  EXPECT_DOUBLE_EQ(da.arrival->frame, a.frame);  // the full double survives (sub-sample timing)
  EXPECT_DOUBLE_EQ(da.arrival->sample_rate_hz, 44100.0);
  EXPECT_EQ(da.arrival->channel, 1u);
  EXPECT_DOUBLE_EQ(da.arrival->snr_db, 31.25);
  EXPECT_DOUBLE_EQ(da.arrival->t_s(), a.frame / 44100.0);
  EXPECT_EQ(da.arrival->carrier_period, 0.0);  // not carrier-timed: the fields are absent
  ArrivalMessage c = a;
  c.envelope_frame = a.frame - 1.25;
  c.carrier_period = 2.205;
  const Decoded dc = decode("amil", topic_arrival("amil", "L7"), encode(c));
  ASSERT_TRUE(dc.arrival) << dc.error;
  EXPECT_DOUBLE_EQ(dc.arrival->envelope_frame, c.envelope_frame);
  EXPECT_DOUBLE_EQ(dc.arrival->carrier_period, 2.205);
  EXPECT_NEAR(dc.arrival->cycle_offset_s(), 1.25 / 44100.0, 1e-12);

  const Decoded dd = decode("grp/amil", topic_done("grp/amil", "L-2"), encode(DoneMessage{"L-2", 13}));
  ASSERT_TRUE(dd.done) << dd.error;
  EXPECT_EQ(dd.done->arrivals, 13u);
  const Decoded dh = decode("amil", topic_hello("amil", "x_1"), encode(HelloMessage{"x_1", 2}));
  ASSERT_TRUE(dh.hello) << dh.error;
  EXPECT_EQ(dh.hello->channel, 2u);
  EXPECT_EQ(topic_filter("amil"), "amil/#");
}

TEST(AmilMessages, MalformedMessagesAreNamed) {
  const std::string ok = encode(ArrivalMessage{"L1", 0, 10.0, 44100.0, 0, 20.0});
  const auto err = [](std::string_view topic, std::string_view payload) { return decode("amil", topic, payload).error; };
  EXPECT_NE(err("other/arrivals/L1", ok).find("not under 'amil/'"), std::string::npos);
  EXPECT_NE(err("amil/arrivals", ok).find("expected amil/<hello|arrivals|done>/<listener>"), std::string::npos);
  EXPECT_NE(err("amil/beeps/L1", ok).find("unknown message kind 'beeps'"), std::string::npos);
  // Found by tests/fuzz (link): a number beyond double threw out of decode and ended the process.
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","t_s":2.791e30851247})").find("not JSON"),
            std::string::npos);
  EXPECT_NE(err("amil/arrivals/L 1", ok).find("device id"), std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", "{oops").find("not JSON"), std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", "[1,2]").find("expected a JSON object"), std::string::npos);
  EXPECT_NE(err("amil/arrivals/L2", ok).find("differs from the topic's 'L2'"), std::string::npos);
  EXPECT_NE(err("amil/done/L1", ok).find("type 'amil_arrival' on a 'done' topic"), std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","seq":-1,"frame":1,"sample_rate_hz":44100,"channel":0,"snr_db":1})")
                .find("field 'seq': expected a non-negative integer"),
            std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","seq":0,"frame":"x","sample_rate_hz":44100,"channel":0,"snr_db":1})")
                .find("field 'frame': expected a finite number"),
            std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","seq":0,"frame":1,"sample_rate_hz":0,"channel":0,"snr_db":1})")
                .find("sample_rate_hz > 0"),
            std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","seq":0,"frame":1,"sample_rate_hz":44100,"channel":0,"snr_db":1,"carrier_period":2.2})")
                .find("'envelope_frame' and 'carrier_period': expected both"),
            std::string::npos);
  EXPECT_NE(err("amil/arrivals/L1", R"({"type":"amil_arrival","listener":"L1","seq":0,"frame":1000,"sample_rate_hz":44100,"channel":0,"snr_db":1,"carrier_period":2.2,"envelope_frame":1})")
                .find("within 64 periods"),
            std::string::npos);
  EXPECT_NE(err("amil/done/L1", R"({"type":"amil_done","listener":"L1"})").find("field 'arrivals'"), std::string::npos);
  EXPECT_NE(err("amil/hello/L1", R"({"type":"amil_hello"})").find("field 'listener'"), std::string::npos);
}

TEST(AmilMatch, OffsetSkewMissesAndSpuriousDetections) {
  const std::vector<double> beeps{10.0, 11.1, 12.35, 13.3, 14.62};
  const double offset = -3.7, skew = 80e-6;
  std::vector<double> arr;
  for (double b : beeps) arr.push_back(offset + (1 + skew) * b + 0.004);  // 1.4 m away
  // Listener missed beep 2, heard a spurious sound and a beep of an earlier gesture.
  arr.erase(arr.begin() + 2);
  arr.push_back(offset + 12.9);
  arr.push_back(offset + 3.0);
  int matched = 0;
  const auto m = match_arrivals(beeps, arr, 0.02, &matched);
  ASSERT_EQ(m.size(), beeps.size());
  EXPECT_EQ(matched, 4);
  for (std::size_t k : {0u, 1u, 3u, 4u}) EXPECT_NEAR(m[k], offset + (1 + skew) * beeps[k] + 0.004, 1e-12) << k;
  EXPECT_TRUE(std::isnan(m[2]));
}

TEST(AmilMatch, NothingToPair) {
  int matched = -1;
  const auto m = match_arrivals({1.0, 2.0, 3.0}, {}, 0.02, &matched);
  EXPECT_EQ(matched, 0);
  for (double v : m) EXPECT_TRUE(std::isnan(v));
  // Intervals that never agree pair at most one beep.
  const auto m2 = match_arrivals({1.0, 2.0, 3.0}, {5.0, 5.5, 7.3}, 0.02, &matched);
  EXPECT_EQ(matched, 1);
}

}  // namespace
