// The link: how devices exchange messages (beep intervals, timestamps, positions) by topic.
//
// Plugins never know what carries it: the in-process link (one process replaying a multi-device
// scene) or MQTT between boards. Topics are '/'-separated; subscriptions accept MQTT wildcards
// ('+' one level, '#' the rest). Payloads are opaque bytes (plugins use JSON or a packed struct).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>

namespace locus {

struct LinkMessage {
  std::string topic;
  std::string payload;
};

using LinkHandler = std::function<void(const LinkMessage&)>;

class Link {
 public:
  virtual ~Link() = default;
  /// [main] Sends `payload` to every subscriber whose filter matches `topic` (including the sender's
  /// own subscriptions). Never blocks on a slow subscriber; delivery is asynchronous.
  virtual void publish(std::string_view topic, std::string_view payload) = 0;
  /// [main] Registers `handler` for topics matching `filter`; returns an id for unsubscribe.
  /// Handlers run on a thread owned by the link (the host re-posts them to its dispatcher thread).
  virtual std::uint64_t subscribe(std::string_view filter, LinkHandler handler) = 0;
  /// [main] Removes a subscription; after it returns, its handler is not running and will not run.
  virtual void unsubscribe(std::uint64_t id) = 0;
};

/// MQTT topic-filter matching ('+' matches one level, '#' as the last level matches the rest).
bool topic_matches(std::string_view filter, std::string_view topic) noexcept;

}  // namespace locus
