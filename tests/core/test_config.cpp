// load_config / validate_params: one test per error class (exact message, line and column), all
// errors of a file at once, and a full config read into the Config struct with defaults filled.
// Uses its own fake plugins and source in a local Registry (never the built-ins).
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "config_values.hpp"
#include "support/test_host.hpp"
#include "locus/config.hpp"
#include "locus/playback.hpp"
#include "locus/registry.hpp"

namespace locus {
namespace {

namespace fs = std::filesystem;

// ------------------------------------------------------------------------------ fakes

const ParamSchema* onset_schema() {
  static const ParamSchema schema = [] {
    ParamSchema s;
    s.push_back(float_param("threshold_db", -20.0, -60.0, 0.0, "dB", ""));
    s.push_back(float_param("window_s", 0.05, 0.0, 1.0, "s", ""));
    s.push_back(enum_param("mode", std::string("fast"), {"fast", "slow"}, ""));
    s.push_back(bool_param("enabled", true, ""));
    s.push_back(int_param("order", std::int64_t{2}, 1.0, 8.0, "", ""));
    s.push_back(float_list_param("gains", std::vector<double>{1.0}, 0.0, 10.0, "", "", 1, 4));
    return s;
  }();
  return &schema;
}
const ParamSchema* xcorr_schema() {
  static const ParamSchema schema = {float_param("template_hz", {}, 1.0, 20000.0, "Hz", "")};  // required
  return &schema;
}
const ParamSchema* tri_schema() {
  static const ParamSchema schema = {float_param("max_range_m", 10.0, 0.0, 100.0, "m", "")};
  return &schema;
}

const locus_plugin_descriptor kOnset{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "onset", "1", "onsets",
                                     kInputAudio, &onset_schema, &test::make_null_detector, nullptr};
const locus_plugin_descriptor kXcorr{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "xcorr", "1", "xcorr",
                                     kInputAudio, &xcorr_schema, &test::make_null_detector, nullptr};
const locus_plugin_descriptor kTri{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "tri", "1", "trilateration",
                                   0, &tri_schema, nullptr, &test::make_null_localizer};

class ConfigTest : public ::testing::Test {
 protected:
  ConfigTest() {
    registry.add_plugin(&kOnset);
    registry.add_plugin(&kXcorr);
    registry.add_plugin(&kTri);
    registry.add_source(SourceDescriptor{
        "synth", "test tones",
        {float_param("frequency_hz", 1000.0, 1.0, 20000.0, "Hz", ""),
         int_param("channels", std::int64_t{1}, 1.0, 8.0, "", "")},
        [] { return std::make_unique<test::NullSource>(); }});
  }

  std::vector<ConfigError> errors(std::string_view yaml) {
    try {
      load_config_string(yaml, "test.yaml", registry);
    } catch (const ConfigErrors& e) {
      return e.errors();
    }
    ADD_FAILURE() << "the config was accepted";
    return {};
  }

  Registry registry;
};

#define EXPECT_CONFIG_ERROR(err, l, c, k, msg) \
  do {                                         \
    const ConfigError& e_ = (err);             \
    EXPECT_EQ(e_.file, "test.yaml");           \
    EXPECT_EQ(e_.line, l);                     \
    EXPECT_EQ(e_.column, c);                   \
    EXPECT_EQ(e_.key, k);                      \
    EXPECT_EQ(e_.message, msg);                \
  } while (0)

const char* const kEventNames =
    "audio_detection, imu_sample, ble_advertisement, radio_sync, step, attitude, estimate, decay_features";

// ------------------------------------------------------------------------------ error classes

TEST(ConfigError, Format) {
  EXPECT_EQ((ConfigError{"a.yaml", 3, 5, "devices[0].id", "bad"}).format(), "a.yaml:3:5: devices[0].id: bad");
  EXPECT_EQ((ConfigError{"a.yaml", 0, 0, "", "cannot read"}).format(), "a.yaml: cannot read");
  EXPECT_EQ((ConfigError{"a.yaml", 3, 5, "", "syntax"}).format(), "a.yaml:3:5: syntax");
  EXPECT_EQ((ConfigError{"", 0, 0, "order", "expected"}).format(), "order: expected");
  const ConfigErrors all({ConfigError{"a.yaml", 1, 1, "x", "one"}, ConfigError{"a.yaml", 2, 1, "y", "two"}});
  EXPECT_STREQ(all.what(), "a.yaml:1:1: x: one\na.yaml:2:1: y: two");
  EXPECT_EQ(all.errors().size(), 2u);
}

TEST_F(ConfigTest, UnreadableFile) {
  try {
    load_config("/nonexistent/locus.yaml", registry);
    FAIL();
  } catch (const ConfigErrors& e) {
    ASSERT_EQ(e.errors().size(), 1u);
    EXPECT_EQ(e.errors()[0].format(), "/nonexistent/locus.yaml: cannot read the config file: No such file or directory");
  }
}

TEST_F(ConfigTest, YamlSyntaxError) {
  const auto e = errors("devices: [A, B\nlog_level: info\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 2, 10, "", "YAML syntax error: end of sequence flow not found");
}

TEST_F(ConfigTest, EmptyFileAndTopLevelNotAMapping) {
  auto e = errors("# nothing here\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 0, 0, "", "the file is empty; expected a mapping with at least one device or localizer");
  e = errors("- id: A\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 1, 1, "", "expected a mapping, got a list");
}

TEST_F(ConfigTest, SeveralYamlDocuments) {
  const auto e = errors("devices:\n  - id: A\n---\nlog_level: info\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 4, 1, "", "expected one YAML document, found 2 (remove the '---' separators)");
}

// Found by tests/fuzz (config): a lone ',' made yaml-cpp 0.7's LoadAll loop forever, allocating
// (jbeder/yaml-cpp#1040); `locus check-config` hung until the machine ran out of memory.
TEST_F(ConfigTest, ALoneCommaIsAnErrorNotAHang) {
  for (const char* text : {",\n", "devices:\n  - id: A\n,\n", "\n\n,templatet port: {from_scene: true}\n"}) {
    const auto e = errors(text);
    ASSERT_FALSE(e.empty()) << text;
  }
  // An empty second document (a trailing '---') is no document.
  try {
    load_config_string("log_level: info\ndevices:\n  - id: A\n---\n", "test.yaml", registry);
  } catch (const ConfigErrors& e) {
    for (const auto& err : e.errors()) EXPECT_EQ(err.message.find("YAML document"), std::string::npos) << err.message;
  }
}

TEST_F(ConfigTest, WrongNodeKind) {
  const auto e = errors(R"(output: [estimate]
devices:
  - id: A
    detectors:
      - plugin: onset
        params: [1, 2]
localizers: tri
)");
  ASSERT_EQ(e.size(), 3u);
  EXPECT_CONFIG_ERROR(e[0], 1, 9, "output", "expected a mapping, got a list");
  EXPECT_CONFIG_ERROR(e[1], 6, 17, "devices[0].detectors[0].params", "expected a mapping, got a list");
  EXPECT_CONFIG_ERROR(e[2], 7, 13, "localizers", "expected a list of localizers, got 'tri'");
}

TEST_F(ConfigTest, DevicesMustBeAList) {
  const auto e = errors("devices:\n  id: A\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 2, 3, "devices", "expected a list of devices, got a mapping");
}

TEST_F(ConfigTest, UnknownKeySuggestsTheClosest) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: onset
        params:
          treshold_db: -30
)");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 6, 11, "devices[0].detectors[0].params.treshold_db",
                      "unknown key 'treshold_db'; did you mean 'threshold_db'? (known keys: threshold_db, window_s, "
                      "mode, enabled, order, gains)");
}

TEST_F(ConfigTest, UnknownTopLevelKey) {
  const auto e = errors("devices:\n  - id: A\nlog_levl: debug\nfoo: 1\n");
  ASSERT_EQ(e.size(), 2u);
  const std::string known = "(known keys: sample_rate_hz, log_level, plugin_dirs, output, link, outputs, devices, localizers)";
  EXPECT_CONFIG_ERROR(e[0], 3, 1, "log_levl", "unknown key 'log_levl'; did you mean 'log_level'? " + known);
  EXPECT_CONFIG_ERROR(e[1], 4, 1, "foo", "unknown key 'foo' " + known);
}

TEST_F(ConfigTest, MissingRequiredKey) {
  const auto e = errors(R"(devices:
  - id: A
    audio:
      ring_frames: 4096
    detectors:
      - plugin: xcorr
  - audio: {source: synth}
)");
  ASSERT_EQ(e.size(), 3u);
  EXPECT_CONFIG_ERROR(e[0], 4, 7, "devices[0].audio.source", "missing required key 'source'");
  EXPECT_CONFIG_ERROR(e[1], 6, 9, "devices[0].detectors[0].params.template_hz", "missing required key 'template_hz'");
  EXPECT_CONFIG_ERROR(e[2], 7, 5, "devices[1].id", "missing required key 'id'");
}

TEST_F(ConfigTest, WrongType) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: onset
        params:
          window_s: abc
          enabled: yes
          order: 1.5
          threshold_db: .nan
          mode: "0.5"
          gains: {a: 1}
)");
  ASSERT_EQ(e.size(), 6u);
  const std::string p = "devices[0].detectors[0].params.";
  EXPECT_CONFIG_ERROR(e[0], 6, 21, p + "window_s", "expected a float in [0, 1] (unit: s), got 'abc'");
  EXPECT_CONFIG_ERROR(e[1], 7, 20, p + "enabled", "expected a bool (true or false), got 'yes'");
  EXPECT_CONFIG_ERROR(e[2], 8, 18, p + "order", "expected an integer in [1, 8], got '1.5'");
  EXPECT_CONFIG_ERROR(e[3], 9, 25, p + "threshold_db",
                      "expected a float in [-60, 0] (unit: dB), got '.nan' (not a finite number)");
  EXPECT_CONFIG_ERROR(e[4], 10, 17, p + "mode", "expected one of 'fast', 'slow', got the quoted string \"0.5\"");
  EXPECT_CONFIG_ERROR(e[5], 11, 18, p + "gains", "expected a list of 1 to 4 floats in [0, 10], got a mapping");
}

TEST_F(ConfigTest, QuotedNumberIsAString) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: xcorr
        params:
          template_hz: "440"
)");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 6, 24, "devices[0].detectors[0].params.template_hz",
                      "expected a float in [1, 20000] (unit: Hz), got the quoted string \"440\"");
}

TEST_F(ConfigTest, OutOfRange) {
  const auto e = errors(R"(sample_rate_hz: 0
devices:
  - id: A
    audio:
      source: synth
      ring_frames: 1000
      params: {frequency_hz: 0.5}
    detectors:
      - plugin: onset
        params:
          order: 9
          threshold_db: 1e999
)");
  ASSERT_EQ(e.size(), 5u);
  EXPECT_CONFIG_ERROR(e[0], 1, 17, "sample_rate_hz", "expected a float in (0, 384000] (unit: Hz), got '0'");
  EXPECT_CONFIG_ERROR(e[1], 6, 20, "devices[0].audio.ring_frames", "expected an integer in [1024, 16777216], got '1000'");
  EXPECT_CONFIG_ERROR(e[2], 7, 30, "devices[0].audio.params.frequency_hz",
                      "expected a float in [1, 20000] (unit: Hz), got '0.5'");
  EXPECT_CONFIG_ERROR(e[3], 11, 18, "devices[0].detectors[0].params.order", "expected an integer in [1, 8], got '9'");
  EXPECT_CONFIG_ERROR(e[4], 12, 25, "devices[0].detectors[0].params.threshold_db",
                      "expected a float in [-60, 0] (unit: dB), got '1e999' (not a finite number)");
}

TEST_F(ConfigTest, BlockFramesAtMostHalfTheRing) {
  const auto e = errors(R"(devices:
  - id: A
    audio:
      source: synth
      ring_frames: 1024
      block_frames: 1000
)");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 6, 21, "devices[0].audio.block_frames", "expected at most half of ring_frames (512), got '1000'");
}

TEST_F(ConfigTest, NotOneOfTheChoices) {
  const auto e = errors(R"(log_level: verbose
devices:
  - id: A
    detectors:
      - plugin: onset
        params: {mode: fats}
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 1, 12, "log_level", "expected one of 'trace', 'debug', 'info', 'warn', 'error', got 'verbose'");
  EXPECT_CONFIG_ERROR(e[1], 6, 24, "devices[0].detectors[0].params.mode",
                      "expected one of 'fast', 'slow', got 'fats'; did you mean 'fast'?");
}

TEST_F(ConfigTest, ListLengthAndElements) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: onset
        params:
          gains: []
  - id: B
    detectors:
      - plugin: onset
        params:
          gains: [1, 11, x]
  - id: C
    detectors:
      - plugin: onset
        params:
          gains: [1, 2, 3, 4, 5]
)");
  ASSERT_EQ(e.size(), 4u);
  EXPECT_CONFIG_ERROR(e[0], 6, 18, "devices[0].detectors[0].params.gains",
                      "expected a list of 1 to 4 floats in [0, 10], got 0 items");
  EXPECT_CONFIG_ERROR(e[1], 11, 22, "devices[1].detectors[0].params.gains[1]", "expected a float in [0, 10], got '11'");
  EXPECT_CONFIG_ERROR(e[2], 11, 26, "devices[1].detectors[0].params.gains[2]", "expected a float in [0, 10], got 'x'");
  EXPECT_CONFIG_ERROR(e[3], 16, 18, "devices[2].detectors[0].params.gains",
                      "expected a list of 1 to 4 floats in [0, 10], got 5 items");
}

TEST_F(ConfigTest, UnknownPlugin) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: foo
      - plugin: onst
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 4, 17, "devices[0].detectors[0].plugin",
                      "unknown plugin 'foo' (registered detectors: onset, xcorr)");
  EXPECT_CONFIG_ERROR(e[1], 5, 17, "devices[0].detectors[1].plugin",
                      "unknown plugin 'onst'; did you mean 'onset'? (registered detectors: onset, xcorr)");
}

TEST_F(ConfigTest, PluginOfTheWrongKind) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: tri
localizers:
  - plugin: onset
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 4, 17, "devices[0].detectors[0].plugin", "plugin 'tri' is a localizer, not a detector");
  EXPECT_CONFIG_ERROR(e[1], 6, 13, "localizers[0].plugin", "plugin 'onset' is a detector, not a localizer");
}

TEST_F(ConfigTest, UnknownSource) {
  const auto e = errors(R"(devices:
  - id: A
    audio:
      source: synht
)");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 4, 15, "devices[0].audio.source",
                      "unknown audio source 'synht'; did you mean 'synth'? (registered: synth)");
}

TEST_F(ConfigTest, UnknownEventType) {
  const auto e = errors(R"(output:
  events: [estimate, stepp, estimate]
devices:
  - id: A
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 2, 22, "output.events[1]",
                      std::string("unknown event type 'stepp'; did you mean 'step'? (known: ") + kEventNames + ")");
  EXPECT_CONFIG_ERROR(e[1], 2, 29, "output.events[2]", "event type 'estimate' is listed twice (first at line 2)");
}

TEST_F(ConfigTest, DuplicateDeviceId) {
  const auto e = errors("devices:\n  - id: A\n  - id: B\n  - id: A\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 4, 9, "devices[2].id", "duplicate device id 'A' (first defined at line 2)");
}

TEST_F(ConfigTest, BadIdCharacters) {
  const auto e = errors(R"(devices:
  - id: a b
  - id: abcdefghijklmnopqrstuvwxyz0123456
    detectors:
      - plugin: onset
        name: on.set
)");
  ASSERT_EQ(e.size(), 3u);
  const std::string chars = "letters, digits, '_' or '-' (at most 31 characters)";
  EXPECT_CONFIG_ERROR(e[0], 2, 9, "devices[0].id", "expected a device id of " + chars + ", got 'a b'");
  EXPECT_CONFIG_ERROR(e[1], 3, 9, "devices[1].id",
                      "expected a device id of " + chars + ", got 'abcdefghijklmnopqrstuvwxyz0123456'");
  EXPECT_CONFIG_ERROR(e[2], 6, 15, "devices[1].detectors[0].name", "expected an instance name of " + chars + ", got 'on.set'");
}

TEST_F(ConfigTest, DuplicateInstanceName) {
  const auto e = errors(R"(devices:
  - id: A
    detectors:
      - plugin: onset
      - plugin: onset
      - plugin: xcorr
        name: loc
        params: {template_hz: 1000}
localizers:
  - plugin: tri
    name: loc
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 5, 9, "devices[0].detectors[1].name",
                      "duplicate instance name 'onset' (first defined at line 4); it is the default name, set 'name' "
                      "to tell them apart");
  EXPECT_CONFIG_ERROR(e[1], 11, 11, "localizers[0].name", "duplicate instance name 'loc' (first defined at line 7)");
}

TEST_F(ConfigTest, DuplicateKeyInAMapping) {
  const auto e = errors(R"(sample_rate_hz: 48000
devices:
  - id: A
    detectors:
      - plugin: onset
        params: {order: 2, order: 3}
sample_rate_hz: 44100
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 6, 28, "devices[0].detectors[0].params.order", "duplicate key 'order' (first defined at line 6)");
  EXPECT_CONFIG_ERROR(e[1], 7, 1, "sample_rate_hz", "duplicate key 'sample_rate_hz' (first defined at line 1)");
}

TEST_F(ConfigTest, NeedsADeviceOrALocalizer) {
  auto e = errors("log_level: info\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 1, 1, "devices", "expected at least one device or one localizer");
  e = errors("log_level: info\ndevices: []\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_CONFIG_ERROR(e[0], 2, 10, "devices", "expected at least one device or one localizer");
  // A localizer alone is a valid node.
  EXPECT_NO_THROW(load_config_string("localizers:\n  - plugin: tri\n", "test.yaml", registry));
}

TEST_F(ConfigTest, PluginDirectoryFailureIsLocatedAtItsEntry) {
  const auto e = errors("plugin_dirs: [/nonexistent/locus-plugins]\ndevices:\n  - id: A\n");
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].line, 1);
  EXPECT_EQ(e[0].column, 15);
  EXPECT_EQ(e[0].key, "plugin_dirs[0]");
  EXPECT_NE(e[0].message.find("/nonexistent/locus-plugins"), std::string::npos) << e[0].message;
}

// ------------------------------------------------------------------------------ all at once

TEST_F(ConfigTest, ReportsEveryErrorOfAFile) {
  try {
    load_config_string(R"(sample_rate_hz: fast
log_level: info
output:
  path: out.jsonl
  events: [estimat]
devices:
  - id: A
    audio:
      source: synth
      params: {channels: 9}
    detectors:
      - plugin: onset
        params: {threshold_db: -90, windw_s: 0.1}
  - id: A
localizers:
  - plugin: nope
)",
                       "node.yaml", registry);
    FAIL() << "accepted";
  } catch (const ConfigErrors& e) {
    const std::string expected =
        "node.yaml:1:17: sample_rate_hz: expected a float in (0, 384000] (unit: Hz), got 'fast'\n"
        "node.yaml:5:12: output.events[0]: unknown event type 'estimat'; did you mean 'estimate'? (known: " +
        std::string(kEventNames) +
        ")\n"
        "node.yaml:10:26: devices[0].audio.params.channels: expected an integer in [1, 8], got '9'\n"
        "node.yaml:13:32: devices[0].detectors[0].params.threshold_db: expected a float in [-60, 0] (unit: dB), "
        "got '-90'\n"
        "node.yaml:13:37: devices[0].detectors[0].params.windw_s: unknown key 'windw_s'; did you mean 'window_s'? "
        "(known keys: threshold_db, window_s, mode, enabled, order, gains)\n"
        "node.yaml:14:9: devices[1].id: duplicate device id 'A' (first defined at line 7)\n"
        "node.yaml:16:13: localizers[0].plugin: unknown plugin 'nope' (registered localizers: tri)";
    EXPECT_EQ(std::string(e.what()), expected);
    EXPECT_EQ(e.errors().size(), 7u);
  }
}

// ------------------------------------------------------------------------------ valid configs

TEST_F(ConfigTest, MinimalConfigGetsDefaults) {
  const Config c = load_config_string("devices:\n  - id: A\n", "min.yaml", registry);
  EXPECT_EQ(c.file, "min.yaml");
  EXPECT_DOUBLE_EQ(c.sample_rate_hz, 44100.0);
  EXPECT_EQ(c.log_level, LogLevel::Info);
  EXPECT_TRUE(c.plugin_dirs.empty());
  EXPECT_EQ(c.output.path, "-");
  EXPECT_EQ(c.output.events, (std::vector<EventType>{EventType::Estimate, EventType::AudioDetection}));
  ASSERT_EQ(c.devices.size(), 1u);
  EXPECT_EQ(c.devices[0].id, "A");
  EXPECT_FALSE(c.devices[0].audio.has_value());
  EXPECT_TRUE(c.devices[0].detectors.empty());
  EXPECT_TRUE(c.localizers.empty());
}

TEST_F(ConfigTest, FullConfigRoundTrips) {
  const Config c = load_config_string(R"(# a node with two devices
sample_rate_hz: 48000
log_level: debug
output:
  path: out.jsonl
  events: [estimate, step]
devices:
  - id: A
    audio:
      source: synth
      block_frames: 512
      params: {frequency_hz: 440}
    detectors:
      - plugin: onset
        params:
          threshold_db: -30
          gains: [0.5, 2]
          window_s: 1
      - plugin: xcorr
        name: xc
        params: {template_hz: 1000}
  - id: B-2
    detectors:
      - plugin: onset
        params:
          enabled: false
          mode: slow
          order: 0x3
localizers:
  - plugin: tri
)",
                                      "full.yaml", registry);
  EXPECT_DOUBLE_EQ(c.sample_rate_hz, 48000.0);
  EXPECT_EQ(c.log_level, LogLevel::Debug);
  EXPECT_EQ(c.output.path, "out.jsonl");
  EXPECT_EQ(c.output.events, (std::vector<EventType>{EventType::Estimate, EventType::Step}));
  ASSERT_EQ(c.devices.size(), 2u);

  const DeviceConfig& a = c.devices[0];
  EXPECT_EQ(a.id, "A");
  ASSERT_TRUE(a.audio.has_value());
  EXPECT_EQ(a.audio->source, "synth");
  EXPECT_EQ(a.audio->ring_frames, 65536u);
  EXPECT_EQ(a.audio->block_frames, 512u);
  EXPECT_DOUBLE_EQ(a.audio->params.get_float("frequency_hz"), 440.0);
  EXPECT_EQ(a.audio->params.get_int("channels"), 1);
  ASSERT_EQ(a.detectors.size(), 2u);
  EXPECT_EQ(a.detectors[0].plugin, "onset");
  EXPECT_EQ(a.detectors[0].name, "onset_A");  // onset runs on two devices
  const Params& p = a.detectors[0].params;
  EXPECT_DOUBLE_EQ(p.get_float("threshold_db"), -30.0);
  EXPECT_EQ(p.get_floats("gains"), (std::vector<double>{0.5, 2.0}));
  EXPECT_TRUE(std::holds_alternative<double>(p.values().at("window_s")));  // "1" read as a float
  EXPECT_DOUBLE_EQ(p.get_float("window_s"), 1.0);
  EXPECT_EQ(p.get_string("mode"), "fast");
  EXPECT_TRUE(p.get_bool("enabled"));
  EXPECT_EQ(p.get_int("order"), 2);
  EXPECT_EQ(a.detectors[1].name, "xc");
  EXPECT_DOUBLE_EQ(a.detectors[1].params.get_float("template_hz"), 1000.0);

  const DeviceConfig& b = c.devices[1];
  EXPECT_EQ(b.id, "B-2");
  EXPECT_FALSE(b.audio.has_value());
  ASSERT_EQ(b.detectors.size(), 1u);
  EXPECT_EQ(b.detectors[0].name, "onset_B-2");
  EXPECT_FALSE(b.detectors[0].params.get_bool("enabled"));
  EXPECT_EQ(b.detectors[0].params.get_string("mode"), "slow");
  EXPECT_EQ(b.detectors[0].params.get_int("order"), 3);
  EXPECT_DOUBLE_EQ(b.detectors[0].params.get_float("threshold_db"), -20.0);

  ASSERT_EQ(c.localizers.size(), 1u);
  EXPECT_EQ(c.localizers[0].plugin, "tri");
  EXPECT_EQ(c.localizers[0].name, "tri");
  EXPECT_DOUBLE_EQ(c.localizers[0].params.get_float("max_range_m"), 10.0);
}

TEST_F(ConfigTest, LoadsAFileAndResolvesPluginDirsNextToIt) {
  const fs::path dir = fs::temp_directory_path() / ("locus-config-test-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "plugins");
  const fs::path file = dir / "node.yaml";
  std::ofstream(file) << "plugin_dirs: [plugins]\ndevices:\n  - id: A\n";
  const Config c = load_config(file.string(), registry);
  EXPECT_EQ(c.file, file.string());
  EXPECT_EQ(c.plugin_dirs, (std::vector<std::string>{(dir / "plugins").string()}));

  std::ofstream(file) << "plugin_dirs: [plugins, missing]\ndevices:\n  - id: A\n";
  try {
    load_config(file.string(), registry);
    ADD_FAILURE() << "accepted a missing plugin directory";
  } catch (const ConfigErrors& e) {
    ASSERT_EQ(e.errors().size(), 1u);
    EXPECT_EQ(e.errors()[0].file, file.string());
    EXPECT_EQ(e.errors()[0].line, 1);
    EXPECT_EQ(e.errors()[0].column, 24);
    EXPECT_EQ(e.errors()[0].key, "plugin_dirs[1]");
    EXPECT_NE(e.errors()[0].message.find((dir / "missing").string()), std::string::npos) << e.errors()[0].message;
  }
  fs::remove_all(dir);
}

// ------------------------------------------------------------------------------ validate_params

TEST(ConfigValidateParams, ParsesKeyValueStrings) {
  std::vector<ConfigError> errors;
  const Params p = validate_params(
      *onset_schema(), {{"threshold_db", "-10"}, {"gains", "[1, 2.5]"}, {"mode", "slow"}, {"enabled", "false"}, {"order", "4"}},
      errors);
  EXPECT_TRUE(errors.empty());
  EXPECT_DOUBLE_EQ(p.get_float("threshold_db"), -10.0);
  EXPECT_EQ(p.get_floats("gains"), (std::vector<double>{1.0, 2.5}));
  EXPECT_EQ(p.get_string("mode"), "slow");
  EXPECT_FALSE(p.get_bool("enabled"));
  EXPECT_EQ(p.get_int("order"), 4);
  EXPECT_DOUBLE_EQ(p.get_float("window_s"), 0.05);  // default
  const Params q = validate_params(*onset_schema(), {{"gains", "3,4"}}, errors);
  EXPECT_TRUE(errors.empty());
  EXPECT_EQ(q.get_floats("gains"), (std::vector<double>{3.0, 4.0}));
}

TEST(ConfigValidateParams, ReportsEveryProblemByKey) {
  std::vector<ConfigError> errors;
  validate_params(*onset_schema(),
                  {{"treshold_db", "1"}, {"order", "x"}, {"gains", "1, 20"}, {"order", "3"}, {"mode", "medium"}}, errors);
  ASSERT_EQ(errors.size(), 5u);
  EXPECT_EQ(errors[0].format(), "treshold_db: unknown key 'treshold_db'; did you mean 'threshold_db'? (known keys: "
                                "threshold_db, window_s, mode, enabled, order, gains)");
  EXPECT_EQ(errors[1].format(), "order: expected an integer in [1, 8], got 'x'");
  EXPECT_EQ(errors[2].format(), "gains[1]: expected a float in [0, 10], got '20'");
  EXPECT_EQ(errors[3].format(), "order: duplicate key 'order' (given more than once)");
  EXPECT_EQ(errors[4].format(), "mode: expected one of 'fast', 'slow', got 'medium'");
  EXPECT_EQ(errors[0].line, 0);

  errors.clear();
  validate_params(*xcorr_schema(), {}, errors);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].format(), "template_hz: missing required key 'template_hz'");
}

// ------------------------------------------------------------------------------ playback, geometry, link, outputs

class NullSink : public AudioSink {
 public:
  void open(const Params&, HostContext&) override {}
  std::uint32_t channels() const override { return 1; }
  double sample_rate_hz() const override { return 44100.0; }
  void start(PlaybackScheduler&) override {}
  void stop() override {}
};

class NullOutput : public EventOutput {
 public:
  void write(const Event&) override {}
};

class ConfigSectionsTest : public ConfigTest {
 protected:
  ConfigSectionsTest() {
    registry.add_sink(SinkDescriptor{"speaker", "test sink", {int_param("period_frames", std::int64_t{256}, 16, 8192, "", "")},
                                     [] { return std::make_unique<NullSink>(); }});
    registry.add_link(LinkDescriptor{"wire", "test link", {string_param("host", std::string("localhost"), "")},
                                     [](const Params&, Logger&) -> std::unique_ptr<Link> { return nullptr; }});
    registry.add_output(OutputDescriptor{"tap", "test output", {},
                                         [](const Params&, Logger&) { return std::make_unique<NullOutput>(); }});
  }
};

TEST_F(ConfigSectionsTest, AcceptsPlaybackGeometryLinkAndOutputs) {
  const Config c = load_config_string(R"(link: {type: wire, params: {host: broker}}
outputs:
  - type: tap
    events: [estimate, step]
devices:
  - id: A
    playback: {sink: speaker, max_pending: 8, params: {period_frames: 512}}
    geometry: {mics_m: [0, 0, 0, 0.07, 0, 0], speaker_m: [0, 0.1, 0]}
)",
                                      "test.yaml", registry);
  ASSERT_TRUE(c.link);
  EXPECT_EQ(c.link->type, "wire");
  EXPECT_EQ(c.link->params.get_string("host"), "broker");
  ASSERT_EQ(c.outputs.size(), 1u);
  EXPECT_EQ(c.outputs[0].events, (std::vector<EventType>{EventType::Estimate, EventType::Step}));
  ASSERT_TRUE(c.devices[0].playback);
  EXPECT_EQ(c.devices[0].playback->sink, "speaker");
  EXPECT_EQ(c.devices[0].playback->max_pending, 8u);
  EXPECT_EQ(c.devices[0].playback->params.get_int("period_frames"), 512);
  ASSERT_TRUE(c.devices[0].geometry);
  ASSERT_EQ(c.devices[0].geometry->mics_m.size(), 2u);
  EXPECT_DOUBLE_EQ(c.devices[0].geometry->mics_m[1][0], 0.07);
  ASSERT_TRUE(c.devices[0].geometry->speaker_m);
  EXPECT_FALSE(c.devices[0].geometry->anchor_m);
}

TEST_F(ConfigSectionsTest, ReportsEveryBadSectionWithItsPlace) {
  const auto errs = errors(R"(link: {type: wir}
outputs:
  - type: tap
    events: [estimat]
devices:
  - id: A
    playback: {sink: speaker, params: {period_frames: 1}}
    geometry: {mics_m: [0, 0, 0, 1], anchor_m: [1, 2]}
)");
  ASSERT_EQ(errs.size(), 5u);
  EXPECT_EQ(errs[0].key, "link.type");
  EXPECT_NE(errs[0].message.find("unknown link 'wir'; did you mean 'wire'?"), std::string::npos) << errs[0].message;
  EXPECT_EQ(errs[1].key, "outputs[0].events[0]");
  EXPECT_EQ(errs[1].line, 4);
  EXPECT_EQ(errs[2].key, "devices[0].playback.params.period_frames");
  EXPECT_EQ(errs[2].line, 7);
  EXPECT_EQ(errs[3].key, "devices[0].geometry.mics_m");
  EXPECT_NE(errs[3].message.find("multiple of 3"), std::string::npos) << errs[3].message;
  EXPECT_EQ(errs[4].key, "devices[0].geometry.anchor_m");
}

TEST_F(ConfigSectionsTest, MissingNamesAreReported) {
  const auto errs = errors(R"(link: {params: {}}
devices:
  - id: A
    playback: {}
)");
  ASSERT_EQ(errs.size(), 2u);
  EXPECT_EQ(errs[0].message, "missing required key 'type'");
  EXPECT_EQ(errs[1].message, "missing required key 'sink'");
}

// ------------------------------------------------------------------------------ backends not built in

// A backend the build lacks (LOCUS_WITH_<X>=OFF, or AUTO and its library missing) is registered as not
// built in: a config naming it gets that reason at its file:line:column, in every section a backend
// can fill, instead of "unknown ...". Fake entries, so this runs in every build (the real ones are
// checked in tests/hal/test_optional_backends.cpp).
class NotBuiltTest : public ConfigSectionsTest {
 protected:
  NotBuiltTest() {
    registry.add_not_built({"fakejack", "FAKEJACK support was not built in (LOCUS_WITH_FAKEJACK=OFF)"});
    registry.add_not_built({"fakemqtt", "FAKEMQTT support was not built in (LOCUS_WITH_FAKEMQTT=AUTO and "
                                        "libfake not found: pkg-config module 'fake', Debian package libfake-dev)"});
  }
};

TEST_F(NotBuiltTest, EverySectionSaysTheBackendWasNotBuiltIn) {
  const auto e = errors(R"(link: {type: fakemqtt, params: {host: broker}}
outputs:
  - type: fakemqtt
devices:
  - id: A
    audio: {source: fakejack, params: {client_name: locus}}
    ble: {source: fakejack}
    playback: {sink: fakejack}
)");
  const std::string jack = "FAKEJACK support was not built in (LOCUS_WITH_FAKEJACK=OFF)";
  const std::string mqtt = "FAKEMQTT support was not built in (LOCUS_WITH_FAKEMQTT=AUTO and libfake not found: "
                           "pkg-config module 'fake', Debian package libfake-dev)";
  ASSERT_EQ(e.size(), 5u);
  EXPECT_CONFIG_ERROR(e[0], 1, 14, "link.type", "link 'fakemqtt' is not available: " + mqtt);
  EXPECT_CONFIG_ERROR(e[1], 3, 11, "outputs[0].type", "output 'fakemqtt' is not available: " + mqtt);
  EXPECT_CONFIG_ERROR(e[2], 6, 21, "devices[0].audio.source", "audio source 'fakejack' is not available: " + jack);
  EXPECT_CONFIG_ERROR(e[3], 7, 19, "devices[0].ble.source", "ble source 'fakejack' is not available: " + jack);
  EXPECT_CONFIG_ERROR(e[4], 8, 22, "devices[0].playback.sink",
                      "playback sink 'fakejack' is not available: " + jack);
  EXPECT_EQ(e[2].format(), "test.yaml:6:21: devices[0].audio.source: audio source 'fakejack' is not available: " + jack);
}

TEST_F(NotBuiltTest, OtherUnknownNamesStayUnknown) {
  // Only the names recorded as not built in get the reason; a typo still gets "did you mean".
  const auto e = errors(R"(devices:
  - id: A
    audio: {source: fakejak}
    playback: {sink: speakr}
)");
  ASSERT_EQ(e.size(), 2u);
  EXPECT_CONFIG_ERROR(e[0], 3, 21, "devices[0].audio.source",
                      "unknown audio source 'fakejak' (registered: synth)");
  EXPECT_CONFIG_ERROR(e[1], 4, 22, "devices[0].playback.sink",
                      "unknown playback sink 'speakr'; did you mean 'speaker'? (registered: speaker)");
}

// The did-you-mean distance against the textbook full-matrix recurrence on random short words over a
// small alphabet (many repeats, so transpositions and ties are exercised), and a huge unknown key
// gets no suggestion rather than a matrix of its size per candidate.
std::size_t reference_osa(const std::string& a, const std::string& b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
    for (std::size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0u : 1u)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
    }
  return d[a.size()][b.size()];
}

TEST(ConfigSuggestions, EditDistanceMatchesTheFullMatrixRecurrence) {
  std::mt19937 rng(7);
  auto word = [&] {
    std::string w(std::uniform_int_distribution<int>(0, 9)(rng), 'a');
    for (char& c : w) c = static_cast<char>('a' + std::uniform_int_distribution<int>(0, 3)(rng));
    return w;
  };
  for (int k = 0; k < 2000; ++k) {
    const std::string a = word(), b = word();
    ASSERT_EQ(config_detail::edit_distance(a, b), reference_osa(a, b)) << "'" << a << "' vs '" << b << "'";
  }
  EXPECT_EQ(config_detail::edit_distance("threshold_db", "treshold_db"), 1u);
  EXPECT_EQ(config_detail::edit_distance("fast", "fats"), 1u);
}

TEST(ConfigSuggestions, SuggestsOnlyPlausibleTyposAndNothingForAHugeKey) {
  const std::vector<std::string> keys{"threshold_db", "window_s", "log_level"};
  EXPECT_EQ(config_detail::closest("treshold_db", keys), "threshold_db");
  EXPECT_EQ(config_detail::closest("windows", keys), "window_s");
  EXPECT_EQ(config_detail::closest("colour", keys), "");
  EXPECT_EQ(config_detail::closest(std::string(100000, 'w'), keys), "");
}

}  // namespace
}  // namespace locus
