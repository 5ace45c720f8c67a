// One JACK client shared by the `jack` source and the `jack` sink of a node, and its supervisor.
//
// Why shared: a source and a sink naming the same server and client_name get ONE jack_client_t, hence
// one process callback and one frame counter for capture and playback (see jack_process.hpp). That is
// what lets a device record its own emission at a known frame offset. The registry of shared clients
// is process-wide, keyed by (server, client_name), and main-side only.
//
// Why a supervisor thread: when jackd goes away (jack_on_info_shutdown, which may come from any libjack
// thread and only sets an atomic here), everything that talks to the server (closing the dead client,
// jack_client_open with backoff, registering ports, activating, connecting by pattern) and every log
// line happens on this thread, never on the RT callback. When the server is back the stream resumes on
// the same frame counter and the outage is reported as lost frames (estimated by JackProcessor).
//
// Life cycle of a part (capture = the source's input ports, playback = the sink's output ports):
//   attach (open(): registers the ports) -> start (publishes the ring/scheduler; the client is
//   activated once every attached part has started, or 0.5 s after the first did) -> stop
//   (unpublishes; nothing touches the ring/scheduler afterwards) -> detach (unregisters the ports).
// The client is closed when the last part lets go of it.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "jack/jack_process.hpp"
#include "locus/audio_ring.hpp"
#include "locus/host.hpp"
#include "locus/playback.hpp"

typedef struct _jack_client jack_client_t;  // NOLINT: libjack's own spelling
typedef struct _jack_port jack_port_t;      // NOLINT

namespace locus::hal::jack {

/// How the supervisor retries after the server went away.
struct ReconnectPolicy {
  double backoff_s = 0.5;         ///< first retry delay; doubles per failed attempt up to max(backoff_s, 5 s)
  std::int64_t max_attempts = 0;  ///< failed attempts before giving up; 0 = retry until stopped
  bool operator==(const ReconnectPolicy&) const = default;
};

/// The server name libjack will use for `server` ("" = $JACK_DEFAULT_SERVER, else "default").
std::string resolve_server_name(const std::string& server);

/// Installs (once) libjack error/info handlers that keep libjack's own messages off stderr while this
/// backend probes for a server (they are summarised in our own errors instead). Messages from other
/// threads still go to stderr, prefixed "libjack:".
void install_jack_message_handlers();

/// RAII: libjack messages emitted by this thread are collected (not printed) while alive.
class QuietJack {
 public:
  QuietJack();
  ~QuietJack();
  QuietJack(const QuietJack&) = delete;
  QuietJack& operator=(const QuietJack&) = delete;
  /// The libjack messages collected so far, "; "-separated.
  std::string messages() const { return collected_; }

 private:
  std::string collected_;
  std::string* previous_ = nullptr;
};

/// Explains a jack_client_open failure status in words ("no JACK server 'x' is running", ...).
std::string describe_open_status(unsigned status, const std::string& server, const std::string& client_name);

class SharedJackClient {
 public:
  enum class Part : std::uint8_t { Capture, Playback };

  /// [main] The client (server, client_name) of this process, opened (JackNoStartServer,
  /// JackUseExactName) if nobody holds it. Throws std::runtime_error when no server runs, the name is
  /// taken, or the client exists with another reconnect policy.
  static std::shared_ptr<SharedJackClient> acquire(const std::string& server, const std::string& client_name,
                                                   const ReconnectPolicy& policy, Logger& log);
  ~SharedJackClient();
  SharedJackClient(const SharedJackClient&) = delete;
  SharedJackClient& operator=(const SharedJackClient&) = delete;

  /// [main] Registers `channels` ports for `part` (in_1.. for capture, out_1.. for playback) and keeps
  /// the connect pattern. Throws std::runtime_error if the part is already attached (two sources on one
  /// client) or the server refuses a port.
  void attach(Part part, std::uint32_t channels, const std::string& connect_pattern, Logger& log);
  /// [main] Stops the part if needed and unregisters its ports. Idempotent.
  void detach(Part part) noexcept;
  /// [main] Publishes the ring / scheduler and asks the supervisor to activate. Return quickly.
  /// Throw std::runtime_error when the client has failed for good (see error()).
  void start_capture(AudioRing& ring);
  void start_playback(PlaybackScheduler& scheduler);
  /// [main] Unpublishes: after it returns the callback no longer touches the ring/scheduler. Idempotent.
  void stop(Part part) noexcept;

  /// [any]
  double sample_rate_hz() const noexcept { return processor_.sample_rate_hz(); }
  const std::string& server_name() const noexcept { return server_; }
  const std::string& client_name() const noexcept { return client_name_; }
  /// "JACK client 'locus' on server 'default'"
  std::string describe() const;
  /// True once the client gave up (reconnect_max reached, or the server came back at another rate).
  bool failed() const noexcept { return failed_.load(std::memory_order_acquire); }
  std::string error() const;
  /// True while connected to a running server and activated.
  bool running() const noexcept { return running_.load(std::memory_order_acquire); }
  /// Successful reconnections after an outage.
  std::uint64_t reconnects() const noexcept { return reconnects_.load(std::memory_order_relaxed); }
  /// Period size of the current connection (0 while down).
  std::uint32_t buffer_frames() const noexcept { return buffer_frames_.load(std::memory_order_relaxed); }
  const JackProcessor& processor() const noexcept { return processor_; }
  /// CLOCK_MONOTONIC seconds of client frame 0 (NaN before the first cycle): the server's time of the
  /// current cycle's start (jack_frames_to_time of jack_last_frame_time, on jack_get_time()'s clock,
  /// which jack2 takes from CLOCK_MONOTONIC on Linux with the default system clock source; the offset
  /// to CLOCK_MONOTONIC is measured every cycle anyway, so hpet/cycle-counter sources work too) minus
  /// the client frames before it. Updated every cycle (follows the server's DLL, skipped cycles and
  /// outages, which advance the frame counter). Capture rings share the client's frame numbers.
  double frame_zero_monotonic_s() const noexcept { return frame_zero_s_.load(std::memory_order_acquire); }

 private:
  struct PartState {
    bool attached = false;
    bool started = false;
    std::uint32_t channels = 0;
    std::string pattern;
    Logger* log = nullptr;
    std::array<jack_port_t*, kMaxPorts> ports{};
    std::atomic<std::uint32_t> port_count{0};  // read by the callback
    bool warned_few = false;                   // "pattern matches fewer ports" said once per connection
  };

  SharedJackClient(std::string server, std::string client_name, ReconnectPolicy policy, double rate);

  static int on_process(std::uint32_t nframes, void* arg) noexcept;
  static int on_xrun(void* arg) noexcept;
  static void on_shutdown(int code, const char* reason, void* arg) noexcept;
  static void on_port_registration(std::uint32_t port, int registered, void* arg) noexcept;

  PartState& state(Part p) noexcept { return p == Part::Capture ? capture_ : playback_; }
  Logger* logger_locked() noexcept;
  void log_locked(LogLevel level, const std::string& message);
  void install_callbacks_locked();
  void register_ports_locked(Part part);
  void connect_locked(Part part);
  bool want_active_locked() const;
  void activate_locked();
  void deactivate_locked();
  void handle_down_locked();
  void try_reconnect_locked();
  void fail_locked(const std::string& message);
  void supervise();

  const std::string server_;       // resolved name
  const std::string server_arg_;   // as given ("" = default)
  const std::string client_name_;
  const ReconnectPolicy policy_;

  JackProcessor processor_;
  std::atomic<double> frame_zero_s_{std::numeric_limits<double>::quiet_NaN()};
  std::atomic<jack_client_t*> jc_{nullptr};
  std::array<const float*, kMaxPorts> in_bufs_{};  // RT scratch: port buffers of one cycle
  std::array<float*, kMaxPorts> out_bufs_{};

  mutable std::mutex mu_;  // main side: everything below (the RT callback never takes it)
  std::condition_variable cv_;
  PartState capture_, playback_;
  bool activated_ = false;
  bool quit_ = false;
  bool down_handled_ = false;
  std::string error_;
  std::chrono::steady_clock::time_point first_start_{};
  std::chrono::steady_clock::time_point down_since_{};
  std::chrono::steady_clock::time_point next_attempt_{};
  double backoff_now_s_ = 0.0;
  std::int64_t attempts_ = 0;
  std::uint64_t resumes_logged_ = 0;
  std::thread supervisor_;

  // Set from libjack threads.
  std::atomic<bool> down_{false};
  std::atomic<bool> ports_changed_{false};
  std::array<char, 256> down_reason_{};  // written before down_ is released
  std::atomic<bool> failed_{false};
  std::atomic<bool> running_{false};
  std::atomic<std::uint64_t> reconnects_{0};
  std::atomic<std::uint32_t> buffer_frames_{0};
};

}  // namespace locus::hal::jack
