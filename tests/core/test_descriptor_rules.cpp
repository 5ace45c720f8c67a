// descriptor_rules: the one set of rules for plugin descriptors, built in or loaded. The wording of
// add_plugin's and load_library's errors is tested with the registry and the loader; this checks
// that every rule is enforced, in order, for built-ins too.
#include "descriptor_rules.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>

#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

const ParamSchema* throwing_schema() { throw std::runtime_error("boom"); }

locus_plugin_descriptor detector(const char* name = "onset") {
  return locus_plugin_descriptor{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, name, "1.0", "test detector",
                                 kInputAudio, &test::empty_schema, &test::make_null_detector, nullptr};
}
locus_plugin_descriptor localizer() {
  return locus_plugin_descriptor{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "tri", "1.0", "test localizer",
                                 0, &test::empty_schema, nullptr, &test::make_null_localizer};
}

DescriptorRule rule_of(const locus_plugin_descriptor& d) {
  const auto fault = descriptor_fault(&d);
  return fault ? fault->rule : DescriptorRule::NotNull;
}

TEST(DescriptorRules, SoundDescriptorsPass) {
  const auto d = detector();
  const auto l = localizer();
  EXPECT_FALSE(descriptor_fault(&d).has_value());
  EXPECT_FALSE(descriptor_fault(&l).has_value());
  ASSERT_TRUE(descriptor_fault(nullptr).has_value());
  EXPECT_EQ(descriptor_fault(nullptr)->rule, DescriptorRule::NotNull);
}

TEST(DescriptorRules, EveryFieldHasItsRule) {
  auto d = detector();
  d.abi_version = LOCUS_PLUGIN_ABI_VERSION + 1;
  d.name = nullptr;  // never read once the ABI differs
  EXPECT_EQ(rule_of(d), DescriptorRule::AbiVersion);
  d = detector(nullptr);
  EXPECT_EQ(rule_of(d), DescriptorRule::NameNotNull);
  d = detector("Onset");
  EXPECT_EQ(rule_of(d), DescriptorRule::NameCharacters);
  d = detector("a_very_long_plugin_name_over_31_chars");
  EXPECT_EQ(rule_of(d), DescriptorRule::NameLength);
  d = detector();
  d.version = nullptr;
  EXPECT_EQ(rule_of(d), DescriptorRule::Version);
  d = detector();
  d.description = nullptr;
  EXPECT_EQ(rule_of(d), DescriptorRule::Description);
  d = detector();
  d.kind = 9;
  EXPECT_EQ(rule_of(d), DescriptorRule::Kind);
  d = detector();
  d.schema = nullptr;
  EXPECT_EQ(rule_of(d), DescriptorRule::SchemaFunction);
  d.schema = &throwing_schema;
  EXPECT_EQ(descriptor_fault(&d)->reason, "schema() threw an exception");
}

TEST(DescriptorRules, EachKindHasExactlyItsOwnFactoryAndADetectorItsInputs) {
  auto d = detector();
  d.create_localizer = &test::make_null_localizer;
  EXPECT_EQ(descriptor_fault(&d)->reason, "a detector that also sets create_localizer");
  d = detector();
  d.inputs = 0;
  EXPECT_EQ(descriptor_fault(&d)->reason, "a detector that declares no inputs");
  d.inputs = kInputImu | 0x40u;
  EXPECT_EQ(descriptor_fault(&d)->reason, "unknown input bits " + std::to_string(kInputImu | 0x40u));
  auto l = localizer();
  l.create_detector = &test::make_null_detector;
  EXPECT_EQ(descriptor_fault(&l)->reason, "a localizer that also sets create_detector");
}

TEST(DescriptorRules, BuiltInsMeetTheLoadersRulesToo) {
  // These used to be checked only for loaded libraries.
  Registry r;
  auto d = detector();
  d.inputs = 0;
  try {
    r.add_plugin(&d);
    FAIL() << "accepted a detector without inputs";
  } catch (const PluginLoadError& e) {
    EXPECT_STREQ(e.what(), "cannot add plugin 'onset' (built-in): a detector that declares no inputs");
  }
  d = detector();
  d.description = nullptr;
  EXPECT_THROW(r.add_plugin(&d), PluginLoadError);
  EXPECT_TRUE(r.plugins().empty());
}

TEST(DescriptorRules, SchemaProblemsAreNamed) {
  ParamSpec a;
  a.key = "gain";
  a.type = ParamType::Float;
  a.default_value = 2.0;
  a.min = 0.0;
  a.max = 1.0;
  EXPECT_EQ(schema_problem(ParamSchema{a}), "parameter 'gain' has a default outside [min, max]");
  a.default_value = std::numeric_limits<double>::quiet_NaN();  // "automatic"
  EXPECT_EQ(schema_problem(ParamSchema{a}), "");
  EXPECT_EQ(schema_problem(ParamSchema{a, a}), "parameter 'gain' is declared twice");
}

}  // namespace
}  // namespace locus
