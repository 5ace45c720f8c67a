#include "locus/events.hpp"

#include <array>

namespace locus {

namespace {
constexpr std::array<std::string_view, kEventTypeCount> kNames = {
    "audio_detection", "imu_sample", "ble_advertisement", "radio_sync", "step", "attitude", "estimate",
    "decay_features",
};
}  // namespace

std::string_view event_type_name(EventType t) noexcept {
  const auto i = static_cast<std::size_t>(t);
  return i < kNames.size() ? kNames[i] : std::string_view("unknown");
}

bool event_type_from_name(std::string_view name, EventType& out) noexcept {
  for (std::size_t i = 0; i < kNames.size(); ++i) {
    if (kNames[i] == name) {
      out = static_cast<EventType>(i);
      return true;
    }
  }
  return false;
}

}  // namespace locus
