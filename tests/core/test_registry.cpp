// The in-memory registry: descriptor validation, sources, lookups and factories (dlopen is tested
// with the plugin loader).
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "support/test_host.hpp"
#include "locus/registry.hpp"

namespace locus {
namespace {

const ParamSchema* bad_default_schema() {
  static const ParamSchema schema = [] {
    ParamSpec s;
    s.key = "n";
    s.type = ParamType::Int;
    s.default_value = 0.5;
    return ParamSchema{s};
  }();
  return &schema;
}
const ParamSchema* null_schema() { return nullptr; }

locus_plugin_descriptor detector_descriptor(const char* name) {
  return locus_plugin_descriptor{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, name, "1.0", "test detector",
                                 kInputAudio, &test::empty_schema, &test::make_null_detector, nullptr};
}
locus_plugin_descriptor localizer_descriptor(const char* name) {
  return locus_plugin_descriptor{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, name, "1.0", "test localizer",
                                 0, &test::empty_schema, nullptr, &test::make_null_localizer};
}

std::string add_error(Registry& r, const locus_plugin_descriptor* d, const std::string& origin = "built-in") {
  try {
    r.add_plugin(d, origin);
  } catch (const PluginLoadError& e) {
    return e.what();
  }
  return "(accepted)";
}

TEST(Registry, AddsAndFindsPlugins) {
  static const auto det = detector_descriptor("onset");
  static const auto loc = localizer_descriptor("tri");
  Registry r;
  r.add_plugin(&det);
  r.add_plugin(&loc, "/opt/plugins/libtri.so");
  EXPECT_EQ(r.find_plugin("onset"), &det);
  EXPECT_EQ(r.find_plugin("tri"), &loc);
  EXPECT_EQ(r.find_plugin("nope"), nullptr);
  ASSERT_EQ(r.plugins().size(), 2u);
  EXPECT_EQ(r.plugins()[0].origin, "built-in");
  EXPECT_EQ(r.plugins()[1].origin, "/opt/plugins/libtri.so");
}

TEST(Registry, RefusesDuplicateName) {
  static const auto a = detector_descriptor("onset");
  static const auto b = localizer_descriptor("onset");
  Registry r;
  r.add_plugin(&a);
  EXPECT_EQ(add_error(r, &b, "/p/libx.so"),
            "cannot add plugin 'onset' (/p/libx.so): the name is already registered (built-in)");
  EXPECT_EQ(r.plugins().size(), 1u);
}

TEST(Registry, RefusesAbiMismatchWithoutReadingOtherFields) {
  auto d = detector_descriptor("onset");
  d.abi_version = LOCUS_PLUGIN_ABI_VERSION + 1;
  Registry r;
  EXPECT_EQ(add_error(r, &d, "/p/libold.so"),
            "cannot add plugin (/p/libold.so): built for plugin ABI version " +
                std::to_string(LOCUS_PLUGIN_ABI_VERSION + 1) + ", this host uses version " +
                std::to_string(LOCUS_PLUGIN_ABI_VERSION) + "; rebuild the plugin against this Locus");
}

TEST(Registry, RefusesBadNames) {
  Registry r;
  auto d = detector_descriptor(nullptr);
  EXPECT_EQ(add_error(r, &d), "cannot add plugin (built-in): the descriptor has no name");
  d = detector_descriptor("Onset-2");
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'Onset-2' (built-in): invalid name (a plugin name is [a-z0-9_]+)");
  d = detector_descriptor("");
  EXPECT_EQ(add_error(r, &d), "cannot add plugin '' (built-in): invalid name (a plugin name is [a-z0-9_]+)");
  d = detector_descriptor("a_very_long_plugin_name_over_31_chars");
  EXPECT_EQ(add_error(r, &d),
            "cannot add plugin 'a_very_long_plugin_name_over_31_chars' (built-in): name longer than 31 characters");
  EXPECT_EQ(add_error(r, nullptr), "cannot add plugin (built-in): null descriptor");
  EXPECT_TRUE(r.plugins().empty());
}

TEST(Registry, RefusesBadKindAndMissingFactory) {
  Registry r;
  auto d = detector_descriptor("onset");
  d.kind = 7;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'onset' (built-in): unknown kind 7 (1 = detector, 2 = localizer)");
  d = detector_descriptor("onset");
  d.create_detector = nullptr;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'onset' (built-in): a detector without a create_detector factory");
  d = localizer_descriptor("tri");
  d.create_localizer = nullptr;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'tri' (built-in): a localizer without a create_localizer factory");
}

TEST(Registry, RefusesMissingOrBadSchema) {
  Registry r;
  auto d = detector_descriptor("onset");
  d.schema = nullptr;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'onset' (built-in): no schema function");
  d.schema = &null_schema;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'onset' (built-in): schema() returned nullptr");
  d.schema = &bad_default_schema;
  EXPECT_EQ(add_error(r, &d), "cannot add plugin 'onset' (built-in): bad schema: parameter 'n' has a default that "
                              "does not match its type (integer)");
}

TEST(Registry, CheckPluginValidatesWithoutAdding) {
  static const auto d = detector_descriptor("onset");
  Registry r;
  EXPECT_NO_THROW(r.check_plugin(&d, "x.so"));
  EXPECT_TRUE(r.plugins().empty());
  r.add_plugin(&d);
  EXPECT_THROW(r.check_plugin(&d, "x.so"), PluginLoadError);
}

TEST(Registry, CreatesInstancesOfTheRightKind) {
  static const auto det = detector_descriptor("onset");
  static const auto loc = localizer_descriptor("tri");
  Registry r;
  r.add_plugin(&det);
  r.add_plugin(&loc);
  EXPECT_NE(dynamic_cast<test::NullDetector*>(r.create_detector("onset").get()), nullptr);
  EXPECT_NE(dynamic_cast<test::NullLocalizer*>(r.create_localizer("tri").get()), nullptr);
  try {
    r.create_detector("tri");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "plugin 'tri' is a localizer, not a detector");
  }
  try {
    r.create_localizer("onset");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "plugin 'onset' is a detector, not a localizer");
  }
  try {
    r.create_detector("nope");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "unknown plugin 'nope'");
  }
}

TEST(Registry, Sources) {
  Registry r;
  r.add_source(SourceDescriptor{"null", "silence", {}, [] { return std::make_unique<test::NullSource>(); }});
  ASSERT_NE(r.find_source("null"), nullptr);
  EXPECT_EQ(r.find_source("null")->description, "silence");
  EXPECT_EQ(r.find_source("alsa"), nullptr);
  EXPECT_NE(r.create_source("null"), nullptr);
  try {
    r.create_source("alsa");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "unknown audio source 'alsa'");
  }
  try {
    r.add_source(SourceDescriptor{"null", "again", {}, [] { return std::make_unique<test::NullSource>(); }});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "audio source 'null' is already registered");
  }
  EXPECT_THROW(r.add_source(SourceDescriptor{"nofactory", "", {}, nullptr}), std::invalid_argument);
  EXPECT_EQ(r.sources().size(), 1u);
}

TEST(Registry, NotBuiltBackends) {
  // A backend the build lacks (LOCUS_WITH_<X>) is recorded with its reason; factories report it.
  Registry r;
  r.add_source(SourceDescriptor{"null", "silence", {}, [] { return std::make_unique<test::NullSource>(); }});
  r.add_not_built(NotBuiltBackend{"jack", "JACK support was not built in (LOCUS_WITH_JACK=OFF)"});
  ASSERT_NE(r.find_not_built("jack"), nullptr);
  EXPECT_EQ(r.find_not_built("jack")->reason, "JACK support was not built in (LOCUS_WITH_JACK=OFF)");
  EXPECT_EQ(r.find_not_built("null"), nullptr);
  EXPECT_EQ(r.find_not_built("alsa"), nullptr);
  EXPECT_EQ(r.find_source("jack"), nullptr);  // absent from every list of what can be created
  ASSERT_EQ(r.not_built().size(), 1u);
  EXPECT_EQ(r.not_built()[0].name, "jack");
  try {
    r.create_source("jack");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "audio source 'jack': JACK support was not built in (LOCUS_WITH_JACK=OFF)");
  }
  try {
    r.create_sensor_source("jack");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "sensor source 'jack': JACK support was not built in (LOCUS_WITH_JACK=OFF)");
  }
  try {
    r.create_source("alsa");  // neither registered nor known as not built in
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "unknown audio source 'alsa'");
  }
  const auto refused = [&](NotBuiltBackend b, const char* message) {
    try {
      r.add_not_built(std::move(b));
      ADD_FAILURE() << "accepted: " << message;
    } catch (const std::invalid_argument& e) {
      EXPECT_STREQ(e.what(), message);
    }
  };
  refused({"jack", "again"}, "backend 'jack' is already registered as not built in");
  refused({"null", "NULL support was not built in"},
          "backend 'null' cannot be both not built in and registered as an audio source");
  refused({"", "why"}, "cannot add a not-built backend without a name");
  refused({"mqtt", ""}, "not-built backend 'mqtt' has no reason");
  EXPECT_EQ(r.not_built().size(), 1u);
}

}  // namespace
}  // namespace locus
