// Fixture "good": a valid library with one detector and one localizer.
#include "fixture_plugins.hpp"

namespace {
constexpr locus_plugin_descriptor kLevel = fixture::detector_descriptor("fixture_level");
constexpr locus_plugin_descriptor kCount = fixture::localizer_descriptor("fixture_count");
}  // namespace

LOCUS_PLUGIN_EXPORT(&kLevel, &kCount)
