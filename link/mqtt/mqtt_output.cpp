// MqttEventOutput: events as JSON on MQTT topics, plus Home Assistant discovery for estimates.
// Topic and payload builders are free functions so the unit tests check them without a broker.
#include "mqtt/mqtt_output.hpp"

#include <unistd.h>

#include <cmath>
#include <numbers>

#include "locus/json_events.hpp"
#include "mqtt/mqtt_link.hpp"

namespace locus::mqtt {

namespace {

nlohmann::ordered_json num(double v) {
  return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
}

std::string host_name() {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0 || host[0] == '\0') return "locus";
  return host;
}

struct SubjectOf {
  std::string operator()(const Estimate& e) const { return e.target.str(); }
  template <typename T>
  std::string operator()(const T& e) const {
    return e.device.str();
  }
};

}  // namespace

ParamSchema mqtt_output_schema() {
  ParamSchema s = mqtt_connection_schema();
  s.push_back(string_param("topic_prefix", std::string("locus"),
                           "Root of the event topics: <topic_prefix>/<node>/<event_type>/<target or device>."));
  s.push_back(string_param("node", std::string(""), "Node name in topics and Home Assistant ids; empty = host name."));
  s.push_back(string_param("discovery_prefix", std::string("homeassistant"),
                           "Home Assistant MQTT discovery prefix; empty = no discovery configs."));
  s.push_back(bool_param("retain", false, "Publish event and state messages retained (the last one per topic stays)."));
  return s;
}

MqttOutputOptions mqtt_output_options_from_params(const Params& p) {
  MqttOutputOptions o;
  o.topic_prefix = p.get_string("topic_prefix");
  check_topic_prefix(o.topic_prefix, "topic_prefix", "mqtt output");
  o.node = p.get_string("node");
  if (o.node.empty()) o.node = host_name();
  if (o.node.find_first_of("/+#") != std::string::npos) {
    throw MqttError("mqtt output: node: expected one topic level (no '/', '+' or '#'), got '" + o.node + "'");
  }
  o.discovery_prefix = p.get_string("discovery_prefix");
  if (!o.discovery_prefix.empty()) check_topic_prefix(o.discovery_prefix, "discovery_prefix", "mqtt output");
  o.retain = p.get_bool("retain");
  return o;
}

std::string topic_level(std::string_view name) {
  if (name.empty()) return "_";
  std::string s(name);
  for (char& c : s) {
    if (c == '/' || c == '+' || c == '#' || static_cast<unsigned char>(c) < 0x20) c = '_';
  }
  return s;
}

std::string ha_id(std::string_view name) {
  std::string s(name);
  for (char& c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
    if (!ok) c = '_';
  }
  return s.empty() ? "_" : s;
}

std::string event_topic(const MqttOutputOptions& o, const Event& event) {
  return o.topic_prefix + "/" + topic_level(o.node) + "/" + std::string(event_type_name(type_of(event))) + "/" +
         topic_level(std::visit(SubjectOf{}, event));
}

std::string state_topic(const MqttOutputOptions& o, std::string_view target) {
  return o.topic_prefix + "/" + topic_level(o.node) + "/estimate/" + topic_level(target) + "/state";
}

std::string status_topic(const MqttOutputOptions& o) { return o.topic_prefix + "/" + topic_level(o.node) + "/status"; }

std::string unique_id(const MqttOutputOptions& o, std::string_view target) {
  return ha_id("locus_" + o.node + "_" + std::string(target));
}

std::string discovery_topic(const MqttOutputOptions& o, std::string_view target) {
  return o.discovery_prefix + "/sensor/" + unique_id(o, target) + "/config";
}

nlohmann::ordered_json estimate_state_json(const Estimate& e) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  const int dims = std::min<int>(e.dims, 3);
  j["x"] = dims >= 1 ? num(e.position_m[0]) : nullptr;
  j["y"] = dims >= 2 ? num(e.position_m[1]) : nullptr;
  if (dims >= 3) j["z"] = num(e.position_m[2]);
  double distance = e.distance_m;
  if (!std::isfinite(distance) && dims >= 1) {
    double sum = 0.0;
    for (int i = 0; i < dims; ++i) sum += e.position_m[static_cast<std::size_t>(i)] * e.position_m[static_cast<std::size_t>(i)];
    distance = std::sqrt(sum);  // NaN when a component is unknown
  }
  j["distance_m"] = num(distance);
  j["direction_deg"] = num(e.direction_rad * 180.0 / std::numbers::pi);
  j["std_m"] = num(e.std_m);
  j["confidence"] = num(e.confidence);
  j["plugin"] = e.plugin.str();
  j["reference"] = e.reference.str();
  j["frame"] = e.frame.str();
  j["target"] = e.target.str();
  j["t_s"] = num(e.t_s);
  return j;
}

nlohmann::ordered_json discovery_config_json(const MqttOutputOptions& o, std::string_view target) {
  const std::string state = state_topic(o, target);
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  j["name"] = std::string(target) + " distance";
  j["unique_id"] = unique_id(o, target);
  j["object_id"] = unique_id(o, target);
  j["state_topic"] = state;
  j["json_attributes_topic"] = state;
  j["value_template"] = "{{ value_json.distance_m }}";
  j["unit_of_measurement"] = "m";
  j["device_class"] = "distance";
  j["state_class"] = "measurement";
  j["availability_topic"] = status_topic(o);
  j["payload_available"] = "online";
  j["payload_not_available"] = "offline";
  j["device"] = {{"identifiers", nlohmann::ordered_json::array({ha_id("locus_" + o.node)})},
                 {"name", "Locus " + o.node},
                 {"manufacturer", "Locus"},
                 {"model", "locus node"}};
  return j;
}

MqttEventOutput::MqttEventOutput(MqttOptions connection, MqttOutputOptions options, Logger& log)
    : opt_(std::move(options)), log_(log), flush_timeout_s_(connection.connect_timeout_s) {
  connection.will_topic = status_topic(opt_);
  connection.will_payload = "offline";
  connection.will_retain = true;
  conn_ = std::make_unique<MqttConnection>(std::move(connection), log, "mqtt output");
  conn_->publish_sticky(status_topic(opt_), "online", true);
}

MqttEventOutput::~MqttEventOutput() {
  try {
    conn_->publish(status_topic(opt_), "offline", true);
    conn_->flush(std::min(flush_timeout_s_, 2.0));
  } catch (const std::exception& e) {
    log_.warn(std::string("mqtt output: cannot publish offline status: ") + e.what());
  }
  conn_.reset();
}

void MqttEventOutput::write(const Event& event) {
  conn_->publish(event_topic(opt_, event), event_to_json(event).dump(), opt_.retain);
  if (const auto* e = std::get_if<Estimate>(&event)) {
    const std::string target = e->target.str();
    if (!opt_.discovery_prefix.empty() && announced_.insert(target).second) {
      // Sticky: re-sent after every reconnect, so a restarted broker (or Home Assistant) learns it again.
      conn_->publish_sticky(discovery_topic(opt_, target), discovery_config_json(opt_, target).dump(), true);
    }
    conn_->publish(state_topic(opt_, target), estimate_state_json(*e).dump(), opt_.retain);
  }
}

void MqttEventOutput::flush() {
  if (!conn_->flush(flush_timeout_s_)) {
    const auto s = conn_->stats();
    log_.warn("mqtt output: not everything was sent within " + std::to_string(static_cast<int>(flush_timeout_s_)) + " s (" +
              std::to_string(s.queued) + " messages queued, " + (s.connected ? "connected" : "not connected") +
              ", " + std::to_string(s.dropped) + " dropped in total)");
  }
}

}  // namespace locus::mqtt
