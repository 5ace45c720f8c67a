// The MQTT event output (`outputs: [{type: mqtt, ...}]`): a node's events published to a broker, so
// dashboards and home automation see positions live, without reading the JSON-lines file.
//
// Every event goes as the same JSON object the JSON-lines output writes (json_events.hpp) to
// `<topic_prefix>/<node>/<event_type>/<target or device>`. Estimates additionally feed Home Assistant
// (and anything that speaks its MQTT discovery): the first time a target is seen, a retained config
// `<discovery_prefix>/sensor/<unique_id>/config` declares a distance sensor whose state JSON is
// published to `<topic_prefix>/<node>/estimate/<target>/state`. Availability is
// `<topic_prefix>/<node>/status` ("online", retained; "offline" on shutdown or as the last will).
// Every topic and payload is documented in docs/mqtt.md.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "locus/event_output.hpp"
#include "mqtt/mqtt_connection.hpp"

namespace locus::mqtt {

struct MqttOutputOptions {
  std::string topic_prefix = "locus";
  std::string node;                              ///< "" = this host's name
  std::string discovery_prefix = "homeassistant";  ///< "" = no Home Assistant discovery
  bool retain = false;                           ///< retain event and state messages
};

/// Schema of an `outputs:` entry of type mqtt: mqtt_connection_schema() plus topic_prefix, node,
/// discovery_prefix, retain.
ParamSchema mqtt_output_schema();
/// Reads the output keys (not the connection ones); throws MqttError naming the key.
MqttOutputOptions mqtt_output_options_from_params(const Params& params);

/// One topic level from a name: '/', '+', '#' and control characters become '_'; "" becomes "_".
std::string topic_level(std::string_view name);
/// [a-zA-Z0-9_-] only (Home Assistant unique_id / object_id); others become '_'.
std::string ha_id(std::string_view name);
/// `<prefix>/<node>/<event_type>/<target (estimate) or device>`.
std::string event_topic(const MqttOutputOptions& o, const Event& event);
/// `<prefix>/<node>/estimate/<target>/state`.
std::string state_topic(const MqttOutputOptions& o, std::string_view target);
/// `<prefix>/<node>/status`.
std::string status_topic(const MqttOutputOptions& o);
/// "locus_<node>_<target>" through ha_id().
std::string unique_id(const MqttOutputOptions& o, std::string_view target);
/// `<discovery_prefix>/sensor/<unique_id>/config`.
std::string discovery_topic(const MqttOutputOptions& o, std::string_view target);
/// The Home Assistant state of an estimate: {x, y[, z], distance_m, direction_deg, std_m, confidence,
/// plugin, reference, frame, t_s}; unknown values are null. distance_m is the estimate's range, or the
/// norm of its position when the localizer gives no range.
nlohmann::ordered_json estimate_state_json(const Estimate& e);
/// The retained discovery config of a target's distance sensor.
nlohmann::ordered_json discovery_config_json(const MqttOutputOptions& o, std::string_view target);

class MqttEventOutput final : public EventOutput {
 public:
  /// Connects (see MqttConnection); throws MqttError naming host:port and the reason.
  MqttEventOutput(MqttOptions connection, MqttOutputOptions options, Logger& log);
  ~MqttEventOutput() override;

  /// [main] Queues the event's messages; never waits for the network.
  void write(const Event& event) override;
  /// [main] Waits (up to connect_timeout_s) until everything written was sent; logs what was not.
  void flush() override;

  MqttConnection::Stats stats() const { return conn_->stats(); }
  const MqttOutputOptions& options() const noexcept { return opt_; }

 private:
  MqttOutputOptions opt_;
  Logger& log_;
  double flush_timeout_s_;
  std::set<std::string> announced_;  // targets whose discovery config was published
  std::unique_ptr<MqttConnection> conn_;
};

}  // namespace locus::mqtt
