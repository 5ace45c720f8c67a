// The optional backends (LOCUS_WITH_ALSA/JACK/BLUEZ/MQTT) in the real built-in registry
// (hal/builtin.cpp, link/links.cpp): what this build has is registered with its descriptors, what it
// lacks is registered as not built in with the sentence of locus/build_options.hpp, never both; a
// config naming a missing backend gets that sentence at its file:line:column. The expectations follow
// the build's own table, so the same tests run in the full build and in the minimal one (where they
// exercise the other branch).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "locus/build_options.hpp"
#include "locus/config.hpp"
#include "locus/registry.hpp"

namespace locus {
namespace {

/// What each optional backend registers when built: "source", "sink", "ble", "link", "output".
std::vector<std::string> registered_as(const Registry& r, std::string_view name) {
  std::vector<std::string> out;
  if (r.find_source(name) != nullptr) out.push_back("source");
  if (r.find_sink(name) != nullptr) out.push_back("sink");
  if (const SensorSourceDescriptor* s = r.find_sensor_source(name)) out.push_back(std::string(sensor_kind_name(s->kind)));
  if (r.find_link(name) != nullptr) out.push_back("link");
  if (r.find_output(name) != nullptr) out.push_back("output");
  return out;
}

TEST(OptionalBackends, BuiltOnesAreRegisteredMissingOnesSayWhy) {
  Registry r;
  register_builtins(r);
  const std::vector<std::pair<std::string, std::vector<std::string>>> expected = {
      {"alsa", {"source", "sink"}}, {"jack", {"source", "sink"}}, {"bluez", {"ble"}}, {"mqtt", {"link", "output"}}};
  std::size_t missing = 0;
  for (const auto& [name, parts] : expected) {
    const build::OptionalBackend* b = build::find_optional_backend(name);
    ASSERT_NE(b, nullptr) << name;
    if (b->built) {
      EXPECT_EQ(registered_as(r, name), parts) << name;
      EXPECT_EQ(r.find_not_built(name), nullptr) << name;
    } else {
      ++missing;
      EXPECT_TRUE(registered_as(r, name).empty()) << name;
      const NotBuiltBackend* nb = r.find_not_built(name);
      ASSERT_NE(nb, nullptr) << name;
      EXPECT_EQ(nb->reason, build::not_built_reason(*b));
      EXPECT_EQ(nb->reason.rfind(std::string(b->title) + " support was not built in (" + std::string(b->option) + "=", 0),
                0u)
          << nb->reason;
    }
  }
  EXPECT_EQ(r.not_built().size(), missing);
  // The backends that are not optional are always there.
  EXPECT_NE(r.find_source("synth"), nullptr);
  EXPECT_NE(r.find_sensor_source("iio"), nullptr);
}

TEST(OptionalBackends, ConfigNamingAMissingBackendSaysItWasNotBuiltIn) {
  Registry r;
  register_builtins(r);
  // Every optional backend in the sections it fills; nothing is opened (validation only).
  const std::string yaml = R"(link: {type: mqtt, params: {host: 127.0.0.1}}
outputs:
  - type: mqtt
    events: [estimate]
devices:
  - id: A
    audio: {source: jack, params: {channels: 1}}
    playback: {sink: alsa, params: {pcm: "null", channels: 1}}
    ble: {source: bluez}
)";
  // Where each name is in the text above, and what the error must say when it is missing.
  struct Use {
    const char* backend;
    int line, column;
    const char* key;
    const char* what;
  };
  const Use uses[] = {{"mqtt", 1, 14, "link.type", "link"},
                      {"mqtt", 3, 11, "outputs[0].type", "output"},
                      {"jack", 7, 21, "devices[0].audio.source", "audio source"},
                      {"alsa", 8, 22, "devices[0].playback.sink", "playback sink"},
                      {"bluez", 9, 19, "devices[0].ble.source", "ble source"}};
  std::vector<std::string> expected;
  for (const Use& u : uses) {
    const build::OptionalBackend* b = build::find_optional_backend(u.backend);
    if (b->built) continue;
    expected.push_back("test.yaml:" + std::to_string(u.line) + ":" + std::to_string(u.column) + ": " + u.key + ": " +
                       u.what + " '" + u.backend + "' is not available: " + build::not_built_reason(*b));
  }
  std::vector<std::string> got;
  try {
    load_config_string(yaml, "test.yaml", r);
  } catch (const ConfigErrors& e) {
    for (const ConfigError& err : e.errors()) got.push_back(err.format());
  }
  EXPECT_EQ(got, expected);  // full build: accepted; minimal build: one error per missing use
}

}  // namespace
}  // namespace locus
