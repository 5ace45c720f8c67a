// Sensor sources: the HAL side that produces IMU samples, BLE advertisements and radio sync events
// (IIO, BlueZ, scene replay, simulators) into a device's SensorQueue, the counterpart of AudioSource
// for the non-audio streams. The pipeline owns the queue and the consumer side: the device's detector
// thread merges every sensor stream with the audio by device-local time (docs/config.md, "Time order").
//
// Why a queue of typed events and not a ring of samples: sensor streams are sparse and irregular
// (BLE adverts arrive when they arrive), each item already carries its own local time, and the
// consumer needs to look at the head's time before deciding whether audio or a sensor event comes
// next. A fixed-capacity SPSC queue of trivially copyable Event values gives exactly that without
// allocating on either side.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"
#include "locus/spsc_queue.hpp"

namespace locus {

/// What a sensor source produces (one kind per source).
enum class SensorKind : std::uint8_t {
  Imu = 0,   ///< ImuSample
  Ble,       ///< BleAdvertisement
  Sync,      ///< RadioSync
};

/// "imu", "ble", "sync" (the config section names).
std::string_view sensor_kind_name(SensorKind kind) noexcept;
/// The event type a kind produces.
EventType sensor_event_type(SensorKind kind) noexcept;
/// Local time of a sensor event (ImuSample / BleAdvertisement / RadioSync t_s); NaN for other types.
double sensor_event_time_s(const Event& event) noexcept;
/// [RT] Adds `delta_s` to the local time of a sensor event (ImuSample / BleAdvertisement / RadioSync);
/// false (nothing changed) for other types.
bool shift_sensor_event_time(Event& event, double delta_s) noexcept;

/// The hand-over from one sensor source (producer thread) to the device's detector thread (consumer).
/// Fixed capacity (rounded up to a power of two), lock-free, never allocates after construction.
class SensorQueue {
 public:
  explicit SensorQueue(std::size_t capacity) : queue_(capacity) {}
  SensorQueue(const SensorQueue&) = delete;
  SensorQueue& operator=(const SensorQueue&) = delete;

  /// [RT, producer] Appends an event; false (nothing changed) when full. Never allocates or blocks.
  /// A live source calls count_drop() when this fails; a replay source waits and retries.
  bool try_push(const Event& event) noexcept { return queue_.try_push(event); }
  /// [RT, producer] Counts an event a live source had to drop because the queue was full.
  void count_drop() noexcept { dropped_.fetch_add(1, std::memory_order_relaxed); }

  /// [RT, consumer] Removes the oldest event; false when empty.
  bool try_pop(Event& out) noexcept { return queue_.try_pop(out); }

  std::size_t capacity() const noexcept { return queue_.capacity(); }
  std::size_t size_approx() const noexcept { return queue_.size_approx(); }
  /// [any] Events dropped by a live producer (full queue).
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  SpscQueue<Event> queue_;
  std::atomic<std::uint64_t> dropped_{0};
};

class SensorSource {
 public:
  virtual ~SensorSource() = default;

  /// [main] Validated params. Throw std::runtime_error naming what failed.
  virtual void open(const Params& params, HostContext& ctx) = 0;
  /// The one kind of event this source produces (fixed by its descriptor).
  virtual SensorKind kind() const = 0;

  /// True for hardware-paced sources (a full queue drops events, counted in the queue); false for
  /// sources that can wait for the consumer (replay at max speed). A device whose sources are all
  /// non-live is replayed losslessly and in exact time order.
  virtual bool live() const = 0;

  /// [main, after open()] True when the events' t_s are CLOCK_MONOTONIC seconds (iio polled, iio
  /// buffered with timestamp_clock monotonic, bluez); false when t_s is already device-local time
  /// with audio frame 0 at t = 0 (scene replay) or on some other clock. The pipeline translates
  /// monotonic times onto the audio timeline of a device whose audio source is live (pipeline.hpp,
  /// "Time base").
  virtual bool monotonic_time() const { return false; }

  /// [main] Starts producing into `queue` (the source owns its thread). Must return quickly. Events are
  /// pushed in non-decreasing local time (the order the device sensed them).
  virtual void start(SensorQueue& queue) = 0;
  /// [main] Stops producing; idempotent. After it returns nothing pushes to the queue.
  virtual void stop() = 0;
  /// [any] True once a finite source has pushed its last event (release: everything pushed before
  /// is visible to a consumer that sees finished() == true).
  virtual bool finished() const noexcept = 0;
  /// [main] Error that ended the stream early ("" if none).
  virtual std::string error() const { return {}; }
};

}  // namespace locus
