// The in-process link: devices replayed in one process exchange messages through it. Delivery is
// asynchronous on the link's own thread, in publish order, so a publisher never runs a subscriber's
// code on its own stack (as with MQTT between boards).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "locus/link.hpp"

namespace locus {

class InProcessLink final : public Link {
 public:
  InProcessLink();
  ~InProcessLink() override;

  void publish(std::string_view topic, std::string_view payload) override;
  std::uint64_t subscribe(std::string_view filter, LinkHandler handler) override;
  void unsubscribe(std::uint64_t id) override;

  /// [main] Blocks until every message published so far has been delivered.
  void flush();
  /// [any] Messages published / delivered to handlers so far.
  std::uint64_t published() const;
  std::uint64_t deliveries() const;

 private:
  struct Subscription {
    std::uint64_t id;
    std::string filter;
    std::shared_ptr<LinkHandler> handler;
  };
  void run();

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::deque<LinkMessage> queue_;
  std::vector<Subscription> subs_;
  std::uint64_t next_id_ = 1;
  std::uint64_t published_ = 0;
  std::uint64_t deliveries_ = 0;
  bool delivering_ = false;
  std::uint64_t delivering_sub_ = 0;
  bool stopping_ = false;
  std::thread::id thread_id_;
  std::thread thread_;
};

/// Wraps a link so that subscription handlers run on an event bus's dispatcher thread (what the
/// host hands to localizers: all of a localizer's callbacks arrive on one thread).
class EventBus;
class DispatchedLink final : public Link {
 public:
  DispatchedLink(Link& inner, EventBus& bus) : inner_(inner), bus_(bus) {}
  void publish(std::string_view topic, std::string_view payload) override { inner_.publish(topic, payload); }
  std::uint64_t subscribe(std::string_view filter, LinkHandler handler) override;
  void unsubscribe(std::uint64_t id) override { inner_.unsubscribe(id); }

 private:
  Link& inner_;
  EventBus& bus_;
};

}  // namespace locus
