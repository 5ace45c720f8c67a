#include "locus/event_bus.hpp"

#include <chrono>

namespace locus {

EventBus::~EventBus() { stop(); }

void EventBus::subscribe(EventType type, Handler handler) {
  handlers_[static_cast<std::size_t>(type)].push_back(std::move(handler));
}

RtEventQueue& EventBus::make_rt_queue(std::string name, std::size_t capacity) {
  rt_queues_.push_back(std::make_unique<RtEventQueue>(std::move(name), capacity));
  return *rt_queues_.back();
}

void EventBus::post(const Event& event) {
  {
    std::lock_guard lock(mutex_);
    posted_.emplace_back(event);
  }
  wake_.notify_one();
}

void EventBus::post_task(Task task) {
  {
    std::lock_guard lock(mutex_);
    posted_.emplace_back(std::move(task));
  }
  wake_.notify_one();
}

void EventBus::deliver(const Event& event) {
  const std::size_t i = event.index();
  for (auto& h : handlers_[i]) h(event);
  delivered_[i].fetch_add(1, std::memory_order_relaxed);
}

std::size_t EventBus::drain() {
  std::size_t n = 0;
  // Real-time queues first, a bounded batch each so no producer starves the others.
  Event event;
  for (auto& q : rt_queues_) {
    for (std::size_t k = 0; k < q->capacity() && q->pop(event); ++k, ++n) deliver(event);
  }
  std::deque<std::variant<Event, Task>> batch;
  {
    std::lock_guard lock(mutex_);
    batch.swap(posted_);
  }
  for (auto& item : batch) {
    if (auto* e = std::get_if<Event>(&item)) {
      deliver(*e);
    } else {
      std::get<Task>(item)();
    }
    ++n;
  }
  return n;
}

void EventBus::run() {
  for (;;) {
    if (drain() > 0) continue;
    std::unique_lock lock(mutex_);
    if (stopping_ && posted_.empty()) break;
    // Real-time producers cannot notify (no syscalls there), so poll them every millisecond.
    wake_.wait_for(lock, std::chrono::milliseconds(1), [this] { return stopping_ || !posted_.empty(); });
  }
  while (drain() > 0) {
  }
}

void EventBus::start() {
  if (thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = false;
  }
  thread_ = std::thread([this] { run(); });
}

void EventBus::stop() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

std::uint64_t EventBus::dropped() const noexcept {
  std::uint64_t total = 0;
  for (const auto& q : rt_queues_) total += q->dropped();
  return total;
}

}  // namespace locus
