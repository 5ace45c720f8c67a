// MqttLink: Link semantics (core/include/locus/link.hpp) over MqttConnection. Each distinct filter is
// one broker subscription (with its v5 subscription identifier); a message is dispatched to the local
// subscriptions whose filters it matched, one handler at a time on the connection thread, with the
// same "not running after unsubscribe returns" handshake as the in-process link.
#include "mqtt/mqtt_link.hpp"

#include <algorithm>
#include <chrono>
#include <exception>
#include <unistd.h>

namespace locus::mqtt {

ParamSchema mqtt_link_schema() {
  ParamSchema s = mqtt_connection_schema();
  s.push_back(string_param("topic_prefix", std::string("locus"),
                           "Root of the link's MQTT topics: link topic t travels as <topic_prefix>/link/t."));
  s.push_back(string_param("auth_key_file", std::string(""),
                           "Shared site key (>= 16 bytes, not readable by others): sign every link message "
                           "with HMAC-SHA256 and drop unsigned, forged, stale and replayed ones. Empty = off."));
  s.push_back(string_param("auth_sender", std::string(""),
                           "This node's name in signed messages; empty = the MQTT user name, else the client id, "
                           "else the host name."));
  s.push_back(float_param("auth_window_s", 30.0, 1.0, 3600.0, "s",
                           "Largest difference between a signed message's send time and this board's clock."));
  return s;
}

namespace {
double unix_now_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}
}  // namespace

std::unique_ptr<linkauth::MessageAuthenticator> mqtt_link_authenticator(const Params& params,
                                                                        const MqttOptions& options) {
  const std::string key_file = params.get_string("auth_key_file");
  if (key_file.empty()) return nullptr;
  std::string sender = params.get_string("auth_sender");
  if (sender.empty()) sender = options.username;
  if (sender.empty()) sender = options.client_id;
  if (sender.empty()) {
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) == 0) sender = host;
  }
  std::string key = linkauth::load_key_file(key_file, "mqtt link: auth_key_file");
  return std::make_unique<linkauth::MessageAuthenticator>(std::move(key), std::move(sender),
                                                          params.get_float("auth_window_s"));
}

void check_topic_prefix(const std::string& prefix, std::string_view key, std::string_view what) {
  const bool bad = prefix.empty() || prefix.find_first_of("+#") != std::string::npos || prefix.front() == '/' ||
                   prefix.back() == '/' || prefix.find("//") != std::string::npos;
  if (bad) {
    throw MqttError(std::string(what) + ": " + std::string(key) + ": expected topic levels like 'locus' or 'site/a' " +
                    "(non-empty, no '+' or '#', no leading, trailing or double '/'), got '" + prefix + "'");
  }
}

LinkTopics::LinkTopics(std::string prefix) {
  check_topic_prefix(prefix, "topic_prefix", "mqtt link");
  root_ = std::move(prefix) + "/link/";
}

std::string LinkTopics::to_mqtt(std::string_view link_topic) const { return root_ + std::string(link_topic); }

std::optional<std::string> LinkTopics::from_mqtt(std::string_view mqtt_topic) const {
  if (mqtt_topic.substr(0, root_.size()) != root_) return std::nullopt;
  return std::string(mqtt_topic.substr(root_.size()));
}

MqttLink::MqttLink(MqttOptions options, std::string topic_prefix, Logger& log,
                   std::unique_ptr<linkauth::MessageAuthenticator> auth)
    : topics_(std::move(topic_prefix)), log_(log), auth_(std::move(auth)) {
  conn_ = std::make_unique<MqttConnection>(
      std::move(options), log, "mqtt link",
      [this](const std::string& topic, std::string_view payload, const std::vector<std::uint32_t>& ids) {
        dispatch(topic, payload, ids);
      });
}

MqttLink::~MqttLink() {
  conn_.reset();
  if (auth_ && auth_->counts().rejected() > 0) {
    const linkauth::AuthCounts c = auth_->counts();
    log_.warn("mqtt link: rejected " + std::to_string(c.rejected()) + " link messages (" +
              std::to_string(c.bad_signature) + " bad signature, " + std::to_string(c.replayed) + " replayed, " +
              std::to_string(c.stale) + " stale, " + std::to_string(c.unsigned_messages) + " unsigned, " +
              std::to_string(c.malformed) + " malformed); accepted " + std::to_string(c.accepted));
  }
}

void MqttLink::publish(std::string_view topic, std::string_view payload) {
  if (auth_) {
    conn_->publish(topics_.to_mqtt(topic), auth_->sign(topic, payload, unix_now_s()), false);
    return;
  }
  conn_->publish(topics_.to_mqtt(topic), payload, false);
}

std::uint64_t MqttLink::subscribe(std::string_view filter, LinkHandler handler) {
  const std::string f(filter);
  std::lock_guard lock(mutex_);  // held across conn_->subscribe: dispatch waits until the entry exists
  auto it = filters_.find(f);
  std::uint32_t broker_id = 0;
  if (it != filters_.end()) {
    broker_id = it->second.first;
    ++it->second.second;
  } else {
    broker_id = conn_->subscribe(topics_.to_mqtt(f));  // throws std::invalid_argument for a bad filter
    filters_.emplace(f, std::make_pair(broker_id, 1));
  }
  const std::uint64_t id = next_id_++;
  subs_.push_back(Subscription{id, f, broker_id, std::make_shared<LinkHandler>(std::move(handler))});
  return id;
}

void MqttLink::unsubscribe(std::uint64_t id) {
  std::unique_lock lock(mutex_);
  auto it = std::find_if(subs_.begin(), subs_.end(), [id](const Subscription& s) { return s.id == id; });
  if (it != subs_.end()) {
    auto f = filters_.find(it->filter);
    if (f != filters_.end() && --f->second.second == 0) {
      conn_->unsubscribe(f->second.first);
      filters_.erase(f);
    }
    subs_.erase(it);
  }
  // Once we return, the handler is not running (unless we are that handler, on the link thread).
  if (!conn_->on_connection_thread()) {
    idle_.wait(lock, [&] { return delivering_sub_ != id; });
  }
}

std::uint64_t MqttLink::deliveries() const {
  std::lock_guard lock(mutex_);
  return deliveries_;
}

std::uint64_t MqttLink::unmatched() const {
  std::lock_guard lock(mutex_);
  return unmatched_;
}

void MqttLink::dispatch(const std::string& mqtt_topic, std::string_view payload,
                        const std::vector<std::uint32_t>& ids) {
  std::optional<std::string> topic = topics_.from_mqtt(mqtt_topic);
  std::string body(payload);
  if (topic && auth_) {
    linkauth::MessageAuthenticator::Result r = auth_->verify(*topic, payload, unix_now_s());
    if (r.verdict != linkauth::Verdict::Accepted) {
      // Logged while rare (the first 20), then every 1000th: a flood must not flood the journal.
      const std::uint64_t n = auth_->counts().rejected();
      if (n <= 20 || n % 1000 == 0) {
        log_.warn("mqtt link: dropped a message on '" + *topic + "'" +
                  (r.sender.empty() ? std::string() : " claiming sender '" + r.sender + "'") + ": " +
                  linkauth::verdict_name(r.verdict) + " (" + std::to_string(n) + " rejected so far)");
      }
      return;
    }
    body = std::move(r.payload);
  }
  std::unique_lock lock(mutex_);
  if (!topic) {
    ++unmatched_;
    return;
  }
  const LinkMessage msg{std::move(*topic), std::move(body)};
  std::vector<std::pair<std::uint64_t, std::shared_ptr<LinkHandler>>> targets;
  for (const auto& s : subs_) {
    // The broker names the filters this copy matched; without identifiers, match locally.
    const bool named = ids.empty() || std::find(ids.begin(), ids.end(), s.broker_id) != ids.end();
    if (named && topic_matches(s.filter, msg.topic)) targets.emplace_back(s.id, s.handler);
  }
  if (targets.empty()) ++unmatched_;
  for (auto& [id, handler] : targets) {
    const bool still_subscribed =
        std::any_of(subs_.begin(), subs_.end(), [id = id](const Subscription& s) { return s.id == id; });
    if (!still_subscribed) continue;
    delivering_sub_ = id;
    lock.unlock();
    try {
      (*handler)(msg);
    } catch (const std::exception& e) {
      log_.error("mqtt link: handler for '" + msg.topic + "' threw: " + e.what());
    } catch (...) {
      log_.error("mqtt link: handler for '" + msg.topic + "' threw a non-standard exception");
    }
    lock.lock();
    ++deliveries_;
    delivering_sub_ = 0;
    idle_.notify_all();
  }
}

}  // namespace locus::mqtt
