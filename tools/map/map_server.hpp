// The live map: an HTTP server inside locusd (`locusd --http 127.0.0.1:PORT`) that serves one page
// showing the node's (or, in hub mode, the whole site's) devices, estimated positions with their
// uncertainty ellipses and traces, direction-only results as bearings, per-device health, and the
// event stream live over Server-Sent Events. docs/map.md is the user's reference.
//
// Why this shape (threads and who owns what):
//   - The real-time side never sees the server. Events reach the map through EventTaps: a bounded
//     SPSC queue of trivially copyable TappedEvent per producer (one per pipeline dispatcher thread,
//     subscribed with Pipeline::subscribe). EventTap::push never allocates, locks or blocks; a full
//     tap drops and counts (tests/alloc proves it with the server running).
//   - The map's own "pump" thread drains the taps every few milliseconds, turns events into JSON
//     (core's event_to_json, the JSON-lines shape), folds them into MapState and appends each one to
//     the bounded SSE backlog. It never waits for a client.
//   - cpp-httplib (Debian's libcpp-httplib-dev, not a server of our own) runs the sockets on its thread
//     pool. Each SSE client is one pool thread that waits on the backlog's condition variable and
//     writes what is new; a slow client only slows its own thread until write_timeout_s closes it,
//     and a client that fell behind the backlog is told to reload the state (event `reset`).
//   - Every asset (HTML, JS, CSS) is compiled into the binary (tools/map/web, embedded by
//     cmake/EmbedAssets.cmake): no CDN, nothing read from disk at run time.
//   - The main thread adds health snapshots (Pipeline::live_stats) and, in hub mode, the MQTT thread
//     adds JSON events (post_json); both are outside the real-time path, so they take the state mutex.
//
// Bad HTTP input gets a clean answer from cpp-httplib or from us: unknown paths 404 (text body naming
// the path), header lines over 8192 bytes 400, URIs over 8192 bytes 414, unknown methods 400, clients
// beyond max_clients SSE streams 503; idle or slow clients are dropped after read_timeout_s /
// write_timeout_s. tests/integration/map checks each with real sockets.
#pragma once

#include <chrono>
#include <set>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <ctime>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"
#include "locus/pipeline.hpp"
#include "locus/spsc_queue.hpp"
#include "map_state.hpp"

namespace httplib {
class Server;
}

namespace locus::map {

/// [any] CLOCK_MONOTONIC in nanoseconds (the hub's and the server's timestamps).
inline std::int64_t mono_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// A bad --http address or parameter, or a socket that could not be bound. what() names the key or
/// host:port and the reason.
class MapError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The map's parameters (`--http-param KEY=VALUE`; schema: map_schema()).
struct MapOptions {
  std::string host = "127.0.0.1";  ///< from --http; loopback unless an address is given explicitly
  int port = 0;                    ///< 0 = any free port (the log and url() say which)
  int max_clients = 8;             ///< SSE streams at once (more get 503)
  double read_timeout_s = 5.0;     ///< a client silent this long mid-request is dropped
  double write_timeout_s = 5.0;    ///< a client not reading this long is dropped
  int backlog = 1024;              ///< SSE messages kept for clients that are behind
  int trace_points = 300;          ///< positions kept per estimated target (its trace)
  int tap_capacity = 4096;         ///< events each tap holds for the pump thread
  double health_period_s = 0.5;    ///< how often health is sent to the page
  double linger_s = 0.0;           ///< keep serving after the run ended (replays), until SIGINT/SIGTERM
  std::vector<EventType> events{EventType::Estimate, EventType::AudioDetection};  ///< what the map gets
  std::string title = "Locus";     ///< page title
};

/// The declared parameters (key, type, default, range, unit, doc), validated like every other
/// locusd parameter (locus::validate_params).
ParamSchema map_schema();

/// "PORT", "HOST:PORT" or "[V6]:PORT" + validated params -> options. Throws MapError naming the
/// problem ("--http: port must be in [0, 65535]", "--http-param events: unknown event type 'x'").
MapOptions map_options(const std::string& listen, const Params& params);

/// True for 127.0.0.0/8, ::1 and "localhost".
bool is_loopback(const std::string& host);

/// One event as it crosses from a dispatcher thread to the map: trivially copyable.
struct TappedEvent {
  Event event;
  std::int64_t mono_ns = 0;  ///< CLOCK_MONOTONIC when it was handed over (latency measurement)
};

/// The hand-over from one producer thread (a pipeline's dispatcher) to the map's pump thread.
class EventTap {
 public:
  EventTap(std::string node, std::size_t capacity) : node_(std::move(node)), queue_(capacity) {}
  /// [RT-safe, one producer thread] Never allocates, locks or blocks; false (counted) when full.
  bool push(const Event& event) noexcept;
  /// [pump thread] Oldest event, or false.
  bool pop(TappedEvent& out) noexcept { return queue_.try_pop(out); }
  const std::string& node() const noexcept { return node_; }
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::string node_;
  SpscQueue<TappedEvent> queue_;
  std::atomic<std::uint64_t> dropped_{0};
};

class MapServer {
 public:
  struct Stats {
    std::uint64_t events = 0;         ///< events folded into the map
    std::uint64_t tap_dropped = 0;    ///< events lost because a tap was full
    std::uint64_t sse_messages = 0;   ///< messages appended to the SSE backlog
    std::uint64_t clients_now = 0;    ///< SSE streams open
    std::uint64_t clients_total = 0;  ///< SSE streams ever opened
    std::uint64_t clients_refused = 0;  ///< SSE streams refused (max_clients)
    std::uint64_t resets = 0;         ///< clients that fell behind the backlog
  };

  /// Binds the socket (throws MapError naming host:port and the reason). Nothing runs yet.
  MapServer(MapOptions options, Logger& log);
  ~MapServer();
  MapServer(const MapServer&) = delete;
  MapServer& operator=(const MapServer&) = delete;

  /// [main, before start()] A tap for one producer; subscribe it to a pipeline with attach().
  EventTap& add_tap(const std::string& node);
  /// [main, before the pipeline starts] Subscribes a new tap to every event type of options().events
  /// of `pipeline` (whose dispatcher thread becomes the tap's producer) and lists its devices.
  void attach(const std::string& node, Pipeline& pipeline);

  /// [main] Starts the pump thread and the HTTP server.
  void start();
  /// [main] Stops both; SSE clients are closed, once each has been sent (for at most kStopFlush) what
  /// was handed over before the call. Idempotent.
  void stop();

  /// [any, not RT] One event as JSON (the JSON-lines shape) from `node`, e.g. received over MQTT.
  void post_json(const std::string& node, const nlohmann::ordered_json& event, std::int64_t mono_ns);
  /// [any, not RT] The link state of a node ("online", "offline", "in-process", "mqtt").
  void set_link_state(const std::string& node, const std::string& state);
  /// [main] Health counters of `node`'s devices (Pipeline::live_stats()).
  void set_health(const std::string& node, const std::vector<DeviceStats>& stats);
  /// [main] What the page says about the run ("replaying scene X", "finished").
  void set_status(const std::string& status, bool finished);

  const MapOptions& options() const noexcept { return opt_; }
  int port() const noexcept { return port_; }
  /// "http://host:port/"
  std::string url() const;
  Stats stats() const;
  /// The current state as the page's /api/state returns it.
  nlohmann::ordered_json snapshot() const;

 private:
  void pump();
  void drain_taps();
  void append_locked(std::string event_name, const nlohmann::ordered_json& data);
  void routes();

  MapOptions opt_;
  Logger& log_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::vector<std::unique_ptr<EventTap>> taps_;

  mutable std::mutex mutex_;  // state_, backlog_, seq_, stats_, the flags below (never on the RT side)
  std::condition_variable changed_;
  MapState state_;
  struct Message {
    std::uint64_t seq;
    std::string text;  // the whole SSE message: "id: ..\nevent: ..\ndata: ..\n\n"
  };
  std::deque<Message> backlog_;
  std::uint64_t seq_ = 0;
  std::set<std::shared_ptr<std::uint64_t>> streams_;  // each open /events stream: the last seq it sent
  static constexpr std::chrono::milliseconds kStopFlush{1000};
  bool stopping_ = false;
  bool health_dirty_ = false;
  Stats stats_;

  std::atomic<bool> pump_stop_{false};
  std::thread pump_thread_;
  std::thread http_thread_;
  bool started_ = false;
};

}  // namespace locus::map
