// Fixture "wrong_abi": a hand-built descriptor claiming plugin ABI 999.
#include "fixture_plugins.hpp"

namespace {
constexpr locus_plugin_descriptor kFuture = fixture::detector_descriptor("fixture_from_the_future", 999u);
}  // namespace

LOCUS_PLUGIN_EXPORT(&kFuture)
