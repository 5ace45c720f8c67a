// The event bus: real-time producers hand events over through lock-free queues; one dispatcher
// thread delivers every event to the subscribers of its type, in a single thread, so subscribers
// (localizers, sinks) need no locks of their own.
//
// Producers: each real-time thread (a device's detector thread) owns one RtEventQueue (SPSC, fixed
// capacity, emit() never blocks or allocates and counts what it had to drop). Non-real-time threads
// (link receivers, the main thread, handlers themselves) use post()/post_task(), which may lock.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>
#include <vector>

#include "locus/detector.hpp"
#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/spsc_queue.hpp"

namespace locus {

/// The real-time side of the bus for one producer thread.
class RtEventQueue final : public EventSink {
 public:
  RtEventQueue(std::string name, std::size_t capacity) : name_(std::move(name)), queue_(capacity) {}
  /// [RT, the owning producer thread] Never blocks or allocates; false (counted) when full.
  bool emit(const Event& event) noexcept override {
    if (queue_.try_push(event)) return true;
    dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
    return false;
  }
  /// [dispatcher] Pops one event.
  bool pop(Event& out) noexcept { return queue_.try_pop(out); }
  const std::string& name() const noexcept { return name_; }
  /// [any] Events refused because the queue was full.
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  std::size_t capacity() const noexcept { return queue_.capacity(); }
  /// [any] Approximate number of queued events (seen from the producer: an upper bound, the consumer only removes).
  std::size_t size_approx() const noexcept { return queue_.size_approx(); }

 private:
  std::string name_;
  SpscQueue<Event> queue_;
  std::atomic<std::uint64_t> dropped_{0};
};

class EventBus {
 public:
  using Handler = std::function<void(const Event&)>;
  using Task = std::function<void()>;

  EventBus() = default;
  ~EventBus();
  EventBus(const EventBus&) = delete;
  EventBus& operator=(const EventBus&) = delete;

  /// [main, before start()] Delivers every event of `type` to `handler` on the dispatcher thread.
  void subscribe(EventType type, Handler handler);
  /// [main, before start()] A queue for one real-time producer thread; owned by the bus.
  RtEventQueue& make_rt_queue(std::string name, std::size_t capacity);

  /// [any non-RT thread] Queues an event for delivery.
  void post(const Event& event);
  /// [any non-RT thread] Runs `task` on the dispatcher thread (in order with posted events).
  void post_task(Task task);

  /// [main] Starts the dispatcher thread.
  void start();
  /// [main] Stops the dispatcher after delivering everything queued (including what the delivered
  /// handlers post while draining). Idempotent.
  void stop();
  /// [main, when not started, or on the dispatcher thread] Delivers everything queued now; returns
  /// the number of items delivered. Tests and single-threaded tools use it directly.
  std::size_t drain();

  /// [any] Events delivered so far, per type index.
  std::uint64_t delivered(EventType type) const noexcept {
    return delivered_[static_cast<std::size_t>(type)].load(std::memory_order_relaxed);
  }
  /// [any] Sum of RtEventQueue drops.
  std::uint64_t dropped() const noexcept;
  const std::vector<std::unique_ptr<RtEventQueue>>& rt_queues() const noexcept { return rt_queues_; }

 private:
  void deliver(const Event& event);
  void run();

  std::vector<Handler> handlers_[kEventTypeCount];
  std::vector<std::unique_ptr<RtEventQueue>> rt_queues_;
  std::atomic<std::uint64_t> delivered_[kEventTypeCount] = {};

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::variant<Event, Task>> posted_;
  bool stopping_ = false;
  std::thread thread_;
};

/// A Publisher that posts to a bus (what localizers get).
class BusPublisher final : public Publisher {
 public:
  explicit BusPublisher(EventBus& bus) : bus_(bus) {}
  void publish(const Event& event) override { bus_.post(event); }

 private:
  EventBus& bus_;
};

}  // namespace locus
