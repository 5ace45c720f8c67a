#include "map_state.hpp"

#include <array>

namespace locus::map {

namespace {

std::string str_or(const nlohmann::ordered_json& j, const char* key, const std::string& fallback = {}) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : fallback;
}

bool has_flag(const nlohmann::ordered_json& estimate, const char* flag) {
  const auto it = estimate.find("flags");
  if (it == estimate.end() || !it->is_array()) return false;
  for (const auto& f : *it) {
    if (f.is_string() && f.get<std::string>() == flag) return true;
  }
  return false;
}

}  // namespace

std::string track_key(const nlohmann::ordered_json& e) {
  return str_or(e, "plugin") + "|" + str_or(e, "reference") + "|" + str_or(e, "frame") + "|" + str_or(e, "target");
}

MapState::Device& MapState::device(const std::string& node, const std::string& id) {
  auto [it, inserted] = devices_.try_emplace(id);
  if (inserted) {
    it->second.id = id;
    it->second.node = node;
    const auto link = node_links_.find(node);
    if (link != node_links_.end()) it->second.link = link->second;
  }
  return it->second;
}

void MapState::add_device(const std::string& node, const std::string& id) { device(node, id); }

bool MapState::add_event(const std::string& node, const nlohmann::ordered_json& e) {
  if (!e.is_object()) return false;
  const auto type = e.find("type");
  if (type == e.end() || !type->is_string()) return false;
  const std::string t = type->get<std::string>();
  if (t == "estimate") {
    const auto target = e.find("target");
    if (target == e.end() || !target->is_string()) return false;
    Track& track = tracks_[track_key(e)];
    track.node = node;
    track.latest = e;
    ++track.count;
    const auto pos = e.find("position_m");
    if (!has_flag(e, "direction_only") && pos != e.end() && pos->is_array() && pos->size() >= 2 &&
        (*pos)[0].is_number() && (*pos)[1].is_number()) {
      track.trace.push_back({(*pos)[0].get<double>(), (*pos)[1].get<double>()});
      while (track.trace.size() > static_cast<std::size_t>(trace_points_)) track.trace.pop_front();
    }
    const std::string reference = str_or(e, "reference");
    if (!reference.empty()) device(node, reference);
  } else if (t == "audio_detection") {
    const std::string id = str_or(e, "device");
    if (!id.empty()) {
      Device& d = device(node, id);
      ++d.detections;
      if (const auto snr = e.find("snr_db"); snr != e.end()) d.last_snr_db = *snr;
      if (const auto ts = e.find("t_s"); ts != e.end()) d.last_detection_t_s = *ts;
    }
  }
  ++events_;
  recent_.emplace_back(node, e);
  while (recent_.size() > kRecent) recent_.pop_front();
  return true;
}

void MapState::set_link(const std::string& node, const std::string& state) {
  node_links_[node] = state;
  for (auto& [id, d] : devices_) {
    if (d.node == node) d.link = state;
  }
}

void MapState::set_health(const std::string& node, const std::vector<DeviceStats>& stats) {
  for (const DeviceStats& s : stats) {
    Device& d = device(node, s.id);
    d.frames_lost = s.frames_lost;
    d.overruns = s.overruns;
    d.xruns = s.playback_xruns;
    d.events_dropped = s.events_dropped;
    d.sensor_dropped = s.sensor_dropped;
  }
}

nlohmann::ordered_json MapState::devices_json() const {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const auto& [id, d] : devices_) {
    out.push_back({{"id", d.id},
                   {"node", d.node},
                   {"link", d.link},
                   {"frames_lost", d.frames_lost},
                   {"overruns", d.overruns},
                   {"xruns", d.xruns},
                   {"events_dropped", d.events_dropped},
                   {"sensor_dropped", d.sensor_dropped},
                   {"detections", d.detections},
                   {"last_snr_db", d.last_snr_db},
                   {"last_detection_t_s", d.last_detection_t_s}});
  }
  return out;
}

nlohmann::ordered_json MapState::snapshot() const {
  nlohmann::ordered_json tracks = nlohmann::ordered_json::array();
  for (const auto& [key, t] : tracks_) {
    nlohmann::ordered_json trace = nlohmann::ordered_json::array();
    for (const auto& p : t.trace) trace.push_back({p[0], p[1]});
    tracks.push_back({{"key", key}, {"node", t.node}, {"count", t.count}, {"estimate", t.latest}, {"trace", trace}});
  }
  nlohmann::ordered_json recent = nlohmann::ordered_json::array();
  for (const auto& [node, e] : recent_) recent.push_back({{"node", node}, {"event", e}});
  return {{"title", title_},   {"status", status_},         {"finished", finished_},
          {"events", events_}, {"devices", devices_json()}, {"tracks", tracks},
          {"recent", recent},  {"trace_points", trace_points_}};
}

}  // namespace locus::map
