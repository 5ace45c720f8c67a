// `link` sync source: a board's radio sync (SpyLoc's per-beacon sync frame, Montage's start signal)
// carried as a message over the node's link (MQTT between boards), for the `sync:` section of a device.
//
//   receive   every message on `<topic_prefix>/<source>` becomes one RadioSync event {device, t_s,
//             source}: t_s = CLOCK_MONOTONIC when the message reached this node's localizer thread
//             (the link hands its messages to the dispatcher: that is where a plugin could act on it);
//             the pipeline moves it onto the device's audio timeline (monotonic_time() == true), so a
//             replay's sync.csv and a live node's RadioSync mean the same thing: the local time at which
//             the sync arrived. A plugin that emits schedules its sound from it (plugins/sync_emitter).
//   transmit  (the "radio" role, `send_period_s` > 0) a thread publishes `<topic_prefix>/<send_as>`
//             every send_period_s on CLOCK_MONOTONIC from send_first_s after the epoch (start(), or
//             `send_epoch_monotonic_s`: boards of one host that share it keep their stagger); the node
//             receives its own message like every other node (a beacon schedules its beep from its own
//             arrival). The seq of a message is its slot k, so a skipped slot shows as a gap.
//
// Why over the link: there is no Wi-Fi beacon frame or BLE trigger a process can send and time here;
// the link is the radio the boards share. Its latency is real and unknown to the receiver, as a
// radio's is: the message carries the sender's CLOCK_MONOTONIC at publish, so on ONE host (the HIL
// room) each arrival's one-way latency is measured exactly and logged at stop (on separate boards the
// clocks differ and the figure means nothing). SpyLoc's ranging takes the beep minus the sync's
// arrival minus the known delay: what the walker's arrival lags the emitter's own arrival is a range
// bias of c × that difference (docs/room.md, "SpyLoc").
//
// Message: "<source> <seq> <sent_monotonic_ns>" (decode_sync refuses anything else with a reason).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "locus/link.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"

namespace locus::hal::radio {

/// One radio sync message.
struct SyncMessage {
  std::string source;                  ///< the sender's id ([A-Za-z0-9_-]+, at most 31 characters)
  std::uint64_t seq = 0;               ///< the sender's count, from 0
  std::int64_t sent_monotonic_ns = 0;  ///< the sender's CLOCK_MONOTONIC at publish
};

/// "<source> <seq> <sent_monotonic_ns>".
std::string encode_sync(const SyncMessage& m);
/// The message, or nullopt with `*why` (when given) saying what was wrong and what was expected.
std::optional<SyncMessage> decode_sync(std::string_view payload, std::string* why = nullptr);
/// "<prefix>/<source>".
std::string sync_topic(std::string_view prefix, std::string_view source);

const ParamSchema& link_sync_schema();

class LinkSyncSource final : public SensorSource {
 public:
  LinkSyncSource();
  ~LinkSyncSource() override;

  void open(const Params& params, HostContext& ctx) override;
  SensorKind kind() const override { return SensorKind::Sync; }
  bool live() const override { return true; }
  bool monotonic_time() const override { return true; }
  void start(SensorQueue& queue) override;
  void stop() override;
  bool finished() const noexcept override { return false; }

  /// [any] Messages sent / received (accepted: from a listed source) / malformed so far.
  std::uint64_t sent() const noexcept;
  std::uint64_t received() const noexcept;
  std::uint64_t malformed() const noexcept;

 private:
  struct State;  // shared with the link handler, which may still be queued on the dispatcher after stop()
  void transmit();

  std::shared_ptr<State> state_;
  Link* link_ = nullptr;
  Logger* log_ = nullptr;
  std::string device_, prefix_, send_as_;
  std::vector<std::string> sources_;  ///< empty = any
  double send_period_s_ = 0.0, send_first_s_ = 1.0, send_epoch_s_ = 0.0;
  std::int64_t send_count_ = 0;
  std::uint64_t sub_ = 0;
  bool subscribed_ = false;
  std::thread thread_;
  std::mutex thread_mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::atomic<std::uint64_t> sent_{0};
};

/// Registers the "link" sync source.
void register_link_sync_source(Registry& registry);

}  // namespace locus::hal::radio
