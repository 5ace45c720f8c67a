// The `link` sync source (hal/radio/link_sync.hpp).
#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <thread>

#include "locus/sensor_source.hpp"
#include "radio/link_sync.hpp"
#include "support/test_host.hpp"

namespace locus::hal::radio {
namespace {

double monotonic_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

std::vector<RadioSync> drain(SensorQueue& q) {
  std::vector<RadioSync> out;
  Event e;
  while (q.try_pop(e)) out.push_back(std::get<RadioSync>(e));
  return out;
}

TEST(LinkSyncMessage, RoundTrips) {
  const SyncMessage m{"B1", 42, 123456789012345};
  EXPECT_EQ(encode_sync(m), "B1 42 123456789012345");
  const auto d = decode_sync(encode_sync(m));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->source, "B1");
  EXPECT_EQ(d->seq, 42u);
  EXPECT_EQ(d->sent_monotonic_ns, 123456789012345);
  EXPECT_EQ(sync_topic("sync", "B1"), "sync/B1");
}

TEST(LinkSyncMessage, RefusesMalformedWithAReason) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"", "fields"},
      {"B1 1", "2 fields"},
      {"B1 1 2 3", "4 fields"},
      {"B1  1 2", "fields"},
      {"B/1 1 2", "source"},
      {"0123456789012345678901234567890123 1 2", "source"},
      {"B1 -1 2", "seq"},
      {"B1 x 2", "seq"},
      {"B1 1 -5", "sent_monotonic_ns"},
      {"B1 1 2.5", "sent_monotonic_ns"},
  };
  for (const auto& [payload, field] : bad) {
    std::string why;
    EXPECT_FALSE(decode_sync(payload, &why).has_value()) << payload;
    EXPECT_NE(why.find(field), std::string::npos) << payload << ": " << why;
    EXPECT_NE(why.find("expected '<source> <seq> <sent_monotonic_ns>'"), std::string::npos) << why;
  }
}

TEST(LinkSyncSource, EachMessageIsARadioSyncAtItsArrival) {
  test::TestHost host;
  HostContext ctx = host.context("sync", "W");
  LinkSyncSource src;
  Params p = Params::defaults(link_sync_schema());
  p.set("sources", std::string("B1,B2"));
  src.open(p, ctx);
  EXPECT_EQ(src.kind(), SensorKind::Sync);
  EXPECT_TRUE(src.monotonic_time());
  EXPECT_TRUE(src.live());
  SensorQueue q(64);
  src.start(q);
  const double before = monotonic_s();
  host.link.publish("sync/B1", encode_sync({"B1", 0, 1}));
  host.link.publish("sync/B3", encode_sync({"B3", 0, 1}));   // not a listed source
  host.link.publish("sync/B2", "B2 zero 1");                  // malformed
  host.link.publish("sync/B2", encode_sync({"B1", 1, 1}));   // source is not the topic's
  host.link.publish("sync/B2", encode_sync({"B2", 7, 1}));
  const double after = monotonic_s();
  const auto got = drain(q);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].source.view(), "B1");
  EXPECT_EQ(got[1].source.view(), "B2");
  for (const RadioSync& s : got) {
    EXPECT_EQ(s.device.view(), "W");
    EXPECT_GE(s.t_s, before);
    EXPECT_LE(s.t_s, after);
  }
  EXPECT_LE(got[0].t_s, got[1].t_s);
  EXPECT_EQ(src.received(), 2u);
  EXPECT_EQ(src.malformed(), 2u);
  src.stop();
  host.link.publish("sync/B1", encode_sync({"B1", 2, 1}));  // after stop(): nothing
  EXPECT_TRUE(drain(q).empty());
  EXPECT_TRUE(host.log.contains("link sync W: 0 sent as W, 2 received (from B1,B2), 1 from other sources, 2 malformed"));
  EXPECT_TRUE(host.log.contains("first malformed message: sync/B2", LogLevel::Warn));
}

TEST(LinkSyncSource, TransmitsItsOwnSyncsAndReceivesThem) {
  test::TestHost host;
  HostContext ctx = host.context("sync", "B1");
  LinkSyncSource src;
  Params p = Params::defaults(link_sync_schema());
  p.set("send_period_s", 0.02);
  p.set("send_first_s", 0.01);
  p.set("send_count", std::int64_t{3});
  src.open(p, ctx);
  std::vector<std::string> heard;
  host.link.subscribe("sync/#", [&](const LinkMessage& m) { heard.push_back(m.payload); });
  SensorQueue q(64);
  src.start(q);
  for (int i = 0; i < 200 && src.sent() < 3; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  src.stop();
  EXPECT_EQ(src.sent(), 3u);
  const auto got = drain(q);
  ASSERT_EQ(got.size(), 3u);  // its own, as every node receives them
  for (const RadioSync& s : got) EXPECT_EQ(s.source.view(), "B1");
  ASSERT_EQ(heard.size(), 3u);
  for (std::size_t k = 0; k < heard.size(); ++k) {
    const auto m = decode_sync(heard[k]);
    ASSERT_TRUE(m.has_value()) << heard[k];
    EXPECT_EQ(m->seq, k);
    EXPECT_EQ(m->source, "B1");
  }
  EXPECT_TRUE(host.log.contains("one-way latency"));
}

TEST(LinkSyncSource, AnEpochInThePastSkipsItsSlots) {
  // Boards sharing one epoch keep their stagger; a board that starts late skips the slots already past.
  test::TestHost host;
  HostContext ctx = host.context("sync", "B2");
  LinkSyncSource src;
  Params p = Params::defaults(link_sync_schema());
  p.set("send_period_s", 0.02);
  p.set("send_first_s", 0.0);
  p.set("send_count", std::int64_t{60});
  p.set("send_epoch_monotonic_s", monotonic_s() - 1.0);  // slots 0..49 are past
  src.open(p, ctx);
  std::vector<std::uint64_t> seqs;
  host.link.subscribe("sync/#", [&](const LinkMessage& m) { seqs.push_back(decode_sync(m.payload)->seq); });
  SensorQueue q(64);
  src.start(q);
  for (int i = 0; i < 400 && src.sent() < 9; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // the last slot (59) is 0.2 s from the start
  src.stop();
  ASSERT_FALSE(seqs.empty());
  EXPECT_GE(seqs.front(), 50u);
  EXPECT_LE(seqs.front(), 52u);  // the first slot not yet past when the test started it
  EXPECT_EQ(seqs.back(), 59u);
  EXPECT_EQ(src.sent(), 60u - seqs.front());
  EXPECT_EQ(seqs.size(), src.sent());
}

TEST(LinkSyncSource, StopEndsTheTransmitterAtOnce) {
  test::TestHost host;
  HostContext ctx = host.context("sync", "B1");
  LinkSyncSource src;
  Params p = Params::defaults(link_sync_schema());
  p.set("send_period_s", 100.0);
  p.set("send_first_s", 100.0);
  src.open(p, ctx);
  SensorQueue q(8);
  src.start(q);
  src.stop();  // would hang for 100 s if the wait ignored it
  EXPECT_EQ(src.sent(), 0u);
}

TEST(LinkSyncSource, RefusesBadParameters) {
  auto error = [](const std::string& key, ParamValue v) {
    test::TestHost host;
    HostContext ctx = host.context("sync", "B1");
    LinkSyncSource src;
    Params p = Params::defaults(link_sync_schema());
    p.set(key, std::move(v));
    try {
      src.open(p, ctx);
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error("topic_prefix", std::string("sync/#")).find("'topic_prefix'"), std::string::npos);
  EXPECT_NE(error("topic_prefix", std::string("")).find("'topic_prefix'"), std::string::npos);
  EXPECT_NE(error("sources", std::string("B1,B 2")).find("'sources': 'B 2'"), std::string::npos);
  EXPECT_NE(error("send_period_s", 0.001).find("'send_period_s'"), std::string::npos);
  EXPECT_EQ(error("send_period_s", 0.5), "");
}

}  // namespace
}  // namespace locus::hal::radio
