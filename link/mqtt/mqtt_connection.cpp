// libmosquitto behind MqttConnection: own loop thread, reconnect with backoff, bounded offline queue,
// v5 subscription identifiers. See mqtt_connection.hpp for the why and the guarantees.
#include "mqtt/mqtt_connection.hpp"

#include <mosquitto.h>
#include <mqtt_protocol.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace locus::mqtt {

namespace {

using Clock = std::chrono::steady_clock;

std::chrono::duration<double> seconds(double s) { return std::chrono::duration<double>(s); }

std::string format_s(double s) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", s);
  return buf;
}

void init_library() {
  static std::once_flag once;
  std::call_once(once, [] { mosquitto_lib_init(); });
}

std::string check_readable(const std::string& path, std::string_view key, std::string_view what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    throw MqttError(std::string(what) + ": " + std::string(key) + ": '" + path + "' is not a readable file");
  }
  std::ifstream in(path);
  if (!in) throw MqttError(std::string(what) + ": " + std::string(key) + ": cannot open '" + path + "'");
  return path;
}

}  // namespace

ParamSchema mqtt_connection_schema() {
  return ParamSchema{
      string_param("host", std::string("127.0.0.1"), "Broker host name or address."),
      int_param("port", std::int64_t{1883}, 1, 65535, "", "Broker TCP port (8883 is usual with TLS)."),
      string_param("client_id", std::string(""), "MQTT client id; empty = locus-<hostname>-<pid>-<n>."),
      string_param("username", std::string(""), "User name; empty = anonymous."),
      string_param("password", std::string(""), "Password (needs a username)."),
      string_param("tls_ca_file", std::string(""), "CA certificate (PEM) that signed the broker's; non-empty enables TLS."),
      string_param("tls_cert_file", std::string(""), "Client certificate (PEM) for brokers that require one (with tls_key_file)."),
      string_param("tls_key_file", std::string(""), "Private key (PEM, unencrypted) of tls_cert_file."),
      bool_param("tls_insecure", false, "Do not check the broker's host name against its certificate (testing only)."),
      int_param("qos", std::int64_t{1}, 0, 2, "", "MQTT QoS of publications and subscriptions (1 = at least once)."),
      int_param("keepalive_s", std::int64_t{30}, 5, 3600, "s", "Keep-alive interval; a dead broker is noticed within 1.5x it."),
      float_param("reconnect_min_s", 0.5, 0.01, 3600.0, "s", "First delay before reconnecting; doubles per failed attempt."),
      float_param("reconnect_max_s", 30.0, 0.01, 3600.0, "s", "Longest delay between reconnect attempts."),
      float_param("connect_timeout_s", 10.0, 0.1, 3600.0, "s",
                  "How long construction waits for the broker's CONNACK (also the per-attempt limit)."),
      int_param("queue_limit", std::int64_t{10000}, 1, 10000000, "",
                "Messages kept while disconnected; beyond it the oldest is dropped (counted)."),
  };
}

MqttOptions mqtt_options_from_params(const Params& p, std::string_view what) {
  MqttOptions o;
  const std::string w(what);
  o.host = p.get_string("host");
  if (o.host.empty()) throw MqttError(w + ": host: expected a host name or address, got ''");
  o.port = static_cast<int>(p.get_int("port"));
  o.client_id = p.get_string("client_id");
  if (o.client_id.size() > 65535) throw MqttError(w + ": client_id: longer than 65535 bytes");
  o.username = p.get_string("username");
  o.password = p.get_string("password");
  if (!o.password.empty() && o.username.empty()) {
    throw MqttError(w + ": password: a password needs a username (set 'username')");
  }
  o.tls_ca_file = p.get_string("tls_ca_file");
  o.tls_cert_file = p.get_string("tls_cert_file");
  o.tls_key_file = p.get_string("tls_key_file");
  o.tls_insecure = p.get_bool("tls_insecure");
  if (o.tls_ca_file.empty()) {
    if (!o.tls_cert_file.empty() || !o.tls_key_file.empty() || o.tls_insecure) {
      throw MqttError(w + ": tls_ca_file: TLS options (tls_cert_file, tls_key_file, tls_insecure) need tls_ca_file");
    }
  } else {
    check_readable(o.tls_ca_file, "tls_ca_file", what);
    if (o.tls_cert_file.empty() != o.tls_key_file.empty()) {
      throw MqttError(w + ": " + (o.tls_cert_file.empty() ? "tls_cert_file" : "tls_key_file") +
                      ": a client certificate needs both tls_cert_file and tls_key_file");
    }
    if (!o.tls_cert_file.empty()) {
      check_readable(o.tls_cert_file, "tls_cert_file", what);
      check_readable(o.tls_key_file, "tls_key_file", what);
    }
  }
  o.qos = static_cast<int>(p.get_int("qos"));
  o.keepalive_s = static_cast<int>(p.get_int("keepalive_s"));
  o.reconnect_min_s = p.get_float("reconnect_min_s");
  o.reconnect_max_s = p.get_float("reconnect_max_s");
  if (o.reconnect_min_s > o.reconnect_max_s) {
    throw MqttError(w + ": reconnect_min_s: must not exceed reconnect_max_s (" + format_s(o.reconnect_min_s) + " > " +
                    format_s(o.reconnect_max_s) + ")");
  }
  o.connect_timeout_s = p.get_float("connect_timeout_s");
  o.queue_limit = static_cast<std::size_t>(p.get_int("queue_limit"));
  return o;
}

std::string generated_client_id() {
  static std::atomic<unsigned> counter{0};
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0 || host[0] == '\0') std::strcpy(host, "host");
  std::string h(host);
  for (char& c : h) {
    if (c == '+' || c == '#' || c == '/' || static_cast<unsigned char>(c) < 0x20) c = '_';
  }
  return "locus-" + h + "-" + std::to_string(getpid()) + "-" + std::to_string(++counter);
}

// ------------------------------------------------------------------------------------------ connection

MqttConnection::MqttConnection(MqttOptions options, Logger& log, std::string what, MessageFn on_message)
    : opt_(std::move(options)), log_(log), what_(std::move(what)), on_message_(std::move(on_message)) {
  init_library();
  client_id_ = opt_.client_id.empty() ? generated_client_id() : opt_.client_id;
  mosq_ = mosquitto_new(client_id_.c_str(), true, this);
  if (!mosq_) throw MqttError(what_ + ": cannot create an MQTT client: " + std::strerror(errno));
  auto fail = [&](const std::string& msg) {
    mosquitto_destroy(mosq_);
    mosq_ = nullptr;
    throw MqttError(what_ + ": " + msg);
  };
  mosquitto_int_option(mosq_, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V5);
  mosquitto_threaded_set(mosq_, true);  // other threads publish while ours runs mosquitto_loop()
  mosquitto_connect_v5_callback_set(mosq_, &MqttConnection::on_connect_cb);
  mosquitto_disconnect_v5_callback_set(mosq_, &MqttConnection::on_disconnect_cb);
  mosquitto_publish_v5_callback_set(mosq_, &MqttConnection::on_publish_cb);
  mosquitto_message_v5_callback_set(mosq_, &MqttConnection::on_message_cb);
  mosquitto_subscribe_v5_callback_set(mosq_, &MqttConnection::on_subscribe_cb);
  mosquitto_log_callback_set(mosq_, &MqttConnection::on_log_cb);
  if (!opt_.username.empty()) {
    if (mosquitto_username_pw_set(mosq_, opt_.username.c_str(), opt_.password.empty() ? nullptr : opt_.password.c_str()) !=
        MOSQ_ERR_SUCCESS) {
      fail("username: not valid UTF-8");
    }
  }
  if (!opt_.tls_ca_file.empty()) {
    const int rc = mosquitto_tls_set(mosq_, opt_.tls_ca_file.c_str(), nullptr,
                                     opt_.tls_cert_file.empty() ? nullptr : opt_.tls_cert_file.c_str(),
                                     opt_.tls_key_file.empty() ? nullptr : opt_.tls_key_file.c_str(), nullptr);
    if (rc != MOSQ_ERR_SUCCESS) fail(std::string("TLS setup failed: ") + mosquitto_strerror(rc));
    if (opt_.tls_insecure) mosquitto_tls_insecure_set(mosq_, true);
  }
  if (!opt_.will_topic.empty()) {
    const int rc = mosquitto_will_set(mosq_, opt_.will_topic.c_str(), static_cast<int>(opt_.will_payload.size()),
                                      opt_.will_payload.data(), opt_.qos, opt_.will_retain);
    if (rc != MOSQ_ERR_SUCCESS) fail("last will '" + opt_.will_topic + "': " + mosquitto_strerror(rc));
  }

  thread_ = std::thread([this] { run(); });

  // Wait for the first CONNACK (or a refusal, or the timeout).
  std::unique_lock lock(mutex_);
  const bool done = changed_.wait_for(lock, seconds(opt_.connect_timeout_s), [&] { return online_ || refused_; });
  if (online_) return;
  std::string reason = refused_ ? last_error_
                                : "no connection within connect_timeout_s = " + format_s(opt_.connect_timeout_s) +
                                      " s" + (last_error_.empty() ? std::string() : " (last error: " + last_error_ + ")");
  (void)done;
  lock.unlock();
  stop_thread();
  mosquitto_destroy(mosq_);
  mosq_ = nullptr;
  throw MqttError(what_ + ": cannot connect to MQTT broker " + endpoint() + ": " + reason);
}

MqttConnection::~MqttConnection() {
  stop_thread();
  if (mosq_) mosquitto_destroy(mosq_);
}

std::string MqttConnection::endpoint() const { return opt_.host + ":" + std::to_string(opt_.port); }

bool MqttConnection::on_connection_thread() const noexcept { return thread_id_.load() == std::this_thread::get_id(); }

void MqttConnection::stop_thread() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::string MqttConnection::describe_error(int rc, int err) const {
  std::string s;
  if (rc == MOSQ_ERR_ERRNO) {
    s = std::strerror(err);
  } else {
    s = mosquitto_strerror(rc);
  }
  std::lock_guard lock(mutex_);
  if ((rc == MOSQ_ERR_TLS || rc == MOSQ_ERR_ERRNO || rc == MOSQ_ERR_CONN_LOST) && !last_lib_error_.empty()) {
    s += " (" + last_lib_error_ + ")";
  }
  return s;
}

void MqttConnection::run() {
  thread_id_ = std::this_thread::get_id();
  bool first = true;
  bool have_socket = false;
  double backoff_s = opt_.reconnect_min_s;
  Clock::time_point next_attempt = Clock::now();
  Clock::time_point attempt_start{};
  bool awaiting_connack = false;

  auto schedule_retry = [&](const std::string& why) {
    connection_lost(why);
    have_socket = false;
    awaiting_connack = false;
    next_attempt = Clock::now() + std::chrono::duration_cast<Clock::duration>(seconds(backoff_s));
    backoff_s = std::min(backoff_s * 2.0, opt_.reconnect_max_s);
  };

  for (;;) {
    {
      std::unique_lock lock(mutex_);
      if (stopping_) break;
      if (!have_socket && Clock::now() < next_attempt) {
        changed_.wait_until(lock, next_attempt, [&] { return stopping_; });
        continue;
      }
    }
    if (!have_socket) {
      {
        std::lock_guard lock(mutex_);
        last_lib_error_.clear();
      }
      errno = 0;
      const int rc = first ? mosquitto_connect_bind_async(mosq_, opt_.host.c_str(), opt_.port, opt_.keepalive_s, nullptr)
                           : mosquitto_reconnect_async(mosq_);
      const int err = errno;
      first = false;  // connect_async stored host, port and keepalive even if the attempt failed
      if (rc != MOSQ_ERR_SUCCESS) {
        schedule_retry(rc == MOSQ_ERR_EAI ? "cannot resolve host '" + opt_.host + "'" : describe_error(rc, err));
        continue;
      }
      have_socket = true;
      awaiting_connack = true;
      attempt_start = Clock::now();
    }

    errno = 0;
    const int rc = mosquitto_loop(mosq_, 100, 1);
    const int err = errno;
    bool connack = false;
    {
      std::lock_guard lock(mutex_);
      connack = connack_ok_;
      connack_ok_ = false;
    }
    if (connack) {
      awaiting_connack = false;
      backoff_s = opt_.reconnect_min_s;
      after_connack();
    }
    if (rc != MOSQ_ERR_SUCCESS) {
      std::string why;
      {
        std::lock_guard lock(mutex_);
        if (refused_ && awaiting_connack) why = last_error_;
      }
      if (why.empty()) why = describe_error(rc, err);
      schedule_retry(why);
      continue;
    }
    if (awaiting_connack && Clock::now() - attempt_start > seconds(opt_.connect_timeout_s)) {
      schedule_retry("no CONNACK within " + format_s(opt_.connect_timeout_s) + " s");
      continue;
    }
  }

  // Shutdown: say goodbye (the broker then does not publish the last will) and let the DISCONNECT out.
  bool was_online = false;
  {
    std::lock_guard lock(mutex_);
    was_online = online_;
    online_ = false;
  }
  if (was_online) {
    std::lock_guard send_lock(send_mutex_);
    mosquitto_disconnect(mosq_);
  }
  if (have_socket) {
    const auto until = Clock::now() + std::chrono::seconds(1);
    while (Clock::now() < until && mosquitto_loop(mosq_, 50, 1) == MOSQ_ERR_SUCCESS) {
    }
  }
}

void MqttConnection::after_connack() {
  std::lock_guard send_lock(send_mutex_);
  std::map<std::uint32_t, std::string> subs;
  std::deque<Outgoing> backlog;
  std::vector<Outgoing> sticky;
  {
    std::lock_guard lock(mutex_);
    subs = subs_;
    pending_subacks_.clear();
    early_subacks_.clear();
    early_acks_.clear();
    sticky = sticky_;
    backlog.swap(queue_);
  }
  for (const auto& [id, filter] : subs) send_subscribe_locked(id, filter);
  for (const auto& m : sticky) send_locked(m);
  std::size_t sent = 0;
  while (!backlog.empty()) {
    if (!send_locked(backlog.front())) break;
    backlog.pop_front();
    ++sent;
  }
  std::uint64_t connects = 0;
  {
    std::lock_guard lock(mutex_);
    if (backlog.empty()) {
      online_ = true;
    } else {
      // Lost again while flushing: keep the rest in front of anything queued meanwhile.
      for (auto it = backlog.rbegin(); it != backlog.rend(); ++it) queue_.push_front(std::move(*it));
    }
    stats_.connected = online_;
    connects = ++stats_.connects;
  }
  changed_.notify_all();
  if (connects == 1) {
    log_.info(what_ + ": connected to " + endpoint() + " as '" + client_id_ + "'");
  } else {
    log_.info(what_ + ": reconnected to " + endpoint() + " (" + std::to_string(subs.size()) + " subscriptions renewed, " +
              std::to_string(sent) + " queued messages sent)");
  }
}

void MqttConnection::connection_lost(const std::string& why) {
  bool was_online = false;
  std::uint64_t lost = 0;
  {
    std::lock_guard lock(mutex_);
    was_online = online_ || stats_.connected;
    online_ = false;
    stats_.connected = false;
    last_error_ = why;
    // qos 0 messages not yet written are gone with the connection; qos >= 1 ones libmosquitto re-sends.
    for (auto it = inflight_.begin(); it != inflight_.end();) {
      if (it->second == 0) {
        it = inflight_.erase(it);
        ++lost;
      } else {
        ++it;
      }
    }
    stats_.dropped += lost;
    pending_subacks_.clear();
  }
  changed_.notify_all();
  if (was_online) {
    log_.warn(what_ + ": connection to " + endpoint() + " lost: " + why + "; reconnecting" +
              (lost ? " (" + std::to_string(lost) + " qos 0 messages lost)" : std::string()));
  } else {
    log_.debug(what_ + ": connecting to " + endpoint() + " failed: " + why);
  }
}

bool MqttConnection::send_locked(const Outgoing& m) {
  int mid = 0;
  const int rc = mosquitto_publish_v5(mosq_, &mid, m.topic.c_str(), static_cast<int>(m.payload.size()),
                                      m.payload.data(), opt_.qos, m.retain, nullptr);
  std::lock_guard lock(mutex_);
  if (rc == MOSQ_ERR_SUCCESS || rc == MOSQ_ERR_ERRNO || rc == MOSQ_ERR_CONN_LOST) {
    // Handed to libmosquitto (an error writing means the connection is breaking: qos >= 1 is re-sent
    // after the reconnect, qos 0 is counted lost in connection_lost()).
    if (auto early = early_acks_.find(mid); early != early_acks_.end()) {
      ++(early->second >= 0x80 ? stats_.dropped : stats_.sent);
      early_acks_.erase(early);
      changed_.notify_all();
    } else {
      inflight_[mid] = opt_.qos;
    }
    return true;
  }
  if (rc == MOSQ_ERR_NO_CONN) return false;
  ++stats_.dropped;
  log_.warn(what_ + ": cannot publish to '" + m.topic + "': " + mosquitto_strerror(rc));
  return true;
}

void MqttConnection::send_subscribe_locked(std::uint32_t id, const std::string& filter) {
  mosquitto_property* props = nullptr;
  mosquitto_property_add_varint(&props, MQTT_PROP_SUBSCRIPTION_IDENTIFIER, id);
  int mid = 0;
  const int rc = mosquitto_subscribe_v5(mosq_, &mid, filter.c_str(), opt_.qos, 0, props);
  mosquitto_property_free_all(&props);
  if (rc == MOSQ_ERR_SUCCESS) {
    int refused_code = 0;
    {
      std::lock_guard lock(mutex_);
      if (auto early = early_subacks_.find(mid); early != early_subacks_.end()) {
        refused_code = early->second >= 0x80 ? early->second : 0;
        early_subacks_.erase(early);
        changed_.notify_all();
      } else {
        pending_subacks_[mid] = id;
      }
    }
    if (refused_code) {
      log_.error(what_ + ": the broker refused the subscription '" + filter + "': " + mosquitto_reason_string(refused_code));
    }
  } else if (rc != MOSQ_ERR_NO_CONN) {
    log_.warn(what_ + ": cannot subscribe to '" + filter + "': " + mosquitto_strerror(rc));
  }
}

void MqttConnection::enqueue_locked(Outgoing m) {
  if (queue_.size() >= opt_.queue_limit) {
    queue_.pop_front();
    ++stats_.dropped;
  }
  queue_.push_back(std::move(m));
}

void MqttConnection::publish(std::string_view topic, std::string_view payload, bool retain) {
  Outgoing m{std::string(topic), std::string(payload), retain};
  if (m.topic.empty() || mosquitto_pub_topic_check(m.topic.c_str()) != MOSQ_ERR_SUCCESS ||
      mosquitto_validate_utf8(m.topic.c_str(), static_cast<int>(m.topic.size())) != MOSQ_ERR_SUCCESS) {
    throw std::invalid_argument(what_ + ": cannot publish to topic '" + m.topic +
                                "': expected a non-empty UTF-8 topic without '+' or '#'");
  }
  std::lock_guard send_lock(send_mutex_);
  bool online = false;
  {
    std::lock_guard lock(mutex_);
    ++stats_.published;
    online = online_;
    if (!online) enqueue_locked(std::move(m));
  }
  if (online && !send_locked(m)) {
    std::lock_guard lock(mutex_);
    enqueue_locked(std::move(m));
  }
}

void MqttConnection::publish_sticky(std::string_view topic, std::string_view payload, bool retain) {
  publish(topic, payload, retain);  // validates the topic
  std::lock_guard lock(mutex_);
  sticky_.push_back(Outgoing{std::string(topic), std::string(payload), retain});
}

std::uint32_t MqttConnection::subscribe(std::string_view filter) {
  const std::string f(filter);
  if (f.empty() || mosquitto_sub_topic_check(f.c_str()) != MOSQ_ERR_SUCCESS ||
      mosquitto_validate_utf8(f.c_str(), static_cast<int>(f.size())) != MOSQ_ERR_SUCCESS) {
    throw std::invalid_argument(what_ + ": invalid topic filter '" + f +
                                "': '+' and '#' must fill a whole level and '#' must be the last");
  }
  std::lock_guard send_lock(send_mutex_);
  std::uint32_t id = 0;
  bool online = false;
  {
    std::lock_guard lock(mutex_);
    id = next_sub_id_++;
    if (next_sub_id_ > 268435455u) next_sub_id_ = 1;  // MQTT's largest subscription identifier
    subs_[id] = f;
    online = online_;
  }
  if (online) send_subscribe_locked(id, f);
  return id;
}

void MqttConnection::unsubscribe(std::uint32_t id) {
  std::lock_guard send_lock(send_mutex_);
  std::string filter;
  bool online = false;
  {
    std::lock_guard lock(mutex_);
    auto it = subs_.find(id);
    if (it == subs_.end()) return;
    filter = it->second;
    subs_.erase(it);
    online = online_;
    // Another subscription id may hold the same filter: then the broker keeps it (under that id).
    for (const auto& [other, f] : subs_) {
      if (f == filter) return;
    }
  }
  if (online) mosquitto_unsubscribe_v5(mosq_, nullptr, filter.c_str(), nullptr);
}

bool MqttConnection::wait_ready(double timeout_s) const {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, seconds(timeout_s),
                           [&] { return online_ && pending_subacks_.empty() && queue_.empty(); });
}

bool MqttConnection::flush(double timeout_s) const {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, seconds(timeout_s), [&] { return online_ && queue_.empty() && inflight_.empty(); });
}

MqttConnection::Stats MqttConnection::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = stats_;
  s.queued = queue_.size();
  s.connected = online_;
  return s;
}

// ------------------------------------------------------------------------------------------- callbacks

void MqttConnection::on_connect_cb(struct mosquitto*, void* self_ptr, int rc, int, const mqtt5__property*) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  {
    std::lock_guard lock(self->mutex_);
    if (rc == 0) {
      self->connack_ok_ = true;
      self->refused_ = false;
    } else {
      self->refused_ = true;
      self->last_error_ = "the broker refused the connection: " + std::string(mosquitto_reason_string(rc)) +
                          " (CONNACK reason code " + std::to_string(rc) + ")";
      if (rc == MQTT_RC_BAD_USERNAME_OR_PASSWORD || rc == MQTT_RC_NOT_AUTHORIZED || rc == 4 || rc == 5) {
        self->last_error_ += self->opt_.username.empty() ? "; the broker may require a username and password"
                                                         : "; check username '" + self->opt_.username + "' and its password";
      }
    }
  }
  self->changed_.notify_all();
}

void MqttConnection::on_disconnect_cb(struct mosquitto*, void* self_ptr, int rc, const mqtt5__property*) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  // The loop reports the loss (connection_lost); a publish() racing with it gets MOSQ_ERR_NO_CONN and queues.
  std::lock_guard lock(self->mutex_);
  if (rc >= MQTT_RC_UNSPECIFIED && rc < 256) {
    // A v5 DISCONNECT from the broker carries a reason (e.g. session taken over).
    self->last_lib_error_ = std::string("broker sent DISCONNECT: ") + mosquitto_reason_string(rc);
  }
}

void MqttConnection::on_publish_cb(struct mosquitto*, void* self_ptr, int mid, int reason, const mqtt5__property*) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  bool refused = false;
  {
    std::lock_guard lock(self->mutex_);
    refused = reason >= 0x80;
    if (self->inflight_.erase(mid) == 0) {
      self->early_acks_[mid] = reason;  // counted when send_locked() records the mid
    } else if (refused) {
      ++self->stats_.dropped;
    } else {
      ++self->stats_.sent;
    }
  }
  self->changed_.notify_all();
  if (refused) self->log_.warn(self->what_ + ": the broker refused a publication: " + mosquitto_reason_string(reason));
}

void MqttConnection::on_message_cb(struct mosquitto*, void* self_ptr, const struct mosquitto_message* msg,
                                   const mqtt5__property* props) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  std::vector<std::uint32_t> ids;
  const mosquitto_property* p = props;
  bool skip_first = false;
  std::uint32_t value = 0;
  while ((p = mosquitto_property_read_varint(p, MQTT_PROP_SUBSCRIPTION_IDENTIFIER, &value, skip_first)) != nullptr) {
    ids.push_back(value);
    skip_first = true;
  }
  {
    std::lock_guard lock(self->mutex_);
    ++self->stats_.received;
  }
  if (!self->on_message_) return;
  const std::string topic(msg->topic ? msg->topic : "");
  std::string_view payload(static_cast<const char*>(msg->payload), msg->payload ? static_cast<std::size_t>(msg->payloadlen) : 0);
  self->on_message_(topic, payload, ids);
}

void MqttConnection::on_subscribe_cb(struct mosquitto*, void* self_ptr, int mid, int count, const int* granted,
                                     const mqtt5__property*) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  std::string refused_filter;
  int code = 0;
  {
    std::lock_guard lock(self->mutex_);
    auto it = self->pending_subacks_.find(mid);
    if (it != self->pending_subacks_.end()) {
      if (count > 0 && granted[0] >= 0x80) {
        auto sub = self->subs_.find(it->second);
        refused_filter = sub != self->subs_.end() ? sub->second : "?";
        code = granted[0];
      }
      self->pending_subacks_.erase(it);
    } else {
      self->early_subacks_[mid] = count > 0 ? granted[0] : 0;  // send_subscribe_locked() has not recorded it yet
    }
  }
  self->changed_.notify_all();
  if (!refused_filter.empty()) {
    self->log_.error(self->what_ + ": the broker refused the subscription '" + refused_filter +
                     "': " + mosquitto_reason_string(code));
  }
}

void MqttConnection::on_log_cb(struct mosquitto*, void* self_ptr, int level, const char* text) {
  auto* self = static_cast<MqttConnection*>(self_ptr);
  if ((level & (MOSQ_LOG_ERR | MOSQ_LOG_WARNING)) && text) {
    std::lock_guard lock(self->mutex_);
    self->last_lib_error_ = text;
  }
}

}  // namespace locus::mqtt
