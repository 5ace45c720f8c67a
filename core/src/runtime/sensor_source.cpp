// Helpers of sensor_source.hpp (kind names, event times).
#include "locus/sensor_source.hpp"

namespace locus {

std::string_view sensor_kind_name(SensorKind kind) noexcept {
  switch (kind) {
    case SensorKind::Imu: return "imu";
    case SensorKind::Ble: return "ble";
    case SensorKind::Sync: return "sync";
  }
  return "unknown";
}

EventType sensor_event_type(SensorKind kind) noexcept {
  switch (kind) {
    case SensorKind::Imu: return EventType::ImuSample;
    case SensorKind::Ble: return EventType::BleAdvertisement;
    case SensorKind::Sync: return EventType::RadioSync;
  }
  return EventType::ImuSample;
}

double sensor_event_time_s(const Event& event) noexcept {
  if (const auto* s = std::get_if<ImuSample>(&event)) return s->t_s;
  if (const auto* a = std::get_if<BleAdvertisement>(&event)) return a->t_s;
  if (const auto* r = std::get_if<RadioSync>(&event)) return r->t_s;
  return kNaN;
}

bool shift_sensor_event_time(Event& event, double delta_s) noexcept {
  if (auto* s = std::get_if<ImuSample>(&event)) {
    s->t_s += delta_s;
    return true;
  }
  if (auto* a = std::get_if<BleAdvertisement>(&event)) {
    a->t_s += delta_s;
    return true;
  }
  if (auto* r = std::get_if<RadioSync>(&event)) {
    r->t_s += delta_s;
    return true;
  }
  return false;
}

}  // namespace locus
