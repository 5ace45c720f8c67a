// Fixture "duplicate": a fresh name followed by the name the "good" fixture already registers.
#include "fixture_plugins.hpp"

namespace {
constexpr locus_plugin_descriptor kUnique = fixture::detector_descriptor("fixture_dup_unique");
constexpr locus_plugin_descriptor kClash = fixture::detector_descriptor("fixture_level");
}  // namespace

LOCUS_PLUGIN_EXPORT(&kUnique, &kClash)
