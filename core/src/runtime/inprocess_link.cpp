#include "locus/inprocess_link.hpp"

#include <algorithm>

#include "locus/event_bus.hpp"

namespace locus {

InProcessLink::InProcessLink() : thread_([this] { run(); }) {}

InProcessLink::~InProcessLink() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void InProcessLink::publish(std::string_view topic, std::string_view payload) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(LinkMessage{std::string(topic), std::string(payload)});
    ++published_;
  }
  wake_.notify_all();
}

std::uint64_t InProcessLink::subscribe(std::string_view filter, LinkHandler handler) {
  std::lock_guard lock(mutex_);
  const std::uint64_t id = next_id_++;
  subs_.push_back(Subscription{id, std::string(filter), std::make_shared<LinkHandler>(std::move(handler))});
  return id;
}

void InProcessLink::unsubscribe(std::uint64_t id) {
  std::unique_lock lock(mutex_);
  subs_.erase(std::remove_if(subs_.begin(), subs_.end(), [id](const Subscription& s) { return s.id == id; }),
              subs_.end());
  // Guarantee: once we return, the handler is not running (unless we are that handler).
  if (std::this_thread::get_id() != thread_id_) {
    idle_.wait(lock, [&] { return !(delivering_ && delivering_sub_ == id); });
  }
}

void InProcessLink::flush() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] { return queue_.empty() && !delivering_; });
}

std::uint64_t InProcessLink::published() const {
  std::lock_guard lock(mutex_);
  return published_;
}

std::uint64_t InProcessLink::deliveries() const {
  std::lock_guard lock(mutex_);
  return deliveries_;
}

void InProcessLink::run() {
  std::unique_lock lock(mutex_);
  thread_id_ = std::this_thread::get_id();
  for (;;) {
    wake_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
    if (queue_.empty() && stopping_) break;
    LinkMessage msg = std::move(queue_.front());
    queue_.pop_front();
    delivering_ = true;
    // Deliver to the subscriptions present now; one at a time, without holding the lock.
    std::vector<std::pair<std::uint64_t, std::shared_ptr<LinkHandler>>> targets;
    for (const auto& s : subs_) {
      if (topic_matches(s.filter, msg.topic)) targets.emplace_back(s.id, s.handler);
    }
    for (auto& [id, handler] : targets) {
      const bool still_subscribed =
          std::any_of(subs_.begin(), subs_.end(), [id = id](const Subscription& s) { return s.id == id; });
      if (!still_subscribed) continue;
      delivering_sub_ = id;
      lock.unlock();
      (*handler)(msg);
      lock.lock();
      ++deliveries_;
      delivering_sub_ = 0;
      idle_.notify_all();
    }
    delivering_ = false;
    idle_.notify_all();
  }
}

std::uint64_t DispatchedLink::subscribe(std::string_view filter, LinkHandler handler) {
  auto shared = std::make_shared<LinkHandler>(std::move(handler));
  return inner_.subscribe(filter, [this, shared](const LinkMessage& msg) {
    bus_.post_task([shared, msg] { (*shared)(msg); });
  });
}

}  // namespace locus
