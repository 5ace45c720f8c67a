// What the live map knows: devices with their health, and every estimated target (per localizer,
// reference, frame and target) with its latest estimate and its trace. Pure data, no threads or
// sockets, so it is unit-tested on its own (tests/tools/map); MapServer guards it with its mutex.
//
// Input is the JSON-lines shape of events (docs/events.md), whether it came from a pipeline on this
// node (core's event_to_json) or from another node over MQTT (hub mode): one code path for both.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/pipeline.hpp"

namespace locus::map {

class MapState {
 public:
  static constexpr std::size_t kRecent = 100;
  explicit MapState(int trace_points = 300) : trace_points_(trace_points < 1 ? 1 : trace_points) {}

  /// A device served by `node` (listed even before it produced anything).
  void add_device(const std::string& node, const std::string& id);
  /// Folds one event in: `estimate` updates its target's track (a position, or a bearing for
  /// `direction_only`), `audio_detection` its device's last SNR. Other types only count. Returns false
  /// (and changes nothing) for an object that is not an event: no string "type", or an estimate
  /// without a string "target".
  bool add_event(const std::string& node, const nlohmann::ordered_json& event);
  /// Link state of every device of `node` ("in-process", "mqtt", "online", "offline").
  void set_link(const std::string& node, const std::string& state);
  /// Health counters of `node`'s devices (Pipeline::live_stats()).
  void set_health(const std::string& node, const std::vector<DeviceStats>& stats);
  void set_status(std::string status, bool finished) {
    status_ = std::move(status);
    finished_ = finished;
  }
  void set_title(std::string title) { title_ = std::move(title); }

  /// The health table: one object per device (id, node, link, frames_lost, overruns, xruns,
  /// events_dropped, sensor_dropped, detections, last_snr_db, last_detection_t_s).
  nlohmann::ordered_json devices_json() const;
  /// Everything the page needs at load time: title, status, finished, devices, tracks (each with its
  /// latest estimate and trace), the last kRecent events (`recent`, oldest first), counters.
  nlohmann::ordered_json snapshot() const;

  std::size_t track_count() const noexcept { return tracks_.size(); }
  std::uint64_t events() const noexcept { return events_; }

 private:
  struct Device {
    std::string id, node, link = "unknown";
    std::uint64_t frames_lost = 0, overruns = 0, xruns = 0, events_dropped = 0, sensor_dropped = 0;
    std::uint64_t detections = 0;
    nlohmann::ordered_json last_snr_db = nullptr, last_detection_t_s = nullptr;
  };
  struct Track {
    std::string node;
    nlohmann::ordered_json latest;
    std::deque<std::array<double, 2>> trace;
    std::uint64_t count = 0;
  };
  Device& device(const std::string& node, const std::string& id);

  int trace_points_;
  std::map<std::string, Device> devices_;  // by id
  std::map<std::string, Track> tracks_;    // by plugin|reference|frame|target
  std::map<std::string, std::string> node_links_;
  std::deque<std::pair<std::string, nlohmann::ordered_json>> recent_;  // (node, event), the page's log
  std::string status_ = "starting", title_ = "Locus";
  bool finished_ = false;
  std::uint64_t events_ = 0;
};

/// "plugin|reference|frame|target" of an estimate (the identity of a track on the map).
std::string track_key(const nlohmann::ordered_json& estimate);

}  // namespace locus::map
