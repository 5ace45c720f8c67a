// link/mqtt against a real mosquitto broker started by each test (tests/integration/mqtt/broker.hpp):
//   - two MqttLink endpoints (two clients, as two boards) exchange messages both ways with wildcards,
//     overlapping filters deliver once per subscription, a publisher hears itself, prefixes isolate,
//     unsubscribe returns only after a running handler finished and stops delivery;
//   - the broker is killed and restarted on the same port: both reconnect, re-subscribe and exchange
//     again; what one published during the outage is delivered after its reconnect (docs/mqtt.md);
//   - the offline queue is bounded: the oldest messages are dropped and counted;
//   - a wrong password / no credentials are refused with host:port and the broker's reason;
//   - TLS with a CA made by openssl; a client without TLS or trusting another CA is refused;
//   - the event output publishes event JSON, HA discovery configs (retained, once per target) and
//     state, checked with a libmosquitto subscriber and with mosquitto_sub.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <numbers>
#include <sys/stat.h>
#include <thread>

#include "integration/mqtt/broker.hpp"
#include "locus/json_events.hpp"
#include "mqtt/mqtt_link.hpp"
#include "mqtt/mqtt_output.hpp"

namespace locus::mqtt {
namespace {

using locus::testing::Broker;
using locus::testing::TempDir;
using namespace std::chrono_literals;

class TestLogger final : public Logger {
 public:
  void log(LogLevel level, std::string_view message) override {
    std::lock_guard lock(m_);
    lines_.push_back(std::string(message));
    if (level >= LogLevel::Info) std::fprintf(stderr, "[log] %.*s\n", static_cast<int>(message.size()), message.data());
  }
  bool contains(std::string_view s) const {
    std::lock_guard lock(m_);
    for (const auto& l : lines_) {
      if (l.find(s) != std::string::npos) return true;
    }
    return false;
  }

 private:
  mutable std::mutex m_;
  std::vector<std::string> lines_;
};

/// Collects what a handler receives; waits with generous timeouts.
class Inbox {
 public:
  LinkHandler handler() {
    return [this](const LinkMessage& m) {
      {
        std::lock_guard lock(m_);
        got_.push_back(m);
      }
      cv_.notify_all();
    };
  }
  bool wait_count(std::size_t n, std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, timeout, [&] { return got_.size() >= n; });
  }
  std::vector<LinkMessage> messages() const {
    std::lock_guard lock(m_);
    return got_;
  }
  std::vector<std::string> topics() const {
    std::vector<std::string> t;
    for (const auto& m : messages()) t.push_back(m.topic);
    return t;
  }
  std::size_t size() const {
    std::lock_guard lock(m_);
    return got_.size();
  }

 private:
  mutable std::mutex m_;
  std::condition_variable cv_;
  std::vector<LinkMessage> got_;
};

MqttOptions options_for(const Broker& b) {
  MqttOptions o;
  o.host = "127.0.0.1";
  o.port = b.port();
  o.connect_timeout_s = 10.0;
  o.reconnect_min_s = 0.1;
  o.reconnect_max_s = 0.5;
  return o;
}

template <typename Pred>
bool eventually(Pred pred, std::chrono::milliseconds timeout = 15s) {
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < until) {
    if (pred()) return true;
    std::this_thread::sleep_for(10ms);
  }
  return pred();
}

std::string connect_error(MqttOptions o, TestLogger& log) {
  try {
    MqttLink link(std::move(o), "locus", log);
  } catch (const MqttError& e) {
    std::fprintf(stderr, "[refused as expected] %s\n", e.what());
    return e.what();
  }
  return "(connected)";
}

TEST(MqttLinkBroker, TwoEndpointsExchangeBothWaysWithWildcards) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  // Receivers first: they must outlive the links whose handlers write to them.
  Inbox a_pos, a_self, b_beep, b_beep_one, b_beep_one_again, other_all;
  MqttLink a(options_for(broker), "locus", log);
  MqttLink b(options_for(broker), "locus", log);
  EXPECT_NE(a.connection().client_id(), b.connection().client_id());

  a.subscribe("pos/+", a_pos.handler());
  a.subscribe("self/#", a_self.handler());
  b.subscribe("beep/#", b_beep.handler());
  b.subscribe("beep/+/1", b_beep_one.handler());        // overlaps beep/#: one delivery each
  b.subscribe("beep/+/1", b_beep_one_again.handler());  // same filter twice: one broker subscription
  ASSERT_TRUE(a.wait_ready(10));
  ASSERT_TRUE(b.wait_ready(10));

  const std::string binary("x\0y\xff", 4);
  a.publish("beep/A/1", binary);
  a.publish("beep/A/2", "two");
  b.publish("pos/B", "{\"x\":1}");
  b.publish("pos/B/extra", "no");  // '+' is one level: not for pos/+
  a.publish("self/echo", "me");    // a publisher hears itself
  ASSERT_TRUE(b_beep.wait_count(2));
  ASSERT_TRUE(b_beep_one.wait_count(1));
  ASSERT_TRUE(b_beep_one_again.wait_count(1));
  ASSERT_TRUE(a_pos.wait_count(1));
  ASSERT_TRUE(a_self.wait_count(1));
  // Give stray duplicates or wrong matches time to show up.
  b.publish("beep/sync", "end");
  ASSERT_TRUE(b_beep.wait_count(3));
  std::this_thread::sleep_for(200ms);

  EXPECT_EQ(b_beep.topics(), (std::vector<std::string>{"beep/A/1", "beep/A/2", "beep/sync"}));
  EXPECT_EQ(b_beep.messages()[0].payload, binary);
  EXPECT_EQ(b_beep_one.topics(), (std::vector<std::string>{"beep/A/1"}));
  EXPECT_EQ(b_beep_one_again.topics(), (std::vector<std::string>{"beep/A/1"}));
  EXPECT_EQ(a_pos.topics(), (std::vector<std::string>{"pos/B"}));
  EXPECT_EQ(a_pos.messages()[0].payload, "{\"x\":1}");
  EXPECT_EQ(a_self.topics(), (std::vector<std::string>{"self/echo"}));

  // Another prefix is another deployment: it hears nothing of "locus".
  MqttLink other(options_for(broker), "other", log);
  other.subscribe("#", other_all.handler());
  ASSERT_TRUE(other.wait_ready(10));
  a.publish("beep/A/3", "3");
  ASSERT_TRUE(b_beep.wait_count(4));
  other.publish("beep/O", "o");
  ASSERT_TRUE(other_all.wait_count(1));
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(other_all.topics(), (std::vector<std::string>{"beep/O"}));
  EXPECT_EQ(b_beep.size(), 4u);

  // Invalid topics are refused at the call, with the topic named.
  EXPECT_THROW(a.publish("a/+/b", "x"), std::invalid_argument);
  EXPECT_THROW(a.subscribe("a/#/b", [](const LinkMessage&) {}), std::invalid_argument);

  EXPECT_EQ(a.stats().dropped, 0u);
  EXPECT_EQ(b.stats().dropped, 0u);
}

TEST(MqttLinkBroker, UnsubscribeWaitsForARunningHandlerAndStopsDelivery) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  std::atomic<bool> started{false}, finished{false};
  std::atomic<int> calls{0};
  Inbox marker;
  MqttLink a(options_for(broker), "locus", log);
  const auto id = a.subscribe("slow", [&](const LinkMessage&) {
    ++calls;
    started = true;
    std::this_thread::sleep_for(300ms);
    finished = true;
  });
  a.subscribe("marker", marker.handler());
  ASSERT_TRUE(a.wait_ready(10));
  a.publish("slow", "1");
  ASSERT_TRUE(eventually([&] { return started.load(); }));
  a.unsubscribe(id);
  EXPECT_TRUE(finished.load()) << "unsubscribe returned while the handler was still running";
  a.publish("slow", "2");
  a.publish("marker", "after");  // same client, same order: 'slow' was handled (or not) before this
  ASSERT_TRUE(marker.wait_count(1));
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(calls.load(), 1);
}

TEST(MqttLinkBroker, BothEndpointsSurviveABrokerRestart) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  // A retries every 4 s, B every 0.1 s: after the restart B is back (and subscribed) well before A
  // sends what it queued during the outage, so B's delivery of A's queue is deterministic.
  MqttOptions ao = options_for(broker);
  ao.reconnect_min_s = ao.reconnect_max_s = 4.0;
  MqttOptions bo = options_for(broker);
  bo.reconnect_min_s = bo.reconnect_max_s = 0.1;
  Inbox a_in, b_in;
  MqttLink a(ao, "locus", log);
  MqttLink b(bo, "locus", log);
  a.subscribe("data/#", a_in.handler());
  b.subscribe("data/#", b_in.handler());
  ASSERT_TRUE(a.wait_ready(10) && b.wait_ready(10));
  a.publish("data/before", "1");
  ASSERT_TRUE(b_in.wait_count(1) && a_in.wait_count(1));

  broker.kill_hard();
  ASSERT_TRUE(eventually([&] { return !a.stats().connected && !b.stats().connected; }))
      << "the links did not notice the broker's death";
  for (int i = 0; i < 5; ++i) a.publish("data/outage/" + std::to_string(i), std::to_string(i));
  EXPECT_EQ(a.stats().queued, 5u);
  broker.start();  // same port

  ASSERT_TRUE(b.wait_ready(20)) << "B did not reconnect";
  ASSERT_TRUE(a.wait_ready(20)) << "A did not reconnect";
  // A's outage messages: to A itself (re-subscribed before its queue is sent) and to B.
  ASSERT_TRUE(a_in.wait_count(6)) << "A got " << a_in.size();
  ASSERT_TRUE(b_in.wait_count(6)) << "B got " << b_in.size();
  const std::vector<std::string> expected{"data/before", "data/outage/0", "data/outage/1", "data/outage/2",
                                          "data/outage/3", "data/outage/4"};
  EXPECT_EQ(a_in.topics(), expected);
  EXPECT_EQ(b_in.topics(), expected);

  // And the exchange works both ways again.
  b.publish("data/after/b", "b");
  a.publish("data/after/a", "a");
  ASSERT_TRUE(a_in.wait_count(8) && b_in.wait_count(8));
  EXPECT_EQ(a.stats().connects, 2u);
  EXPECT_EQ(b.stats().connects, 2u);
  EXPECT_EQ(a.stats().dropped, 0u);
  EXPECT_EQ(a.stats().queued, 0u);
  EXPECT_TRUE(log.contains("reconnected to 127.0.0.1:" + std::to_string(broker.port())));
}

TEST(MqttLinkBroker, OfflineQueueIsBoundedAndCountsDrops) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  MqttOptions o = options_for(broker);
  o.queue_limit = 3;
  Inbox in;
  MqttLink a(o, "locus", log);
  a.subscribe("q/#", in.handler());
  ASSERT_TRUE(a.wait_ready(10));
  broker.kill_hard();
  ASSERT_TRUE(eventually([&] { return !a.stats().connected; }));
  for (int i = 0; i < 5; ++i) a.publish("q/" + std::to_string(i), "x");
  EXPECT_EQ(a.stats().queued, 3u);
  EXPECT_EQ(a.stats().dropped, 2u);
  broker.start();
  ASSERT_TRUE(a.wait_ready(20));
  ASSERT_TRUE(in.wait_count(3));
  std::this_thread::sleep_for(200ms);
  EXPECT_EQ(in.topics(), (std::vector<std::string>{"q/2", "q/3", "q/4"}));  // the oldest were dropped
}

TEST(MqttLinkBroker, WrongPasswordIsRefused) {
  TempDir dir;
  Broker::Options auth;
  auth.username = "alice";
  auth.password = "s3cret";
  Broker broker(dir.path(), auth);
  broker.start();
  TestLogger log;
  MqttOptions o = options_for(broker);
  const std::string where = "127.0.0.1:" + std::to_string(broker.port());

  o.username = "alice";
  o.password = "wrong";
  const std::string wrong = connect_error(o, log);
  EXPECT_NE(wrong.find(where), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("refused the connection"), std::string::npos) << wrong;
  EXPECT_NE(wrong.find("CONNACK reason code"), std::string::npos) << wrong;

  o.username.clear();
  o.password.clear();
  const std::string anonymous = connect_error(o, log);
  EXPECT_NE(anonymous.find("refused the connection"), std::string::npos) << anonymous;

  o.username = "alice";
  o.password = "s3cret";
  Inbox in;
  MqttLink ok(o, "locus", log);
  ok.subscribe("t", in.handler());
  ASSERT_TRUE(ok.wait_ready(10));
  ok.publish("t", "authorized");
  ASSERT_TRUE(in.wait_count(1));
}

// packaging/mosquitto/locus.acl, as shipped: a board writes only the link topics that end in its own
// name (and its own output tree); everyone reads the site.
TEST(MqttLinkBroker, AclLetsABoardWriteOnlyItsOwnTopics) {
  TempDir dir;
  Broker::Options auth;
  auth.username = "L01";
  auth.password = "pw-l01";
  auth.more_users = {{"L02", "pw-l02"}, {"hub", "pw-hub"}};
  auth.acl_file = std::string(LOCUS_SOURCE_DIR) + "/packaging/mosquitto/locus.acl";
  Broker broker(dir.path(), auth);
  broker.start();
  TestLogger log;
  const auto as = [&](const char* user, const char* password) {
    MqttOptions o = options_for(broker);
    o.username = user;
    o.password = password;
    return o;
  };
  Inbox hub_in;
  MqttLink hub(as("hub", "pw-hub"), "locus", log);
  hub.subscribe("amil/#", hub_in.handler());
  ASSERT_TRUE(hub.wait_ready(10));
  MqttLink l01(as("L01", "pw-l01"), "locus", log);
  MqttLink l02(as("L02", "pw-l02"), "locus", log);
  ASSERT_TRUE(l01.wait_ready(10));
  ASSERT_TRUE(l02.wait_ready(10));

  l01.publish("amil/arrivals/L01", "own");
  l01.publish("amil/arrivals/L02", "forged by L01");  // the broker drops it (not authorized)
  l01.publish("amil/hello", "not a board topic");     // too short: no board's
  l02.publish("amil/arrivals/L02", "own L02");
  l01.publish("amil/done/L01", "own again");          // after the forged one on the same connection
  ASSERT_TRUE(l01.flush(10));
  ASSERT_TRUE(l02.flush(10));
  ASSERT_TRUE(hub_in.wait_count(3)) << broker.log();
  std::this_thread::sleep_for(300ms);  // anything else would have arrived by now
  const std::vector<LinkMessage> got = hub_in.messages();
  ASSERT_EQ(got.size(), 3u) << ::testing::PrintToString(hub_in.topics());
  std::map<std::string, std::string> by_topic;
  for (const LinkMessage& m : got) by_topic[m.topic] = m.payload;
  EXPECT_EQ(by_topic["amil/arrivals/L01"], "own");
  EXPECT_EQ(by_topic["amil/arrivals/L02"], "own L02");  // L02's, never L01's forgery
  EXPECT_EQ(by_topic["amil/done/L01"], "own again");
  EXPECT_EQ(by_topic.count("amil/hello"), 0u);
}

// Signed link messages (auth_key_file): an attacker on the broker without the key cannot inject a
// beep report, alter one, or replay a real one; each is dropped before any handler and counted.
TEST(MqttLinkBroker, SignedLinkDropsForgedAlteredAndReplayedMessagesAndCountsThem) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  const std::string key_path = (dir.path() / "site.key").string();
  {
    std::ofstream(key_path) << "9f2c1a7e5b3d8c4f6a0e1d2c3b4a5f6e\n";
  }
  ::chmod(key_path.c_str(), 0600);
  const auto signer = [&](const char* name) {
    return std::make_unique<linkauth::MessageAuthenticator>(linkauth::load_key_file(key_path, "test"), name, 30.0);
  };
  MqttLink a(options_for(broker), "locus", log, signer("A"));
  Inbox b_in;
  MqttLink b(options_for(broker), "locus", log, signer("B"));
  b.subscribe("amil/#", b_in.handler());
  Inbox wire;  // the attacker: no key, sees the raw bytes
  MqttLink attacker(options_for(broker), "locus", log);
  attacker.subscribe("amil/#", wire.handler());
  ASSERT_TRUE(a.wait_ready(10));
  ASSERT_TRUE(b.wait_ready(10));
  ASSERT_TRUE(attacker.wait_ready(10));

  a.publish("amil/arrivals/A", R"({"beep":1,"frame":1000})");
  ASSERT_TRUE(b_in.wait_count(1));
  ASSERT_TRUE(wire.wait_count(1));
  EXPECT_EQ(b_in.messages()[0].payload, R"({"beep":1,"frame":1000})");
  const std::string captured = wire.messages()[0].payload;
  EXPECT_EQ(captured.rfind("LOCUS-HMAC1 A ", 0), 0u) << captured;

  attacker.publish("amil/arrivals/A", R"({"beep":2,"frame":999})");   // forged, unsigned
  attacker.publish("amil/arrivals/A", captured);                      // replayed as is
  std::string altered = captured;
  altered.replace(altered.find("1000"), 4, "2000");
  attacker.publish("amil/arrivals/A", altered);                       // altered
  attacker.publish("amil/arrivals/B", captured);                      // moved to another board's topic
  ASSERT_TRUE(eventually([&] { return b.auth_counts().rejected() == 4; })) << b.auth_counts().rejected();
  a.publish("amil/arrivals/A", R"({"beep":3,"frame":3000})");
  ASSERT_TRUE(b_in.wait_count(2));
  std::this_thread::sleep_for(200ms);
  ASSERT_EQ(b_in.size(), 2u);
  EXPECT_EQ(b_in.messages()[1].payload, R"({"beep":3,"frame":3000})");
  const linkauth::AuthCounts c = b.auth_counts();
  EXPECT_EQ(c.accepted, 2u);
  EXPECT_EQ(c.unsigned_messages, 1u);
  EXPECT_EQ(c.replayed, 1u);
  EXPECT_EQ(c.bad_signature, 2u);
  EXPECT_TRUE(log.contains("dropped a message on 'amil/arrivals/A' claiming sender 'A': replayed"));
}

TEST(MqttLinkBroker, Tls) {
  if (!locus::testing::run_command("command -v openssl >/dev/null 2>&1")) {
    GTEST_SKIP() << "openssl is not installed (tools/install-deps.sh installs it): TLS not tested";
  }
  TempDir dir;
  Broker::Options tls_options;
  tls_options.tls = true;
  Broker broker(dir.path(), tls_options);
  broker.start();
  TestLogger log;
  MqttOptions o = options_for(broker);
  o.tls_ca_file = broker.ca_file().string();
  {
    Inbox in;
    MqttLink a(o, "locus", log);
    MqttLink b(o, "locus", log);
    b.subscribe("secure/+", in.handler());
    ASSERT_TRUE(b.wait_ready(10));
    a.publish("secure/x", "over TLS");
    ASSERT_TRUE(in.wait_count(1));
    EXPECT_EQ(in.messages()[0].payload, "over TLS");
  }
  // Plain MQTT to the TLS listener, and TLS trusting another CA: both refused with a reason.
  MqttOptions plain = options_for(broker);
  plain.connect_timeout_s = 3.0;
  const std::string e1 = connect_error(plain, log);
  EXPECT_NE(e1.find("cannot connect to MQTT broker 127.0.0.1:" + std::to_string(broker.port())), std::string::npos) << e1;

  TempDir other_dir;
  ASSERT_TRUE(locus::testing::run_command(
      "cd '" + other_dir.path().string() +
      "' && openssl req -x509 -newkey rsa:2048 -nodes -keyout k.pem -out other.crt -days 1 -subj /CN=other "
      ">/dev/null 2>&1"));
  MqttOptions wrong_ca = o;
  wrong_ca.tls_ca_file = (other_dir.path() / "other.crt").string();
  wrong_ca.connect_timeout_s = 3.0;
  const std::string e2 = connect_error(wrong_ca, log);
  EXPECT_NE(e2.find("cannot connect to MQTT broker"), std::string::npos) << e2;
  EXPECT_NE(e2.find("TLS"), std::string::npos) << e2;
}

/// A raw libmosquitto subscriber (through MqttConnection) that records topic -> payloads.
class Recorder {
 public:
  Recorder(const Broker& b, TestLogger& log, const std::string& filter) {
    conn_ = std::make_unique<MqttConnection>(options_for(b), log, "recorder",
                                             [this](const std::string& t, std::string_view p, const std::vector<std::uint32_t>&) {
                                               std::lock_guard lock(m_);
                                               got_[t].push_back(std::string(p));
                                             });
    conn_->subscribe(filter);
    if (!conn_->wait_ready(10)) throw std::runtime_error("recorder not ready");
  }
  std::vector<std::string> at(const std::string& topic) const {
    std::lock_guard lock(m_);
    auto it = got_.find(topic);
    return it == got_.end() ? std::vector<std::string>{} : it->second;
  }
  std::size_t topics() const {
    std::lock_guard lock(m_);
    return got_.size();
  }

 private:
  mutable std::mutex m_;
  std::map<std::string, std::vector<std::string>> got_;
  std::unique_ptr<MqttConnection> conn_;
};

Estimate estimate(const char* target, double x, double y) {
  Estimate e;
  e.plugin = "tum";
  e.reference = "A";
  e.frame = "device";
  e.target = target;
  e.t_s = 2.0;
  e.position_m = {x, y, kNaN};
  e.dims = 2;
  e.confidence = 0.9f;
  return e;
}

TEST(MqttOutputBroker, PublishesEventsStateAndDiscovery) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  Recorder rec(broker, log, "#");
  MqttOutputOptions oo;
  oo.node = "n1";
  const Event e1{estimate("B", 3.0, 4.0)};
  const Event e2{estimate("B", 6.0, 8.0)};
  AudioDetection det;
  det.device = "A";
  det.detector = "chirp_A";
  det.frame = 441.0;
  det.sample_rate_hz = 44100.0;
  const Event e3{det};
  {
    MqttEventOutput out(options_for(broker), oo, log);
    out.write(e1);
    out.write(e2);
    out.write(e3);
    out.flush();
    EXPECT_EQ(out.stats().dropped, 0u);
    ASSERT_TRUE(eventually([&] { return rec.at("locus/n1/estimate/B/state").size() == 2; }));
    ASSERT_TRUE(eventually([&] { return rec.at("locus/n1/audio_detection/A").size() == 1; }));

    const auto events = rec.at("locus/n1/estimate/B");
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(events[0], event_to_json(e1).dump());  // the JSON-lines shape
    EXPECT_EQ(events[1], event_to_json(e2).dump());
    EXPECT_EQ(rec.at("locus/n1/audio_detection/A")[0], event_to_json(e3).dump());

    const auto config = rec.at("homeassistant/sensor/locus_n1_B/config");
    ASSERT_EQ(config.size(), 1u);  // once per target
    const auto c = nlohmann::json::parse(config[0]);
    EXPECT_EQ(c["state_topic"], "locus/n1/estimate/B/state");
    EXPECT_EQ(c["unit_of_measurement"], "m");
    EXPECT_EQ(c["value_template"], "{{ value_json.distance_m }}");
    EXPECT_EQ(c["availability_topic"], "locus/n1/status");

    const auto state = nlohmann::json::parse(rec.at("locus/n1/estimate/B/state")[1]);
    EXPECT_DOUBLE_EQ(state["x"].get<double>(), 6.0);
    EXPECT_DOUBLE_EQ(state["y"].get<double>(), 8.0);
    EXPECT_DOUBLE_EQ(state["distance_m"].get<double>(), 10.0);
    EXPECT_NEAR(state["confidence"].get<double>(), 0.9, 1e-6);
    EXPECT_EQ(rec.at("locus/n1/status").back(), "online");

    // A consumer that connects later (Home Assistant after a restart) still gets the retained config
    // and the availability.
    Recorder late(broker, log, "#");
    ASSERT_TRUE(eventually([&] { return late.at("homeassistant/sensor/locus_n1_B/config").size() == 1; }));
    ASSERT_TRUE(eventually([&] { return !late.at("locus/n1/status").empty(); }));
    EXPECT_EQ(late.at("locus/n1/status").back(), "online");
    EXPECT_TRUE(late.at("locus/n1/estimate/B").empty());  // events are not retained by default
  }
  // Shut down: availability goes offline (retained).
  ASSERT_TRUE(eventually([&] { return !rec.at("locus/n1/status").empty() && rec.at("locus/n1/status").back() == "offline"; }));
  Recorder after(broker, log, "locus/n1/status");
  ASSERT_TRUE(eventually([&] { return !after.at("locus/n1/status").empty(); }));
  EXPECT_EQ(after.at("locus/n1/status").back(), "offline");
}

TEST(MqttOutputBroker, DiscoveryIsResentAfterABrokerRestart) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  MqttOutputOptions oo;
  oo.node = "n2";
  MqttEventOutput out(options_for(broker), oo, log);
  out.write(Event{estimate("T", 1.0, 0.0)});
  out.flush();
  broker.kill_hard();  // persistence false: the retained config is gone with it
  ASSERT_TRUE(eventually([&] { return !out.stats().connected; }));
  broker.start();
  ASSERT_TRUE(eventually([&] { return out.stats().connected; }, 20s));
  out.flush();
  Recorder late(broker, log, "homeassistant/#");
  ASSERT_TRUE(eventually([&] { return late.at("homeassistant/sensor/locus_n2_T/config").size() == 1; }));
}

TEST(MqttOutputBroker, TopicNamesSeenByMosquittoSub) {
  TempDir dir;
  Broker broker(dir.path(), {});
  broker.start();
  TestLogger log;
  const std::string out_file = (dir.path() / "sub.txt").string();
  // mosquitto_sub prints "topic payload" per message and exits after 2 messages (or 20 s).
  const std::string cmd = "mosquitto_sub -h 127.0.0.1 -p " + std::to_string(broker.port()) +
                          " -t 'locus/+/estimate/#' -t 'locus/link/#' -v -C 2 -W 20 > '" + out_file + "' 2>&1";
  std::thread sub([&] { locus::testing::run_command(cmd); });
  MqttLink link(options_for(broker), "locus", log);
  MqttOutputOptions oo;
  oo.node = "n3";
  oo.discovery_prefix = "";  // off
  MqttEventOutput out(options_for(broker), oo, log);
  // Publish until mosquitto_sub (subscribing concurrently) has its two messages.
  std::atomic<bool> done{false};
  std::thread pub([&] {
    for (int i = 0; i < 200 && !done; ++i) {
      link.publish("tum/ts/A", "1");
      out.write(Event{estimate("C", 1.0, 1.0)});
      std::this_thread::sleep_for(100ms);
    }
  });
  sub.join();
  done = true;
  pub.join();
  std::ifstream in(out_file);
  std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const bool link_topic = all.find("locus/link/tum/ts/A 1") != std::string::npos;
  const bool event_topic = all.find("locus/n3/estimate/C ") != std::string::npos ||
                           all.find("locus/n3/estimate/C/state ") != std::string::npos;
  EXPECT_TRUE(link_topic || event_topic) << all;
  for (std::size_t pos = 0; (pos = all.find('\n', pos)) != std::string::npos; ++pos) {
  }
  // Every line is one of the documented topics.
  std::istringstream lines(all);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    const std::string topic = line.substr(0, line.find(' '));
    EXPECT_TRUE(topic == "locus/link/tum/ts/A" || topic == "locus/n3/estimate/C" || topic == "locus/n3/estimate/C/state")
        << line;
  }
  EXPECT_EQ(n, 2) << all;
}

}  // namespace
}  // namespace locus::mqtt
