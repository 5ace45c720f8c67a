// The MQTT link (`link: {type: mqtt, ...}`): nodes on different boards exchange link messages through
// an MQTT broker, with the same semantics as the in-process link (core/include/locus/inprocess_link.hpp):
// asynchronous delivery on a thread the link owns, MQTT wildcards, a publisher receives its own
// messages when subscribed, and after unsubscribe() returns the handler is not running and will not run.
//
// Link topic `t` travels as MQTT topic `<topic_prefix>/link/<t>`; filters map the same way, so
// several Locus deployments can share a broker under different prefixes. Reconnection, the offline
// queue and their guarantees are those of MqttConnection (mqtt_connection.hpp, docs/mqtt.md).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "auth/message_auth.hpp"
#include "locus/link.hpp"
#include "mqtt/mqtt_connection.hpp"

namespace locus::mqtt {

/// Schema of `link:` params for type mqtt: mqtt_connection_schema() plus topic_prefix and the message
/// authentication keys (auth_key_file, auth_sender, auth_window_s).
ParamSchema mqtt_link_schema();

/// The authenticator the params ask for (auth_key_file non-empty), else nullptr. `fallback_sender` names
/// this node when auth_sender is empty (the MQTT user name, else the client id, else the host name).
/// Throws linkauth::AuthError naming the key.
std::unique_ptr<linkauth::MessageAuthenticator> mqtt_link_authenticator(const Params& params,
                                                                        const MqttOptions& options);

/// Link topic <-> MQTT topic under a prefix ("locus" -> "locus/link/<topic>").
class LinkTopics {
 public:
  /// Throws MqttError when `prefix` is empty or holds '+', '#', or a leading/trailing '/'.
  explicit LinkTopics(std::string prefix);
  std::string to_mqtt(std::string_view link_topic) const;
  /// The link topic of an MQTT topic, or nullopt if it is not under the prefix.
  std::optional<std::string> from_mqtt(std::string_view mqtt_topic) const;
  const std::string& root() const noexcept { return root_; }  ///< "<prefix>/link/"

 private:
  std::string root_;
};

/// Checks a topic prefix (shared with the output). Throws MqttError naming `key`.
void check_topic_prefix(const std::string& prefix, std::string_view key, std::string_view what);

class MqttLink final : public Link {
 public:
  /// Connects (see MqttConnection); throws MqttError naming host:port and the reason.
  /// With `auth`, every message is signed on publish and verified on arrival; rejected ones are counted
  /// (auth_counts()), logged, and never reach a handler (docs/mqtt.md, "Message authentication").
  MqttLink(MqttOptions options, std::string topic_prefix, Logger& log,
           std::unique_ptr<linkauth::MessageAuthenticator> auth = nullptr);
  ~MqttLink() override;

  /// [main] Never blocks on the network. Throws std::invalid_argument for a topic with '+' or '#'.
  void publish(std::string_view topic, std::string_view payload) override;
  /// [main] Throws std::invalid_argument for an invalid filter.
  std::uint64_t subscribe(std::string_view filter, LinkHandler handler) override;
  void unsubscribe(std::uint64_t id) override;

  /// [main] Connected, every subscription acknowledged by the broker and nothing queued.
  bool wait_ready(double timeout_s) const { return conn_->wait_ready(timeout_s); }
  /// [main] Everything published so far was sent (acknowledged for qos >= 1).
  bool flush(double timeout_s) const { return conn_->flush(timeout_s); }
  MqttConnection::Stats stats() const { return conn_->stats(); }
  /// Messages handed to handlers so far.
  std::uint64_t deliveries() const;
  /// MQTT messages that arrived but matched no current subscription (e.g. just unsubscribed) or lay
  /// outside the prefix.
  std::uint64_t unmatched() const;
  /// Message authentication verdicts so far (all zero without a key).
  linkauth::AuthCounts auth_counts() const { return auth_ ? auth_->counts() : linkauth::AuthCounts{}; }
  const LinkTopics& topics() const noexcept { return topics_; }
  const MqttConnection& connection() const noexcept { return *conn_; }

 private:
  struct Subscription {
    std::uint64_t id;
    std::string filter;
    std::uint32_t broker_id;  // MqttConnection subscription id of this filter (shared by equal filters)
    std::shared_ptr<LinkHandler> handler;
  };
  void dispatch(const std::string& mqtt_topic, std::string_view payload, const std::vector<std::uint32_t>& ids);

  LinkTopics topics_;
  Logger& log_;
  mutable std::mutex mutex_;
  std::condition_variable idle_;
  std::vector<Subscription> subs_;
  std::map<std::string, std::pair<std::uint32_t, int>> filters_;  // filter -> (broker id, local refs)
  std::uint64_t next_id_ = 1;
  std::uint64_t delivering_sub_ = 0;
  std::uint64_t deliveries_ = 0;
  std::uint64_t unmatched_ = 0;
  std::unique_ptr<linkauth::MessageAuthenticator> auth_;
  std::unique_ptr<MqttConnection> conn_;  // last: destroyed first, so no callback outlives the members
};

}  // namespace locus::mqtt
