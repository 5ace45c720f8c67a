// One MQTT client connection (libmosquitto), shared by the MQTT link and the MQTT event output.
//
// Why a layer of our own over libmosquitto: both users need the same things libmosquitto leaves to the
// application, done once and tested once:
//   - construction that connects and waits for the CONNACK, and fails with a clear message naming
//     host:port and the reason (refused credentials, unreachable broker, TLS failure);
//   - reconnection with exponential backoff (reconnect_min_s .. reconnect_max_s) on a thread we own
//     (mosquitto_loop() on it), re-sending every subscription after each reconnect (clean sessions:
//     a restarted broker knows nothing of us);
//   - a bounded queue for messages published while disconnected, sent in order after the reconnect
//     (oldest dropped beyond queue_limit, counted), so a slow or absent broker never blocks a caller;
//   - MQTT v5 subscription identifiers, so a message matching several overlapping filters of one
//     client is attributed to exactly the filters that matched (no duplicate or missed dispatch,
//     whatever the broker's duplicate-delivery policy).
//
// Delivery guarantees (docs/mqtt.md): a publish() accepted while connected is handed to libmosquitto
// at once; with qos >= 1 libmosquitto re-sends it after a reconnect until the broker acknowledges it
// (at least once). A publish() while disconnected waits in our queue and is sent after the reconnect.
// With qos 0, a message written to a connection that then breaks before it left the socket is lost and
// counted in dropped. Like any MQTT clean session, a message reaches only clients subscribed at the
// broker when it arrives there.
//
// Threads: publish/subscribe/unsubscribe/stats are [main] and thread-safe; they never wait for the
// network. The message callback runs on the connection's own thread.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "locus/host.hpp"
#include "locus/params.hpp"

struct mosquitto;
struct mosquitto_message;
struct mqtt5__property;

namespace locus::mqtt {

/// A bad MQTT parameter combination or a connection that could not be made. what() names the
/// parameter or host:port and the reason.
class MqttError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Connection parameters (the keys of mqtt_connection_schema()).
struct MqttOptions {
  std::string host = "127.0.0.1";
  int port = 1883;
  std::string client_id;  ///< "" = generated: locus-<hostname>-<pid>-<n>
  std::string username;   ///< "" = anonymous
  std::string password;
  std::string tls_ca_file;    ///< "" = no TLS
  std::string tls_cert_file;  ///< client certificate (with tls_key_file), optional
  std::string tls_key_file;
  bool tls_insecure = false;  ///< skip the broker host name check (the chain is still verified)
  int qos = 1;
  int keepalive_s = 30;
  double reconnect_min_s = 0.5;
  double reconnect_max_s = 30.0;
  double connect_timeout_s = 10.0;
  std::size_t queue_limit = 10000;  ///< messages held while disconnected

  /// Optional last will (the broker publishes it when the connection drops without a DISCONNECT).
  std::string will_topic;
  std::string will_payload;
  bool will_retain = false;
};

/// The schema entries shared by the link and the output (host, port, credentials, TLS, timing).
ParamSchema mqtt_connection_schema();
/// Reads the shared keys from validated params and checks what a schema cannot (password without a
/// username, a TLS file that does not exist, reconnect_min_s > reconnect_max_s, ...). Throws MqttError
/// naming the key. `what` prefixes messages ("mqtt link", "mqtt output").
MqttOptions mqtt_options_from_params(const Params& params, std::string_view what);
/// "locus-<hostname>-<pid>-<n>", n counting up per process (two clients of one process never share an id).
std::string generated_client_id();

class MqttConnection {
 public:
  /// [link thread] A message arrived; `subscription_ids` are the ids (from subscribe()) of the filters it
  /// matched, empty if the broker sent none.
  using MessageFn =
      std::function<void(const std::string& topic, std::string_view payload, const std::vector<std::uint32_t>& subscription_ids)>;

  struct Stats {
    std::uint64_t published = 0;  ///< accepted by publish()
    std::uint64_t sent = 0;       ///< acknowledged (qos >= 1) or written to the socket (qos 0)
    std::uint64_t dropped = 0;    ///< lost: queue overflow, qos 0 on a broken connection, refused by the broker
    std::uint64_t received = 0;   ///< messages that arrived
    std::uint64_t connects = 0;   ///< successful CONNACKs (1 + reconnects)
    std::size_t queued = 0;       ///< waiting for a connection
    bool connected = false;
  };

  /// Connects and waits for the CONNACK up to connect_timeout_s. Throws MqttError naming host:port and
  /// the reason when the broker refuses (bad credentials, not authorized) or cannot be reached in time.
  /// `what` names the user in logs and errors ("mqtt link").
  MqttConnection(MqttOptions options, Logger& log, std::string what, MessageFn on_message = {});
  ~MqttConnection();
  MqttConnection(const MqttConnection&) = delete;
  MqttConnection& operator=(const MqttConnection&) = delete;

  /// [main] Sends now if connected, else queues (bounded). Never blocks on the network. Throws
  /// std::invalid_argument for a topic MQTT cannot publish to (empty, '+' or '#', not UTF-8).
  void publish(std::string_view topic, std::string_view payload, bool retain = false);
  /// [main] Like publish(), and also re-published after every reconnect (retained state that must
  /// survive a broker restart: availability, Home Assistant discovery configs).
  void publish_sticky(std::string_view topic, std::string_view payload, bool retain);
  /// [main] Subscribes `filter` (an MQTT filter; sent again after every reconnect). Returns its id,
  /// reported with every message it matches. Throws std::invalid_argument for an invalid filter.
  std::uint32_t subscribe(std::string_view filter);
  /// [main] Stops the subscription `id` at the broker (messages already received may still carry it).
  void unsubscribe(std::uint32_t id);

  /// [main] Waits until connected with every subscription acknowledged and nothing queued.
  bool wait_ready(double timeout_s) const;
  /// [main] Waits until every accepted message was sent (acknowledged for qos >= 1). False on timeout.
  bool flush(double timeout_s) const;
  Stats stats() const;
  /// True on the connection's own thread (where the message callback runs).
  bool on_connection_thread() const noexcept;
  const std::string& client_id() const noexcept { return client_id_; }
  /// "host:port" (for messages).
  std::string endpoint() const;

 private:
  struct Outgoing {
    std::string topic;
    std::string payload;
    bool retain = false;
  };

  static void on_connect_cb(struct mosquitto*, void* self, int rc, int flags, const mqtt5__property* props);
  static void on_disconnect_cb(struct mosquitto*, void* self, int rc, const mqtt5__property* props);
  static void on_publish_cb(struct mosquitto*, void* self, int mid, int reason, const mqtt5__property* props);
  static void on_message_cb(struct mosquitto*, void* self, const struct mosquitto_message* msg,
                            const mqtt5__property* props);
  static void on_subscribe_cb(struct mosquitto*, void* self, int mid, int count, const int* granted,
                              const mqtt5__property* props);
  static void on_log_cb(struct mosquitto*, void* self, int level, const char* text);

  void run();
  void after_connack();                        // [link thread] re-subscribe, send queue, go online
  void connection_lost(const std::string& why);  // [link thread]
  void stop_thread();
  /// Sends one message through libmosquitto; false if it has to wait for a reconnect. Caller holds send_mutex_.
  bool send_locked(const Outgoing& message);
  void send_subscribe_locked(std::uint32_t id, const std::string& filter);
  void enqueue_locked(Outgoing message);  // caller holds mutex_
  std::string describe_error(int rc, int err) const;

  MqttOptions opt_;
  Logger& log_;
  std::string what_;
  std::string client_id_;
  MessageFn on_message_;
  struct mosquitto* mosq_ = nullptr;

  // send_mutex_ orders every call into libmosquitto that sends (publish/subscribe) against the queue
  // flush after a reconnect; it is never taken inside a libmosquitto callback. mutex_ guards the state
  // below and is never held while calling libmosquitto.
  mutable std::mutex send_mutex_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  bool stopping_ = false;
  bool online_ = false;          // CONNACK ok, subscriptions re-sent, queue flushed: publish directly
  bool connack_ok_ = false;      // set by the CONNACK callback, consumed by the loop
  bool refused_ = false;         // the broker refused the CONNECT (credentials, authorization)
  std::string last_error_;       // why the last attempt or connection failed
  std::string last_lib_error_;   // last error/warning line libmosquitto logged (TLS details)
  std::deque<Outgoing> queue_;
  std::vector<Outgoing> sticky_;
  std::map<std::uint32_t, std::string> subs_;  // subscription id -> filter
  std::uint32_t next_sub_id_ = 1;
  std::map<int, std::uint32_t> pending_subacks_;  // SUBSCRIBE mid -> subscription id
  std::map<int, int> early_subacks_;              // mid -> code: SUBACK seen before the mid was recorded
  std::map<int, int> inflight_;                   // publish mid -> qos, until on_publish
  std::map<int, int> early_acks_;                 // mid -> reason: on_publish seen before the mid was recorded
  Stats stats_;
  std::atomic<std::thread::id> thread_id_{};
  std::thread thread_;
};

}  // namespace locus::mqtt
