// link/mqtt without a broker: link topic mapping, the output's topics and payloads (event JSON, Home
// Assistant state and discovery config), parameter validation errors (each naming its key), the
// registered descriptors, and an unreachable broker refused with host:port and the reason.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>

#include "integration/mqtt/broker.hpp"
#include "locus/json_events.hpp"
#include "locus/registry.hpp"
#include "links.hpp"
#include "mqtt/mqtt_link.hpp"
#include "mqtt/mqtt_output.hpp"

namespace locus::mqtt {
namespace {

class NullLogger final : public Logger {
 public:
  void log(LogLevel, std::string_view) override {}
};

Params link_params() { return Params::defaults(mqtt_link_schema()); }
Params output_params() { return Params::defaults(mqtt_output_schema()); }

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const MqttError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MqttTopics, LinkTopicsMapUnderThePrefix) {
  LinkTopics t("locus");
  EXPECT_EQ(t.to_mqtt("tum/ranging/A"), "locus/link/tum/ranging/A");
  EXPECT_EQ(t.to_mqtt("#"), "locus/link/#");
  EXPECT_EQ(t.from_mqtt("locus/link/tum/ranging/A").value(), "tum/ranging/A");
  EXPECT_FALSE(t.from_mqtt("locus/linkx/a").has_value());
  EXPECT_FALSE(t.from_mqtt("locus/link").has_value());  // what 'locus/link/#' also matches at the broker
  EXPECT_FALSE(t.from_mqtt("other/link/a").has_value());
  LinkTopics site("site/a");
  EXPECT_EQ(site.to_mqtt("x"), "site/a/link/x");
  EXPECT_EQ(site.from_mqtt("site/a/link/x/y").value(), "x/y");
}

TEST(MqttTopics, BadPrefixesAreRefusedNamingTheKey) {
  for (const char* bad : {"", "a/+", "#", "/locus", "locus/", "a//b"}) {
    const std::string e = error_of([&] { LinkTopics t(bad); });
    EXPECT_NE(e.find("topic_prefix"), std::string::npos) << bad << ": " << e;
    EXPECT_NE(e.find("got '" + std::string(bad) + "'"), std::string::npos) << e;
  }
}

TEST(MqttParams, DefaultsAreValid) {
  const MqttOptions o = mqtt_options_from_params(link_params(), "mqtt link");
  EXPECT_EQ(o.host, "127.0.0.1");
  EXPECT_EQ(o.port, 1883);
  EXPECT_EQ(o.qos, 1);
  EXPECT_TRUE(o.client_id.empty());
  EXPECT_TRUE(o.tls_ca_file.empty());
  EXPECT_EQ(link_params().get_string("topic_prefix"), "locus");
}

TEST(MqttParams, CrossFieldErrorsNameTheKey) {
  auto with = [](std::vector<std::pair<std::string, ParamValue>> kv) {
    Params p = link_params();
    for (auto& [k, v] : kv) p.set(k, v);
    return error_of([&] { mqtt_options_from_params(p, "mqtt link"); });
  };
  EXPECT_NE(with({{"host", std::string("")}}).find("mqtt link: host:"), std::string::npos);
  EXPECT_NE(with({{"password", std::string("x")}}).find("password: a password needs a username"), std::string::npos);
  EXPECT_NE(with({{"tls_cert_file", std::string("/etc/hostname")}}).find("tls_ca_file: TLS options"),
            std::string::npos);
  EXPECT_NE(with({{"tls_insecure", true}}).find("need tls_ca_file"), std::string::npos);
  const std::string missing = with({{"tls_ca_file", std::string("/nonexistent/ca.crt")}});
  EXPECT_NE(missing.find("tls_ca_file: '/nonexistent/ca.crt' is not a readable file"), std::string::npos) << missing;
  testing::TempDir dir;
  const std::string ca = (dir.path() / "ca.crt").string();
  std::ofstream(ca) << "x";
  EXPECT_NE(with({{"tls_ca_file", ca}, {"tls_cert_file", ca}}).find("tls_key_file: a client certificate needs both"),
            std::string::npos);
  EXPECT_EQ(with({{"tls_ca_file", ca}}), "(no error)");
  EXPECT_NE(with({{"reconnect_min_s", 5.0}, {"reconnect_max_s", 1.0}}).find("reconnect_min_s: must not exceed"),
            std::string::npos);
}

TEST(MqttParams, OutputOptions) {
  Params p = output_params();
  p.set("node", std::string("table-1"));
  const MqttOutputOptions o = mqtt_output_options_from_params(p);
  EXPECT_EQ(o.node, "table-1");
  EXPECT_EQ(o.discovery_prefix, "homeassistant");
  EXPECT_FALSE(o.retain);
  p.set("node", std::string(""));
  EXPECT_FALSE(mqtt_output_options_from_params(p).node.empty());  // the host name
  p.set("node", std::string("a/b"));
  EXPECT_NE(error_of([&] { mqtt_output_options_from_params(p); }).find("node: expected one topic level"),
            std::string::npos);
  p.set("node", std::string("n"));
  p.set("discovery_prefix", std::string(""));
  EXPECT_TRUE(mqtt_output_options_from_params(p).discovery_prefix.empty());  // discovery off
  p.set("discovery_prefix", std::string("ha/"));
  EXPECT_NE(error_of([&] { mqtt_output_options_from_params(p); }).find("discovery_prefix"), std::string::npos);
}

MqttOutputOptions out_opts() {
  MqttOutputOptions o;
  o.node = "n1";
  return o;
}

Estimate estimate(const char* target) {
  Estimate e;
  e.plugin = "tum";
  e.reference = "A";
  e.frame = "device";
  e.target = target;
  e.t_s = 1.5;
  e.position_m = {3.0, 4.0, kNaN};
  e.dims = 2;
  e.direction_rad = std::numbers::pi / 2;
  e.std_m = 0.1;
  e.confidence = 0.75f;
  return e;
}

TEST(MqttOutputPayloads, EventTopics) {
  const MqttOutputOptions o = out_opts();
  EXPECT_EQ(event_topic(o, Event{estimate("B")}), "locus/n1/estimate/B");
  AudioDetection d;
  d.device = "A";
  EXPECT_EQ(event_topic(o, Event{d}), "locus/n1/audio_detection/A");
  BleAdvertisement b;
  b.device = "obs";
  EXPECT_EQ(event_topic(o, Event{b}), "locus/n1/ble_advertisement/obs");
  EXPECT_EQ(event_topic(o, Event{estimate("a/b+c#")}), "locus/n1/estimate/a_b_c_");
  EXPECT_EQ(event_topic(o, Event{estimate("")}), "locus/n1/estimate/_");
  EXPECT_EQ(state_topic(o, "B"), "locus/n1/estimate/B/state");
  EXPECT_EQ(status_topic(o), "locus/n1/status");
  EXPECT_EQ(discovery_topic(o, "AA:BB:CC:DD:EE:FF"), "homeassistant/sensor/locus_n1_AA_BB_CC_DD_EE_FF/config");
}

TEST(MqttOutputPayloads, EstimateState) {
  const auto j = estimate_state_json(estimate("B"));
  EXPECT_DOUBLE_EQ(j["x"].get<double>(), 3.0);
  EXPECT_DOUBLE_EQ(j["y"].get<double>(), 4.0);
  EXPECT_FALSE(j.contains("z"));
  EXPECT_DOUBLE_EQ(j["distance_m"].get<double>(), 5.0);  // no range given: norm of the position
  EXPECT_NEAR(j["direction_deg"].get<double>(), 90.0, 1e-12);
  EXPECT_NEAR(j["confidence"].get<double>(), 0.75, 1e-6);
  EXPECT_EQ(j["plugin"], "tum");
  EXPECT_EQ(j["target"], "B");

  Estimate e = estimate("B");
  e.distance_m = 2.5;  // a range wins over the position's norm
  e.direction_rad = kNaN;
  e.dims = 3;
  e.position_m = {1.0, 2.0, 3.0};
  const auto k = estimate_state_json(e);
  EXPECT_DOUBLE_EQ(k["distance_m"].get<double>(), 2.5);
  EXPECT_TRUE(k["direction_deg"].is_null());
  EXPECT_DOUBLE_EQ(k["z"].get<double>(), 3.0);

  Estimate unknown = estimate("B");
  unknown.position_m = {kNaN, kNaN, kNaN};
  const auto u = estimate_state_json(unknown);
  EXPECT_TRUE(u["x"].is_null());
  EXPECT_TRUE(u["distance_m"].is_null());
  EXPECT_NO_THROW((void)u.dump());
}

TEST(MqttOutputPayloads, DiscoveryConfig) {
  const auto j = discovery_config_json(out_opts(), "B");
  EXPECT_EQ(j["unique_id"], "locus_n1_B");
  EXPECT_EQ(j["state_topic"], "locus/n1/estimate/B/state");
  EXPECT_EQ(j["json_attributes_topic"], "locus/n1/estimate/B/state");
  EXPECT_EQ(j["unit_of_measurement"], "m");
  EXPECT_EQ(j["value_template"], "{{ value_json.distance_m }}");
  EXPECT_EQ(j["device_class"], "distance");
  EXPECT_EQ(j["availability_topic"], "locus/n1/status");
  EXPECT_EQ(j["device"]["identifiers"][0], "locus_n1");
}

TEST(MqttRegistry, LinkAndOutputAreRegistered) {
  Registry r;
  links::register_builtin_links(r);
  const LinkDescriptor* l = r.find_link("mqtt");
  ASSERT_NE(l, nullptr);
  const OutputDescriptor* o = r.find_output("mqtt");
  ASSERT_NE(o, nullptr);
  auto keys = [](const ParamSchema& s) {
    std::set<std::string> k;
    for (const auto& p : s) k.insert(p.key);
    return k;
  };
  for (const char* k : {"host", "port", "client_id", "topic_prefix", "username", "password", "tls_ca_file",
                        "tls_cert_file", "tls_key_file", "tls_insecure", "qos", "keepalive_s", "reconnect_min_s",
                        "reconnect_max_s", "connect_timeout_s", "queue_limit"}) {
    EXPECT_TRUE(keys(l->schema).count(k)) << k;
    EXPECT_TRUE(keys(o->schema).count(k)) << k;
  }
  for (const char* k : {"node", "discovery_prefix", "retain"}) EXPECT_TRUE(keys(o->schema).count(k)) << k;
  // A bad combination is refused by create() with the key named (the config validator checks types/ranges).
  Params p = Params::defaults(l->schema);
  p.set("password", std::string("x"));
  NullLogger log;
  try {
    (void)l->create(p, log);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("password"), std::string::npos) << e.what();
  }
}

TEST(MqttConnect, UnreachableBrokerIsRefusedWithHostPortAndReason) {
  // A port that is bound but not listening refuses connections, and no broker can take it meanwhile.
  const int holder = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(holder, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(holder, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::getsockname(holder, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  const int port = ntohs(addr.sin_port);
  Params p = link_params();
  p.set("port", std::int64_t{port});
  p.set("connect_timeout_s", 1.0);
  p.set("reconnect_min_s", 0.1);
  NullLogger log;
  const auto t0 = std::chrono::steady_clock::now();
  const std::string e = error_of([&] { MqttLink link(mqtt_options_from_params(p, "mqtt link"), "locus", log); });
  const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_NE(e.find("127.0.0.1:" + std::to_string(port)), std::string::npos) << e;
  EXPECT_NE(e.find("Connection refused"), std::string::npos) << e;
  EXPECT_LT(took_s, 30.0);  // bounded by connect_timeout_s, never a hang
  ::close(holder);
}

}  // namespace
}  // namespace locus::mqtt
