// Hub mode (`locusd --hub --http ...`): the map of a whole site. No pipeline runs here; one MQTT
// client (link/mqtt's MqttConnection: reconnects, TLS, credentials, exactly as the nodes' link)
// subscribes to what every node's MQTT event output publishes (docs/mqtt.md, Topics):
//   <topic_prefix>/<node>/<event_type>/<target or device>   the event, in the JSON-lines shape
//   <topic_prefix>/<node>/status                             online / offline (retained, last will)
// and hands each event to the map as JSON (MapServer::post_json, the same path as a local pipeline's
// events after event_to_json). A node's status is its devices' link state on the page.
#include <csignal>
#include <ctime>
#include <iostream>

#include "app.hpp"
#include "locus/config.hpp"
#include "map_cli.hpp"
#include "mqtt/mqtt_connection.hpp"
#include "mqtt/mqtt_link.hpp"

namespace locus::map {

namespace {

std::vector<std::string> split_topic(const std::string& topic) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const auto slash = topic.find('/', start);
    out.push_back(topic.substr(start, slash - start));
    if (slash == std::string::npos) return out;
    start = slash + 1;
  }
}

}  // namespace

ParamSchema hub_schema() {
  ParamSchema s = mqtt::mqtt_connection_schema();
  s.push_back(string_param("topic_prefix", std::string("locus"),
                           "Root of the nodes' event topics (their MQTT output's topic_prefix)."));
  return s;
}

bool hub_available() noexcept { return true; }

int run_hub(MapServer& map, const std::vector<std::string>& hub_params, Logger& log) {
  std::vector<std::pair<std::string, std::string>> kv;
  std::vector<std::string> errors;
  for (const std::string& item : hub_params) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      errors.push_back("--hub-param: '" + item + "': expected KEY=VALUE");
      continue;
    }
    kv.emplace_back(item.substr(0, eq), item.substr(eq + 1));
  }
  std::vector<ConfigError> config_errors;
  const Params params = validate_params(hub_schema(), kv, config_errors);
  for (const ConfigError& e : config_errors) errors.push_back("--hub-param " + e.key + ": " + e.message);
  mqtt::MqttOptions options;
  std::string prefix;
  if (errors.empty()) {
    try {
      options = mqtt::mqtt_options_from_params(params, "hub");
      prefix = params.get_string("topic_prefix");
      mqtt::check_topic_prefix(prefix, "topic_prefix", "hub");
    } catch (const std::exception& e) {
      errors.push_back(e.what());
    }
  }
  for (const std::string& e : errors) std::cerr << "locusd: " << e << "\n";
  if (!errors.empty()) return 2;

  const std::size_t prefix_levels = split_topic(prefix).size();
  auto on_message = [&map, &log, prefix_levels](const std::string& topic, std::string_view payload,
                                                const std::vector<std::uint32_t>&) {
    const std::int64_t now = mono_ns();
    const std::vector<std::string> levels = split_topic(topic);
    if (levels.size() == prefix_levels + 2 && levels.back() == "status") {
      map.set_link_state(levels[prefix_levels], std::string(payload));
      return;
    }
    if (levels.size() != prefix_levels + 3) return;  // .../estimate/<target>/state and others
    const std::string& node = levels[prefix_levels];
    if (node == "link") return;  // <topic_prefix>/link/...: the localizers' own messages, not events
    nlohmann::ordered_json event = nlohmann::ordered_json::parse(payload, nullptr, /*allow_exceptions=*/false);
    if (event.is_discarded() || !event.is_object()) {
      log.debug("hub: " + topic + ": not a JSON object: ignored");
      return;
    }
    map.post_json(node, event, now);
  };
  std::unique_ptr<mqtt::MqttConnection> conn;
  try {
    conn = std::make_unique<mqtt::MqttConnection>(options, log, "hub", on_message);
    conn->subscribe(prefix + "/+/+/+");   // every node's events
    conn->subscribe(prefix + "/+/status");  // and its availability
  } catch (const std::exception& e) {
    std::cerr << "locusd: " << e.what() << "\n";
    return 1;
  }
  map.set_status("hub: " + conn->endpoint() + " " + prefix + "/#", false);
  log.info("hub: listening to " + prefix + "/+/+/+ on " + conn->endpoint());
  const sigset_t stop_signals = app::stop_signal_set();
  bool connected = true;
  for (;;) {
    timespec timeout{0, 200'000'000};
    if (sigtimedwait(&stop_signals, nullptr, &timeout) > 0) break;
    const bool now_connected = conn->stats().connected;
    if (now_connected != connected) {
      connected = now_connected;
      map.set_status(std::string("hub: ") + (connected ? "" : "disconnected from ") + conn->endpoint(), false);
    }
  }
  conn.reset();
  map.set_status("hub: stopped", true);
  return 0;
}

}  // namespace locus::map
