// The one signal parser and writer (core/src/api/signal.cpp): YAML and JSON text into SignalSpec with
// every error naming its field, line and column; the typed rules (check_signal) the emitter applies;
// the JSON and YAML writers as inverses of the parser.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <array>
#include <limits>
#include <string>
#include <vector>

#include "locus/signal.hpp"
#include "locus/signal_yaml.hpp"

namespace locus {
namespace {

/// what() of the SignalError parse_signal(text) throws ("" and a failure when it does not throw).
std::string parse_error(const std::string& text) {
  try {
    parse_signal(text, "msg");
  } catch (const SignalError& e) {
    EXPECT_FALSE(e.issues().empty());
    EXPECT_EQ(e.source(), "msg");
    return e.what();
  }
  ADD_FAILURE() << "no SignalError for " << text;
  return "";
}

void expect_same(const SignalSpec& a, const SignalSpec& b) {
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.amplitude, b.amplitude);
  EXPECT_EQ(a.f0_hz, b.f0_hz);
  EXPECT_EQ(a.f1_hz, b.f1_hz);
  EXPECT_EQ(a.duration_s, b.duration_s);
  EXPECT_EQ(a.fade_s, b.fade_s);
  EXPECT_EQ(a.tones_hz, b.tones_hz);
  EXPECT_EQ(a.degree, b.degree);
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.carrier_hz, b.carrier_hz);
  EXPECT_EQ(a.chip_samples, b.chip_samples);
  EXPECT_EQ(a.chips, b.chips);
  EXPECT_EQ(a.address, b.address);
  EXPECT_EQ(a.tx_power_dbm, b.tx_power_dbm);
  EXPECT_EQ(a.interval_s, b.interval_s);
  EXPECT_EQ(a.sync_delay_s, b.sync_delay_s);
}

std::vector<SignalSpec> one_of_each() {
  return {parse_signal("{type: lfm, f0: 2000, f1: 8000.5, duration: 0.04, fade: 0.005, amplitude: 0.7, sync_delay_s: 0.0123}"),
          parse_signal(R"({"type":"multitone","tones_hz":[18000,18250.25],"duration":0.05})"),
          parse_signal("{type: gold, degree: 7, index: 3, carrier: 19000, chip_samples: 4, amplitude: 0.5}"),
          parse_signal("{type: gold, degree: 4, index: 0, carrier: 0, chip_samples: 1, chips: '100010011010111'}"),
          parse_signal("{type: ble, address: 'c4:2C:03:3A:2C:A1', tx_power_dbm: -59, interval_s: 0.1}"),
          parse_signal("{type: zadoff_chu, root: 25}")};
}

TEST(Signal, ParsesYamlAndJsonAlike) {
  const SignalSpec y = parse_signal("{type: lfm, f0: 18000, f1: 22000, duration: 0.05, fade: 0.005}");
  const SignalSpec j = parse_signal(R"({"type":"lfm","f0":18000,"f1":22000,"duration":0.05,"fade":0.005})");
  expect_same(y, j);
  EXPECT_EQ(j.type, "lfm");
  EXPECT_EQ(j.f1_hz, 22000.0);
  EXPECT_EQ(j.amplitude, 1.0);  // default
  EXPECT_FALSE(j.sync_delay_s);
  const SignalSpec b = parse_signal("type: ble\naddress: C4:2C:03:3A:2C:A1\ntx_power_dbm: -59\ninterval_s: 0.1\n");
  EXPECT_EQ(b.address, "C4:2C:03:3A:2C:A1");
  EXPECT_FALSE(b.acoustic());
  // unknown keys are ignored, unknown types kept as they are
  EXPECT_EQ(parse_signal(R"({"type":"lfm","f0":1,"f1":2,"duration":1,"future":true})").f1_hz, 2.0);
  EXPECT_EQ(parse_signal(R"({"type":"ofdm","subcarriers":64})").type, "ofdm");
}

TEST(Signal, ErrorsNameTheFieldLineAndColumn) {
  EXPECT_EQ(parse_error(R"({"type":"lfm","f0":18000})"),
            "msg:1:1: missing required key 'f1' (expected 'f1' for type lfm)\n"
            "msg:1:1: missing required key 'duration' (expected 'duration' for type lfm)");
  EXPECT_EQ(parse_error("{type: lfm, f0: 1, f1: 2,\n duration: 0.1, amplitude: 2}"),
            "msg:2:28: amplitude: value 2 out of range (expected 0..1)");
  EXPECT_EQ(parse_error(R"({"type":"lfm","f0":"high","f1":2,"duration":1})"),
            "msg:1:20: f0: expected a number, got 'high'");
  EXPECT_EQ(parse_error("{type: multitone, tones_hz: [100, -5], duration: 1}"),
            "msg:1:35: tones_hz[1]: value -5 out of range (expected > 0 Hz)");
  EXPECT_EQ(parse_error("{type: gold, degree: 8, index: 0, carrier: 0, chip_samples: 1}"),
            "msg:1:22: degree: degree 8 has no preferred pair (expected 5, 6, 7, 9, 10 or 11, or give 'chips')");
  EXPECT_EQ(parse_error("{type: gold, degree: 5, index: 5000000000, carrier: 0, chip_samples: 1}"),
            "msg:1:32: index: value 5000000000 out of range (expected 0..32)");
  EXPECT_EQ(parse_error("{type: gold, degree: 3, index: 0, carrier: 0, chip_samples: 1, chips: ''}"),
            "msg:1:71: chips: expected a string of 0 and 1, got an empty string");
  EXPECT_EQ(parse_error("{type: ble, address: 'C4:2C', tx_power_dbm: -59, interval_s: 0.1}"),
            "msg:1:22: address: expected a BLE address AA:BB:CC:DD:EE:FF (hex), got 'C4:2C'");
  EXPECT_EQ(parse_error("{f0: 1}"),
            "msg:1:1: missing required key 'type' (expected lfm, gold, multitone, ble or a project type)");
  EXPECT_EQ(parse_error("[1, 2]"), "msg:1:1: expected one signal object ({\"type\": ..., ...}), got a list");
  const std::string bad = parse_error("{not json");  // not JSON (nor YAML): the position of the problem
  EXPECT_EQ(bad.rfind("msg:", 0), 0u) << bad;
  EXPECT_NE(bad.find("not valid YAML/JSON"), std::string::npos) << bad;
}

TEST(Signal, NodeParserPrefixesTheFieldsWithTheirPlace) {
  const YAML::Node doc = YAML::Load("emits:\n  - {type: lfm, f0: 1, f1: 2, duration: 0}\n");
  std::vector<SignalIssue> issues;
  const SignalSpec s = parse_signal_node(doc["emits"][0], "devices[0].emits[0]", issues);
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].format("scene.yaml"),
            "scene.yaml:2:41: devices[0].emits[0].duration: value 0 out of range (expected > 0 s)");
  EXPECT_EQ(s.f1_hz, 2.0);  // the valid fields are kept
}

TEST(Signal, JsonAndYamlWritersAreTheParsersInverse) {
  for (const SignalSpec& s : one_of_each()) {
    const std::string json = signal_to_json(s);
    SCOPED_TRACE(json);
    expect_same(parse_signal(json), s);
    YAML::Emitter out;
    emit_signal_yaml(out, s);
    ASSERT_TRUE(out.good()) << out.GetLastError();
    expect_same(parse_signal(out.c_str()), s);
  }
  EXPECT_EQ(signal_to_json(one_of_each()[0]),
            R"({"type":"lfm","f0":2000.0,"f1":8000.5,"duration":0.04,"fade":0.005,"amplitude":0.7,"sync_delay_s":0.0123})");
  YAML::Emitter out;
  emit_signal_yaml(out, one_of_each()[3]);
  EXPECT_EQ(std::string(out.c_str()),
            R"({type: gold, degree: 4, index: 0, carrier: 0, chip_samples: 1, amplitude: 1, chips: "100010011010111"})");
}

TEST(Signal, TypedRulesAreTheParsersRules) {
  for (const SignalSpec& s : one_of_each()) EXPECT_TRUE(check_signal(s).empty()) << signal_to_json(s);
  SignalSpec s = one_of_each()[0];
  s.duration_s = 0.0;
  s.amplitude = 1.5;
  const auto issues = check_signal(s, "emits[2]");
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].format("beep"), "beep: emits[2].duration: value 0 out of range (expected > 0 s)");
  EXPECT_EQ(issues[1].format("beep"), "beep: emits[2].amplitude: value 1.5 out of range (expected 0..1)");
  SignalSpec m = one_of_each()[1];
  m.tones_hz.push_back(0.0);
  ASSERT_EQ(check_signal(m).size(), 1u);
  EXPECT_EQ(check_signal(m)[0].field, "tones_hz[2]");
  m.tones_hz.clear();
  ASSERT_EQ(check_signal(m).size(), 1u);
  EXPECT_EQ(check_signal(m)[0].message, "expected a non-empty list of frequencies in Hz, got an empty list");
  SignalSpec g = one_of_each()[3];  // degree 4 is fine with explicit chips, not without
  EXPECT_TRUE(check_signal(g).empty());
  g.chips.clear();
  ASSERT_EQ(check_signal(g).size(), 1u);
  EXPECT_EQ(check_signal(g)[0].field, "degree");
  g.chips = "0120";
  EXPECT_EQ(check_signal(g)[0].message, "expected only '0' and '1', got '2' at position 2");
  SignalSpec b = one_of_each()[4];
  b.address = "nope";
  EXPECT_EQ(check_signal(b)[0].field, "address");
  SignalSpec nan_delay = one_of_each()[0];
  nan_delay.sync_delay_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(check_signal(nan_delay)[0].field, "sync_delay_s");
  EXPECT_EQ(check_signal(SignalSpec{})[0].field, "type");
}

TEST(Signal, KnownTypesAndBleAddresses) {
  for (const char* t : {"lfm", "gold", "multitone", "ble"}) EXPECT_TRUE(is_known_signal_type(t)) << t;
  EXPECT_FALSE(is_known_signal_type("ofdm"));
  EXPECT_FALSE(is_known_signal_type(""));
  std::array<std::uint8_t, 6> a{};
  ASSERT_TRUE(parse_ble_address("c4:2C:03:3a:2C:A1", a));
  EXPECT_EQ(format_ble_address(a), "C4:2C:03:3A:2C:A1");
  EXPECT_FALSE(parse_ble_address("C4:2C:03:3A:2C", a));
  EXPECT_FALSE(parse_ble_address("C4-2C-03-3A-2C-A1", a));
}

}  // namespace
}  // namespace locus
