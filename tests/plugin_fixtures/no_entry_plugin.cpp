// Fixture "no_entry": a valid shared object with a detector but no locus_plugin_enum.
#include "fixture_plugins.hpp"

extern "C" __attribute__((visibility("default"))) const locus_plugin_descriptor* not_the_entry_point(std::uint32_t) {
  static constexpr locus_plugin_descriptor kLevel = fixture::detector_descriptor("fixture_no_entry");
  return &kLevel;
}
