// sync_emitter (plugins/sync_emitter/sync_emitter.hpp): emissions scheduled from radio syncs.
#include <gtest/gtest.h>

#include <memory>

#include "locus/params.hpp"
#include "support/test_host.hpp"
#include "sync_emitter/sync_emitter.hpp"

namespace locus::plugins::sync_emitter {
namespace {

using FakeEmitter = test::RecordingEmitter;  // 48 kHz, frame 0

class NullPublisher final : public Publisher {
 public:
  void publish(const Event&) override { ++n; }
  int n = 0;
};

SignalSpec multitone(std::optional<double> delay_s) {
  SignalSpec s;
  s.type = "multitone";
  s.tones_hz = {18000, 19000};
  s.duration_s = 0.05;
  s.fade_s = 0.005;
  s.amplitude = 0.8;
  s.sync_delay_s = delay_s;
  return s;
}

struct Rig {
  test::TestHost host;
  FakeEmitter emitter;
  std::vector<SignalSpec> emits;
  DeviceGeometry geometry;
  std::unique_ptr<Localizer> loc;
  NullPublisher pub;

  std::string configure(Params p, const std::string& device = "B1", bool with_emitter = true) {
    geometry.emits = emits;
    geometry.has_speaker = true;
    HostContext ctx = host.context("sync_emitter", device);
    ctx.geometry = &geometry;
    ctx.emitter = with_emitter ? &emitter : nullptr;
    loc.reset(descriptor()->create_localizer());
    try {
      loc->configure(p, ctx);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  }
  void sync(const std::string& device, const std::string& source, double t_s) {
    RadioSync s;
    s.device = DeviceId(device);
    s.source = NameTag(source);
    s.t_s = t_s;
    loc->on_event(Event{s}, pub);
  }
};

Params defaults() { return Params::defaults(schema()); }

TEST(SyncEmitter, EmissionFrameIsTheSyncPlusTheDelay) {
  EXPECT_EQ(emission_frame(1.0, 0.05, 0.0, 0, 48000.0), 50400);
  EXPECT_EQ(emission_frame(1.0, 0.05, 0.5, 2, 48000.0), 98400);
  EXPECT_EQ(emission_frame(-0.5, 0.05, 0.0, 0, 48000.0), -21600);
  EXPECT_EQ(emission_frame(0.0, 0.0, 0.0, 0, 44100.0), 0);
}

TEST(SyncEmitter, ABeaconBeepsItsDelayAfterEachOfItsOwnSyncs) {
  Rig r;
  r.emits = {SignalSpec{}, multitone(0.06)};  // the first entry is not acoustic (type "")
  r.emits[0].type = "ble";
  ASSERT_EQ(r.configure(defaults()), "");
  EXPECT_EQ(r.loc->subscriptions(), std::vector<EventType>{EventType::RadioSync});
  r.emitter.frame = 40000;
  r.sync("B1", "B1", 1.0);
  r.sync("B1", "B2", 1.2);   // another beacon's sync: not ours
  r.sync("W", "B1", 1.3);    // another device's event
  ASSERT_EQ(r.emitter.calls.size(), 1u);
  EXPECT_EQ(r.emitter.calls[0].start_frame, 50880u);  // (1.0 + 0.06) · 48000
  EXPECT_EQ(r.emitter.calls[0].signal.type, "multitone");
  EXPECT_DOUBLE_EQ(r.emitter.calls[0].gain, 1.0);
  r.loc->finish(r.pub);
  EXPECT_TRUE(r.host.log.contains("sync_emitter B1: 1 syncs, 1 emissions scheduled, 0 late (not scheduled), 0 refused"));
  EXPECT_EQ(r.pub.n, 0);
}

TEST(SyncEmitter, AWalkerEmitsEveryRoundAfterTheStartSignal) {
  Rig r;
  r.emits = {multitone(std::nullopt)};
  Params p = defaults();
  p.set("sources", std::string("U0"));
  p.set("delay_s", 0.02);
  p.set("repeat_period_s", 1.0);
  p.set("repeat_count", std::int64_t{3});
  p.set("gain", 0.5);
  ASSERT_EQ(r.configure(p, "U2"), "");
  r.sync("U2", "U0", 2.0);
  ASSERT_EQ(r.emitter.calls.size(), 3u);
  EXPECT_EQ(r.emitter.calls[0].start_frame, 96960u);
  EXPECT_EQ(r.emitter.calls[1].start_frame, 144960u);
  EXPECT_EQ(r.emitter.calls[2].start_frame, 192960u);
  EXPECT_DOUBLE_EQ(r.emitter.calls[2].gain, 0.5);
}

TEST(SyncEmitter, ASyncTooLateForItsEmissionIsCountedNotScheduled) {
  Rig r;
  r.emits = {multitone(0.05)};
  ASSERT_EQ(r.configure(defaults()), "");
  r.emitter.frame = 60000;  // the playback stream is already past (1.0 + 0.05) · 48000 = 50400
  r.sync("B1", "B1", 1.0);
  EXPECT_TRUE(r.emitter.calls.empty());
  r.emitter.refuse = true;
  r.sync("B1", "B1", 2.0);
  r.loc->finish(r.pub);
  EXPECT_TRUE(r.host.log.contains("2 syncs, 0 emissions scheduled, 1 late (not scheduled), 1 refused"));
  EXPECT_TRUE(r.host.log.contains("first refusal: too many emissions pending", LogLevel::Warn));
}

TEST(SyncEmitter, RefusesWhatItCannotDo) {
  {
    Rig r;
    r.emits = {multitone(0.05)};
    EXPECT_NE(r.configure(defaults(), "B1", false).find("no emitter: the node needs a `playback:` section"), std::string::npos);
  }
  {
    Rig r;  // no emits at all
    EXPECT_NE(r.configure(defaults()).find("declares no emits"), std::string::npos);
  }
  {
    Rig r;
    r.emits = {multitone(std::nullopt)};
    EXPECT_NE(r.configure(defaults()).find("no sync_delay_s and param 'delay_s' is not given"), std::string::npos);
  }
  {
    Rig r;
    r.emits = {multitone(0.05)};
    Params p = defaults();
    p.set("emits_index", std::int64_t{3});
    EXPECT_NE(r.configure(p).find("param 'emits_index': 3"), std::string::npos);
  }
  {
    Rig r;
    r.emits = {multitone(0.05)};
    Params p = defaults();
    p.set("repeat_count", std::int64_t{4});
    EXPECT_NE(r.configure(p).find("param 'repeat_period_s'"), std::string::npos);
  }
}

}  // namespace
}  // namespace locus::plugins::sync_emitter
