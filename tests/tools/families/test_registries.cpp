// One name per system across the registries (docs/writing-a-localizer.md): the simulator family
// (tools/sim/families/<name>.cpp), the eval metric (tools/eval/metrics/<name>.cpp) and, once the
// system has a localizer plugin of that name, config/<name>.yaml, docs/<name>.md and
// tests/scenario/<name>/.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>

#include "locus/config.hpp"
#include "locus/eval/metric.hpp"
#include "locus/registry.hpp"
#include "locus/sim/families.hpp"

namespace locus {
namespace {

namespace fs = std::filesystem;

std::set<std::string> family_names() {
  std::set<std::string> out;
  for (const sim::Family* f : sim::families()) out.insert(f->name);
  return out;
}

TEST(Registries, EverySimulatorFamilyHasAMetricOfItsName) {
  const std::set<std::string> families = family_names();
  EXPECT_EQ(families, (std::set<std::string>{"amil", "locble", "montage", "spyloc", "tum"}));
  for (const std::string& name : families) EXPECT_NE(eval::find_metric(name), nullptr) << name;
  for (const std::string& name : eval::metric_names()) {
    if (name == "position") continue;  // the generic metric, for any localizer
    EXPECT_TRUE(families.count(name)) << "metric '" << name << "' has no simulator family";
  }
}

TEST(Registries, TablesAreInNameOrderWithoutDuplicates) {
  std::vector<std::string> names;
  for (const sim::Family* f : sim::families()) names.push_back(f->name);
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
  EXPECT_EQ(std::adjacent_find(names.begin(), names.end()), names.end());
  const auto metrics = eval::metric_names();
  EXPECT_TRUE(std::is_sorted(metrics.begin(), metrics.end()));
  EXPECT_EQ(std::adjacent_find(metrics.begin(), metrics.end()), metrics.end());
  EXPECT_EQ(sim::find_family("nope"), nullptr);
  ASSERT_NE(sim::find_family("amil"), nullptr);
  EXPECT_EQ(sim::find_family("amil")->name, "amil");
}

TEST(Registries, AFamilysSimulationCarriesItsName) {
  for (const sim::Family* f : sim::families()) {
    sim::FamilyOptions o;
    const sim::Simulation s = f->make(o);
    EXPECT_EQ(s.family, f->name);
  }
}

TEST(Registries, ASystemWithALocalizerHasItsConfigDocsAndScenarioTest) {
  Registry registry;
  register_builtins(registry);
  const fs::path src = LOCUS_SOURCE_DIR;
  std::size_t with_localizer = 0;
  for (const std::string& name : family_names()) {
    const locus_plugin_descriptor* d = registry.find_plugin(name);
    if (d == nullptr || d->kind != LOCUS_PLUGIN_LOCALIZER) continue;
    ++with_localizer;
    SCOPED_TRACE(name);
    const fs::path config = src / "config" / (name + ".yaml");
    ASSERT_TRUE(fs::exists(config)) << config;
    const Config c = load_config(config.string(), registry);
    EXPECT_TRUE(std::any_of(c.localizers.begin(), c.localizers.end(), [&](const ComponentConfig& l) { return l.plugin == name; }))
        << config << " runs no `" << name << "` localizer";
    EXPECT_TRUE(fs::exists(src / "docs" / (name + ".md")));
    EXPECT_TRUE(fs::exists(src / "tests" / "scenario" / name / "CMakeLists.txt"));
    EXPECT_TRUE(fs::exists(src / "tests" / "plugins" / name / "CMakeLists.txt"));
  }
  EXPECT_GE(with_localizer, 1u);  // AMIL
}

}  // namespace
}  // namespace locus
