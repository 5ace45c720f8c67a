// Fixture "bad_descriptor": a valid descriptor followed by one with a null name.
#include "fixture_plugins.hpp"

namespace {
constexpr locus_plugin_descriptor kFine = fixture::detector_descriptor("fixture_bad_first_ok");
constexpr locus_plugin_descriptor kNoName = fixture::detector_descriptor(nullptr);
}  // namespace

LOCUS_PLUGIN_EXPORT(&kFine, &kNoName)
