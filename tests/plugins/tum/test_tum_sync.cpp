// TUM live roles (plugins/tum/sync.hpp, tum.cpp): the clock offset from round trips, the election of the
// working devices, the emission schedule, the sync messages; and three live instances on one link with
// offset clocks and fake emitters: every node elects the same pair, device 2 emits its delay after
// device 1 in true time although their clocks differ by seconds.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "support/test_host.hpp"
#include "tum/sync.hpp"
#include "tum/tum.hpp"

namespace {

using namespace locus;
using namespace locus::plugins::tum;

TEST(TumSync, RoundTripIsNtp) {
  // peer clock = ours + 2.0; 3 ms out, 5 ms back, 1 ms in the peer
  const RoundTrip r{10.0, 10.003 + 2.0, 10.004 + 2.0, 10.009};
  EXPECT_NEAR(r.rtt_s(), 0.008, 1e-12);
  EXPECT_NEAR(r.offset_s(), 2.0 - 0.001, 1e-12);  // asymmetry: off by half the difference of the paths
}

TEST(TumSync, EstimateIsTheMedianOfTheLastSamples) {
  std::vector<RoundTrip> trips;
  for (int i = 0; i < 9; ++i) {
    const double out = i == 4 ? 0.100 : 0.002;  // one slow trip: an outlier the median ignores
    trips.push_back({i * 1.0, i * 1.0 + out + 0.5, i * 1.0 + out + 0.5, i * 1.0 + 2 * out});
  }
  auto e = estimate_clock(trips, 4, 8);  // the last 8
  ASSERT_TRUE(e);
  EXPECT_EQ(e->samples, 8);
  EXPECT_NEAR(e->offset_s, 0.5, 1e-12);
  EXPECT_NEAR(e->rtt_s, 0.004, 1e-12);
  EXPECT_NEAR(e->spread_s, 0.0, 1e-12);
  EXPECT_FALSE(estimate_clock(std::vector<RoundTrip>(trips.begin(), trips.begin() + 3), 4, 8));
  trips.push_back({20.0, 20.5, 20.5, 19.9});  // reply before the ping: not causal
  EXPECT_FALSE(estimate_clock(trips, 4, 8));
}

SyncTable table(const std::string& id, bool can_work, std::map<std::string, double> rtts) {
  SyncTable t{id, can_work, {}};
  for (const auto& [p, r] : rtts) t.peers[p] = ClockEstimate{0.0, r, 0.0, 8};
  return t;
}

TEST(TumSync, ElectsTheClosestCapablePairDeterministically) {
  std::vector<SyncTable> ts{table("C", true, {{"A", 0.010}, {"B", 0.003}, {"D", 0.001}}),
                            table("A", true, {{"B", 0.008}, {"C", 0.012}, {"D", 0.002}}),
                            table("B", true, {{"A", 0.009}, {"C", 0.004}, {"D", 0.001}}),
                            table("D", false, {{"A", 0.001}, {"B", 0.001}, {"C", 0.001}})};
  auto e = elect(ts, 0.0);  // D cannot work; B-C: max(0.003, 0.004) is the smallest
  ASSERT_TRUE(e);
  EXPECT_EQ(e->device1, "B");
  EXPECT_EQ(e->device2, "C");
  EXPECT_DOUBLE_EQ(e->rtt_s, 0.004);
  std::reverse(ts.begin(), ts.end());  // the order tables arrived in does not matter
  auto same = elect(ts, 0.0);
  ASSERT_TRUE(same);
  EXPECT_EQ(same->device1, "B");
  // within the tie, ids decide: A-B (0.009) ties with B-C (0.004) at 6 ms
  auto tie = elect(ts, 0.006);
  ASSERT_TRUE(tie);
  EXPECT_EQ(tie->device1, "A");
  EXPECT_EQ(tie->device2, "B");
  // a ranking breaks the tie and picks device 1
  auto ranked = elect(ts, 0.006, {"C", "B"});
  ASSERT_TRUE(ranked);
  EXPECT_EQ(ranked->device1, "C");
  EXPECT_EQ(ranked->device2, "B");
  // one direction measured is enough; no capable pair, no election
  EXPECT_TRUE(elect({table("A", true, {{"B", 0.001}}), table("B", true, {})}, 0.0));
  EXPECT_FALSE(elect({table("A", true, {{"B", 0.001}}), table("B", false, {})}, 0.0));
  EXPECT_FALSE(elect({table("A", true, {}), table("B", true, {})}, 0.0));
}

TEST(TumSync, Schedule) {
  EXPECT_EQ(next_emission_index(10.0, 0.5, 9.0), 0);
  EXPECT_EQ(next_emission_index(10.0, 0.5, 10.0), 0);
  EXPECT_EQ(next_emission_index(10.0, 0.5, 10.2), 1);
  EXPECT_EQ(next_emission_index(10.0, 0.5, 11.0), 2);
  // device 2's delay: in [delay, delay + jitter), the same for the same k, different across k
  std::vector<double> d;
  for (int k = 0; k < 200; ++k) d.push_back(tone2_delay_s(0.07, 0.05, k));
  EXPECT_EQ(tone2_delay_s(0.07, 0.05, 17), d[17]);
  EXPECT_GE(*std::min_element(d.begin(), d.end()), 0.07);
  EXPECT_LT(*std::max_element(d.begin(), d.end()), 0.12);
  EXPECT_GT(*std::max_element(d.begin(), d.end()) - *std::min_element(d.begin(), d.end()), 0.04);  // spread over the range
  EXPECT_EQ(tone2_delay_s(0.07, 0.0, 5), 0.07);
  // the other clock is ours + 5 s: its t = 17 is our 12, 2 s after the anchor (frame 1000 at our 10)
  EXPECT_EQ(frame_for(17.0, 5.0, 10.0, 1000, 48000.0), 1000 + 96000);
}

TEST(TumSync, MessagesRoundTripAndRefuseBadInput) {
  const auto p = decode_sync("tum", topic_pong("tum", "A"), encode(Pong{"B", "A", 7, 1.0, 2.0, 2.5}));
  ASSERT_TRUE(p.pong) << p.error;
  EXPECT_EQ(p.pong->seq, 7u);
  EXPECT_DOUBLE_EQ(p.pong->t2_s, 2.5);
  SyncTable t = table("A", true, {{"B", 0.003}});
  const auto d = decode_sync("tum", topic_table("tum", "A"), encode(t));
  ASSERT_TRUE(d.table) << d.error;
  EXPECT_DOUBLE_EQ(d.table->peers.at("B").rtt_s, 0.003);
  const auto r = decode_sync("tum", topic_role("tum"), encode(Role{{"A", "B", 0.001}, 5.0, 0.25, 0.08}));
  ASSERT_TRUE(r.role) << r.error;
  EXPECT_EQ(r.role->election.device2, "B");
  EXPECT_DOUBLE_EQ(r.role->delay_s, 0.08);
  // the topic must name the sender; fields are checked
  EXPECT_NE(decode_sync("tum", topic_ping("tum", "B"), encode(Ping{"A", 1, 1.0})).error.find("does not end in its sender"),
            std::string::npos);
  EXPECT_FALSE(decode_sync("tum", topic_ping("tum", "A"), R"({"type":"tum_ping","from":"A","seq":1,"t0":"x"})").error.empty());
  EXPECT_FALSE(decode_sync("tum", topic_role("tum"), R"({"type":"tum_role","device1":"A","device2":"A","rtt":0,"t0":1,"period":0.3,"delay":0})").error.empty());
  EXPECT_FALSE(decode_sync("tum", "tum/role", "not json").error.empty());
  EXPECT_FALSE(decode_sync("tum", "tum/role", R"({"type":"other"})").error.empty());
}

// ---------------------------------------------------------------- three live instances on one link

/// A device's playback stream: frame = (true time - its origin) · rate, read from a shared true time.
class StreamEmitter final : public Emitter {
 public:
  StreamEmitter(const double& true_s, double origin_s) : true_s_(true_s), origin_s_(origin_s) {}
  bool schedule(const SignalSpec& signal, std::uint64_t start_frame, double, std::string*) override {
    starts_true_s.push_back(origin_s_ + static_cast<double>(start_frame) / kRate);
    signals.push_back(signal);
    return true;
  }
  std::uint64_t playback_frame() const noexcept override { return static_cast<std::uint64_t>((true_s_ - origin_s_) * kRate); }
  double sample_rate_hz() const noexcept override { return kRate; }
  std::uint64_t late_emissions() const noexcept override { return 0; }
  static constexpr double kRate = 48000.0;
  std::vector<double> starts_true_s;
  std::vector<SignalSpec> signals;

 private:
  const double& true_s_;
  double origin_s_;
};

class NullPublisher final : public Publisher {
 public:
  void publish(const Event&) override {}
};

TEST(TumLive, ThreeNodesElectAndEmitOnTheirOwnClocks) {
  test::RecordingLogger log;
  test::NaiveFftPlanner fft;
  test::LoopbackLink link;
  double true_s = 0.0;
  const std::vector<std::string> ids{"C", "A", "B"};
  const std::map<std::string, double> clock_offset{{"A", 100.0}, {"B", 100.7}, {"C", 98.1}};  // host clock - true
  struct Node {
    test::ManualClock clock;
    DeviceGeometry geometry;
    std::unique_ptr<StreamEmitter> emitter;
    std::unique_ptr<Localizer> loc;
  };
  std::map<std::string, Node> nodes;
  for (const auto& id : ids) {
    Node& n = nodes[id];
    n.geometry.mic_count = 2;
    n.geometry.mics_m[0] = {0.0, 0.07, 0.0};
    n.geometry.mics_m[1] = {0.0, -0.07, 0.0};
    n.geometry.has_speaker = true;
    n.geometry.speaker_m = {0.02, -0.07, 0.0};
    n.emitter = std::make_unique<StreamEmitter>(true_s, id == "B" ? -3.0 : 1.5);  // audio origins differ too
  }
  NullPublisher out;
  for (const auto& id : ids) {
    Node& n = nodes[id];
    n.loc.reset(descriptor()->create_localizer());
    Params p = Params::defaults(schema());
    p.set("elect_devices", ParamValue(std::int64_t{3}));
    HostContext ctx{log, n.clock, fft, link, "tum", id, &n.geometry, n.emitter.get()};
    n.loc->configure(p, ctx);
  }
  for (int step = 0; step < 600; ++step) {  // 6 s at the IMU's 100 Hz
    true_s = 10.0 + step * 0.01;
    for (const auto& id : ids) nodes[id].clock.set(true_s + clock_offset.at(id));
    for (const auto& id : ids) {
      Node& n = nodes[id];
      ImuSample s;
      s.device.assign(id);
      s.t_s = n.clock.now_s();
      n.loc->on_event(s, out);
    }
  }
  int roles = 0;
  for (const auto& m : link.published)
    if (m.topic == "tum/role") {
      const auto d = decode_sync("tum", m.topic, m.payload);
      ASSERT_TRUE(d.role);
      EXPECT_EQ(d.role->election.device1, "A");  // every RTT is 0: a tie, ids decide
      EXPECT_EQ(d.role->election.device2, "B");
      ++roles;
    }
  EXPECT_GE(roles, 1);
  const auto& a = nodes["A"].emitter->starts_true_s;
  const auto& b = nodes["B"].emitter->starts_true_s;
  EXPECT_TRUE(nodes["C"].emitter->starts_true_s.empty());  // a monitor
  ASSERT_GE(a.size(), 10u);
  ASSERT_GE(b.size(), 10u);
  EXPECT_EQ(nodes["A"].emitter->signals[0].f0_hz, 2000.0);
  EXPECT_EQ(nodes["B"].emitter->signals[0].f0_hz, 8000.0);
  for (std::size_t k = 1; k < a.size(); ++k) EXPECT_NEAR(a[k] - a[k - 1], 1.0 / 3.0, 1.0 / 48000.0);
  // B's emission k follows A's by the delay in true time, although B's clock is 0.7 s ahead of A's
  // A's first emission is exchange first_k of the role's t0 (announced on the link)
  std::int64_t first_k = -1;
  for (const auto& m : link.published)
    if (m.topic == "tum/role" && first_k < 0) {
      const auto r = decode_sync("tum", m.topic, m.payload).role;
      first_k = std::llround((a[0] - (r->t0_s - 100.0)) / r->period_s);  // A's clock = true + 100
    }
  for (double tb : b) {
    double prev = -1e9;
    for (double ta : a)
      if (ta <= tb) prev = ta;
    const auto k = std::llround((prev - a[0]) * 3.0) + first_k;
    EXPECT_NEAR(tb - prev, tone2_delay_s(0.07, 0.05, k), 1e-3) << tb;
  }
  for (auto& [id, node] : nodes) node.loc->finish(out);
  EXPECT_TRUE(log.contains("link sync A -> B: offset 0.700000 s"));
  EXPECT_TRUE(log.contains("working devices A and B"));
}

}  // namespace
