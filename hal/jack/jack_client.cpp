// SharedJackClient: the libjack glue, the shared-client registry and the reconnecting supervisor
// (see jack_client.hpp).
#include "jack/jack_client.hpp"

#include <jack/jack.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <map>
#include <sstream>
#include <stdexcept>

namespace locus::hal::jack {

namespace {

using SteadyClock = std::chrono::steady_clock;

// ---------------------------------------------------------------- libjack messages

thread_local std::string* t_collect = nullptr;

void on_jack_message(const char* msg) {
  if (t_collect != nullptr) {
    if (!t_collect->empty()) t_collect->append("; ");
    t_collect->append(msg ? msg : "");
    return;
  }
  std::fprintf(stderr, "libjack: %s\n", msg ? msg : "");
}

std::string fmt_s(double v) {
  std::ostringstream os;
  os.precision(3);
  os << std::fixed << v;
  return os.str();
}

double seconds_since(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

// The shared-client registry (main side). Recursive: the last reference to a client may be dropped
// while acquire() holds the lock, and the destructor takes it too.
std::recursive_mutex& registry_mutex() {
  static std::recursive_mutex m;
  return m;
}
std::map<std::string, std::weak_ptr<SharedJackClient>>& registry() {
  static std::map<std::string, std::weak_ptr<SharedJackClient>> r;
  return r;
}
std::string registry_key(const std::string& server, const std::string& client) { return server + '\n' + client; }

jack_client_t* open_client(const std::string& server_arg, const std::string& client_name, jack_status_t* status) {
  int options = JackNoStartServer | JackUseExactName;
  if (!server_arg.empty()) options |= JackServerName;
  return jack_client_open(client_name.c_str(), static_cast<jack_options_t>(options), status, server_arg.c_str());
}

}  // namespace

std::string resolve_server_name(const std::string& server) {
  if (!server.empty()) return server;
  const char* env = std::getenv("JACK_DEFAULT_SERVER");
  return env != nullptr && *env != '\0' ? std::string(env) : std::string("default");
}

void install_jack_message_handlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    jack_set_error_function(on_jack_message);
    jack_set_info_function(on_jack_message);
  });
}

QuietJack::QuietJack() : previous_(t_collect) {
  install_jack_message_handlers();
  t_collect = &collected_;
}
QuietJack::~QuietJack() { t_collect = previous_; }

std::string describe_open_status(unsigned status, const std::string& server, const std::string& client_name) {
  std::string what;
  if (status & JackNameNotUnique) {
    what = "the client name '" + client_name + "' is already taken on JACK server '" + server +
           "' (another program or locus instance uses it: set client_name)";
  } else if (status & JackVersionError) {
    what = "JACK server '" + server + "' speaks another protocol version than this libjack";
  } else if (status & (JackServerFailed | JackServerError)) {
    what = "no JACK server '" + server + "' is running or it cannot be reached (start it first, e.g. jackd -n " +
           server + " -d alsa; locus never starts one)";
  } else if (status & JackShmFailure) {
    what = "cannot attach JACK shared memory for server '" + server + "'";
  } else if (status & JackInvalidOption) {
    what = "libjack refused the open options";
  } else if (status & JackInitFailure) {
    what = "libjack could not initialise the client '" + client_name + "'";
  } else {
    what = "jack_client_open('" + client_name + "') on server '" + server + "' failed";
  }
  char hex[32];
  std::snprintf(hex, sizeof hex, " (status 0x%x)", status);
  return what + hex;
}

// ---------------------------------------------------------------- construction

SharedJackClient::SharedJackClient(std::string server, std::string client_name, ReconnectPolicy policy, double rate)
    : server_(resolve_server_name(server)),
      server_arg_(std::move(server)),
      client_name_(std::move(client_name)),
      policy_(policy),
      processor_(rate) {}

std::shared_ptr<SharedJackClient> SharedJackClient::acquire(const std::string& server, const std::string& client_name,
                                                            const ReconnectPolicy& policy, Logger& log) {
  std::lock_guard reg_lock(registry_mutex());
  const std::string resolved = resolve_server_name(server);
  auto& slot = registry()[registry_key(resolved, client_name)];
  if (std::shared_ptr<SharedJackClient> existing = slot.lock()) {
    if (!(existing->policy_ == policy)) {
      throw std::runtime_error(existing->describe() + " is shared by a jack source and a jack sink that give different "
                               "reconnect_backoff_s/reconnect_max (" + fmt_s(existing->policy_.backoff_s) + " s/" +
                               std::to_string(existing->policy_.max_attempts) + " vs " + fmt_s(policy.backoff_s) +
                               " s/" + std::to_string(policy.max_attempts) + "): give both the same values");
    }
    return existing;
  }
  jack_client_t* jc = nullptr;
  jack_status_t status{};
  std::string libjack_says;
  {
    QuietJack quiet;
    jc = open_client(server, client_name, &status);
    libjack_says = quiet.messages();
  }
  if (jc == nullptr) {
    log.debug("libjack: " + libjack_says);
    throw std::runtime_error(describe_open_status(static_cast<unsigned>(status), resolved, client_name));
  }
  const double rate = static_cast<double>(jack_get_sample_rate(jc));
  std::shared_ptr<SharedJackClient> client(new SharedJackClient(server, client_name, policy, rate));
  {
    std::lock_guard lock(client->mu_);
    client->jc_.store(jc, std::memory_order_release);
    client->install_callbacks_locked();
    client->buffer_frames_.store(jack_get_buffer_size(jc), std::memory_order_relaxed);
  }
  client->supervisor_ = std::thread([c = client.get()] { c->supervise(); });
  slot = client;
  log.info("opened " + client->describe() + " at " + fmt_s(rate) + " Hz, " + std::to_string(jack_get_buffer_size(jc)) +
           "-frame periods");
  return client;
}

SharedJackClient::~SharedJackClient() {
  {
    std::lock_guard lock(mu_);
    quit_ = true;
  }
  cv_.notify_all();
  if (supervisor_.joinable()) supervisor_.join();
  std::lock_guard reg_lock(registry_mutex());  // a new client of the same name waits for the close
  if (jack_client_t* jc = jc_.exchange(nullptr)) {
    QuietJack quiet;
    if (activated_) jack_deactivate(jc);
    jack_client_close(jc);
  }
  auto& reg = registry();
  const auto it = reg.find(registry_key(server_, client_name_));
  if (it != reg.end() && it->second.expired()) reg.erase(it);
}

std::string SharedJackClient::describe() const {
  return "JACK client '" + client_name_ + "' on server '" + server_ + "'";
}

std::string SharedJackClient::error() const {
  std::lock_guard lock(mu_);
  return error_;
}

// ---------------------------------------------------------------- libjack callbacks

int SharedJackClient::on_process(std::uint32_t nframes, void* arg) noexcept {
  auto* self = static_cast<SharedJackClient*>(arg);
  self->processor_.begin_cycle();
  jack_client_t* jc = self->jc_.load(std::memory_order_acquire);
  const std::uint32_t n_in = self->capture_.port_count.load(std::memory_order_acquire);
  const std::uint32_t n_out = self->playback_.port_count.load(std::memory_order_acquire);
  for (std::uint32_t i = 0; i < n_in; ++i)
    self->in_bufs_[i] = static_cast<const float*>(jack_port_get_buffer(self->capture_.ports[i], nframes));
  for (std::uint32_t i = 0; i < n_out; ++i)
    self->out_bufs_[i] = static_cast<float*>(jack_port_get_buffer(self->playback_.ports[i], nframes));
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  const std::int64_t now_ns = static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
  const std::uint32_t frame_time = jc != nullptr ? jack_last_frame_time(jc) : 0;
  // The time base (frame_zero_monotonic_s): the cycle began at server frame time `frame_time`, i.e. at
  // jack_frames_to_time() on jack_get_time()'s clock; `offset_us` maps that clock to CLOCK_MONOTONIC.
  // Published before the cycle's frames reach the ring (first cycle: no frame is lost before it, so
  // frame() is this cycle's first frame), and exactly after it (a skip found in this cycle moved it).
  double cycle_start_s = std::numeric_limits<double>::quiet_NaN();
  if (jc != nullptr) {
    const double offset_us = static_cast<double>(now_ns) * 1e-3 - static_cast<double>(jack_get_time());
    cycle_start_s = (static_cast<double>(jack_frames_to_time(jc, frame_time)) + offset_us) * 1e-6;
    if (std::isnan(self->frame_zero_s_.load(std::memory_order_relaxed))) {
      self->frame_zero_s_.store(
          cycle_start_s - static_cast<double>(self->processor_.frame()) / self->processor_.sample_rate_hz(),
          std::memory_order_release);
    }
  }
  self->processor_.process(self->in_bufs_.data(), n_in, self->out_bufs_.data(), n_out, nframes, frame_time, now_ns);
  if (!std::isnan(cycle_start_s)) {
    const double first = static_cast<double>(self->processor_.frame() - nframes);  // this cycle's first frame
    self->frame_zero_s_.store(cycle_start_s - first / self->processor_.sample_rate_hz(), std::memory_order_release);
  }
  self->processor_.end_cycle();
  return 0;
}

int SharedJackClient::on_xrun(void* arg) noexcept {
  static_cast<SharedJackClient*>(arg)->processor_.count_xrun();
  return 0;
}

void SharedJackClient::on_shutdown(int code, const char* reason, void* arg) noexcept {
  auto* self = static_cast<SharedJackClient*>(arg);
  if (!self->down_.load(std::memory_order_acquire)) {
    std::snprintf(self->down_reason_.data(), self->down_reason_.size(), "%s, code 0x%x",
                  reason != nullptr ? reason : "no reason given", static_cast<unsigned>(code));
  }
  self->down_.store(true, std::memory_order_release);
}

void SharedJackClient::on_port_registration(std::uint32_t, int registered, void* arg) noexcept {
  if (registered != 0) static_cast<SharedJackClient*>(arg)->ports_changed_.store(true, std::memory_order_release);
}

void SharedJackClient::install_callbacks_locked() {
  jack_client_t* jc = jc_.load(std::memory_order_relaxed);
  jack_set_process_callback(jc, [](jack_nframes_t n, void* a) { return on_process(n, a); }, this);
  jack_set_xrun_callback(jc, [](void* a) { return on_xrun(a); }, this);
  jack_on_info_shutdown(jc, [](jack_status_t c, const char* r, void* a) { on_shutdown(static_cast<int>(c), r, a); },
                        this);
  jack_set_port_registration_callback(jc, [](jack_port_id_t p, int reg, void* a) { on_port_registration(p, reg, a); },
                                      this);
}

// ---------------------------------------------------------------- parts

Logger* SharedJackClient::logger_locked() noexcept {
  if (capture_.log != nullptr) return capture_.log;
  return playback_.log;
}

void SharedJackClient::log_locked(LogLevel level, const std::string& message) {
  if (Logger* l = logger_locked()) l->log(level, message);
}

void SharedJackClient::register_ports_locked(Part part) {
  PartState& st = state(part);
  jack_client_t* jc = jc_.load(std::memory_order_relaxed);
  const bool capture = part == Part::Capture;
  const unsigned long flags = (capture ? JackPortIsInput : JackPortIsOutput) | JackPortIsTerminal;
  for (std::uint32_t i = 0; i < st.channels; ++i) {
    const std::string name = (capture ? "in_" : "out_") + std::to_string(i + 1);
    jack_port_t* p = nullptr;
    {
      QuietJack quiet;
      p = jack_port_register(jc, name.c_str(), JACK_DEFAULT_AUDIO_TYPE, flags, 0);
    }
    if (p == nullptr) {
      for (std::uint32_t k = 0; k < i; ++k) jack_port_unregister(jc, st.ports[k]);
      st.ports.fill(nullptr);
      st.port_count.store(0, std::memory_order_release);
      throw std::runtime_error(describe() + ": the server refused to register port '" + client_name_ + ":" + name + "'");
    }
    st.ports[i] = p;
  }
  st.port_count.store(st.channels, std::memory_order_release);
}

void SharedJackClient::attach(Part part, std::uint32_t channels, const std::string& connect_pattern, Logger& log) {
  std::lock_guard lock(mu_);
  if (failed_.load(std::memory_order_acquire)) throw std::runtime_error(error_);
  PartState& st = state(part);
  if (st.attached) {
    throw std::runtime_error(describe() + " already has " + (part == Part::Capture ? "a jack source" : "a jack sink") +
                             ": one source and one sink at most may share a client (give another client_name)");
  }
  if (channels == 0 || channels > kMaxPorts)
    throw std::runtime_error("channels must be 1.." + std::to_string(kMaxPorts) + " (got " + std::to_string(channels) + ")");
  st.channels = channels;
  st.pattern = connect_pattern;
  st.log = &log;
  st.warned_few = false;
  if (jc_.load(std::memory_order_relaxed) != nullptr) register_ports_locked(part);  // else at reconnection
  st.attached = true;
  if (activated_) connect_locked(part);
}

void SharedJackClient::detach(Part part) noexcept {
  stop(part);
  std::lock_guard lock(mu_);
  PartState& st = state(part);
  if (!st.attached) return;
  st.port_count.store(0, std::memory_order_release);
  processor_.quiesce();
  if (jack_client_t* jc = jc_.load(std::memory_order_relaxed)) {
    QuietJack quiet;
    for (std::uint32_t i = 0; i < st.channels; ++i)
      if (st.ports[i] != nullptr) jack_port_unregister(jc, st.ports[i]);
  }
  st.ports.fill(nullptr);
  st.attached = false;
  if (st.log != nullptr) {
    st.log->info(describe() + (part == Part::Capture ? " (capture)" : " (playback)") + ": " +
                 std::to_string(processor_.xruns()) + " xruns, " + std::to_string(processor_.frames_lost()) +
                 " frames lost (" + std::to_string(processor_.skip_events()) + " skipped-cycle events, " +
                 std::to_string(processor_.resumes()) + " outages), " + std::to_string(reconnects()) + " reconnects");
  }
  st.log = nullptr;
}

void SharedJackClient::start_capture(AudioRing& ring) {
  std::lock_guard lock(mu_);
  if (failed_.load(std::memory_order_acquire)) throw std::runtime_error(error_);
  if (!capture_.attached) throw std::runtime_error(describe() + ": start before open");
  if (capture_.started) return;
  if (ring.channels() != capture_.channels) {
    throw std::runtime_error(describe() + ": the ring has " + std::to_string(ring.channels()) +
                             " channels but the source has " + std::to_string(capture_.channels) + " ports");
  }
  if (!playback_.started) first_start_ = SteadyClock::now();
  processor_.attach_capture(&ring);
  capture_.started = true;
  cv_.notify_all();
}

void SharedJackClient::start_playback(PlaybackScheduler& scheduler) {
  std::lock_guard lock(mu_);
  if (failed_.load(std::memory_order_acquire)) throw std::runtime_error(error_);
  if (!playback_.attached) throw std::runtime_error(describe() + ": start before open");
  if (playback_.started) return;
  if (std::abs(scheduler.sample_rate_hz() - sample_rate_hz()) > 1e-6) {
    throw std::runtime_error(describe() + " runs at " + fmt_s(sample_rate_hz()) + " Hz but the playback stream is " +
                             fmt_s(scheduler.sample_rate_hz()) +
                             " Hz (the node's sample_rate_hz): run jackd at the node's rate");
  }
  if (!capture_.started) first_start_ = SteadyClock::now();
  processor_.attach_playback(&scheduler);
  playback_.started = true;
  cv_.notify_all();
}

void SharedJackClient::stop(Part part) noexcept {
  std::lock_guard lock(mu_);
  PartState& st = state(part);
  if (!st.started) return;
  if (part == Part::Capture) {
    processor_.detach_capture();
  } else {
    processor_.detach_playback();
  }
  st.started = false;
  cv_.notify_all();
}

// ---------------------------------------------------------------- supervisor

bool SharedJackClient::want_active_locked() const {
  const bool any = capture_.started || playback_.started;
  if (!any) return false;
  const bool all = (!capture_.attached || capture_.started) && (!playback_.attached || playback_.started);
  return all || seconds_since(first_start_) >= 0.5;
}

void SharedJackClient::connect_locked(Part part) {
  PartState& st = state(part);
  if (!st.attached || st.pattern.empty()) return;
  jack_client_t* jc = jc_.load(std::memory_order_relaxed);
  if (jc == nullptr) return;
  const bool capture = part == Part::Capture;
  std::vector<std::string> matches;
  {
    QuietJack quiet;
    const char** ports = jack_get_ports(jc, st.pattern.c_str(), JACK_DEFAULT_AUDIO_TYPE,
                                        capture ? JackPortIsOutput : JackPortIsInput);
    const std::string own = client_name_ + ":";
    for (const char** p = ports; p != nullptr && *p != nullptr; ++p)
      if (std::strncmp(*p, own.c_str(), own.size()) != 0) matches.emplace_back(*p);
    if (ports != nullptr) jack_free(ports);
  }
  const std::size_t n = std::min<std::size_t>(matches.size(), st.port_count.load(std::memory_order_relaxed));
  for (std::size_t i = 0; i < n; ++i) {
    const char* ours = jack_port_name(st.ports[i]);
    const std::string src = capture ? matches[i] : std::string(ours);
    const std::string dst = capture ? std::string(ours) : matches[i];
    int r = 0;
    {
      QuietJack quiet;
      r = jack_connect(jc, src.c_str(), dst.c_str());
    }
    if (r == 0) {
      log_locked(LogLevel::Info, "connected " + src + " -> " + dst);
    } else if (r != EEXIST) {
      log_locked(LogLevel::Warn, "cannot connect " + src + " -> " + dst + " (jack_connect returned " + std::to_string(r) + ")");
    }
  }
  if (matches.size() < st.channels && !st.warned_few) {
    st.warned_few = true;
    log_locked(LogLevel::Warn, "connect pattern '" + st.pattern + "' matches " + std::to_string(matches.size()) + " " +
                                   (capture ? "output" : "input") + " port(s) for " + std::to_string(st.channels) +
                                   " channel(s) of " + describe() + " for now (ports appearing later are connected then)");
  }
}

void SharedJackClient::activate_locked() {
  jack_client_t* jc = jc_.load(std::memory_order_relaxed);
  int r = 0;
  {
    QuietJack quiet;
    r = jack_activate(jc);
  }
  if (r != 0) {
    log_locked(LogLevel::Error, describe() + ": jack_activate failed (" + std::to_string(r) + "); reconnecting");
    std::snprintf(down_reason_.data(), down_reason_.size(), "jack_activate failed (%d)", r);
    down_.store(true, std::memory_order_release);
    return;
  }
  activated_ = true;
  running_.store(true, std::memory_order_release);
  ports_changed_.store(false, std::memory_order_release);
  connect_locked(Part::Capture);
  connect_locked(Part::Playback);
}

void SharedJackClient::deactivate_locked() {
  if (jack_client_t* jc = jc_.load(std::memory_order_relaxed)) {
    QuietJack quiet;
    jack_deactivate(jc);
  }
  activated_ = false;
  running_.store(false, std::memory_order_release);
}

void SharedJackClient::handle_down_locked() {
  down_handled_ = true;
  activated_ = false;
  running_.store(false, std::memory_order_release);
  buffer_frames_.store(0, std::memory_order_relaxed);
  const std::string reason(down_reason_.data());
  if (jack_client_t* jc = jc_.exchange(nullptr)) {
    QuietJack quiet;
    jack_client_close(jc);  // the dead client's threads end here; no callback runs afterwards
  }
  capture_.port_count.store(0, std::memory_order_release);
  playback_.port_count.store(0, std::memory_order_release);
  down_since_ = SteadyClock::now();
  attempts_ = 0;
  backoff_now_s_ = policy_.backoff_s;
  next_attempt_ = down_since_ + std::chrono::duration_cast<SteadyClock::duration>(
                                    std::chrono::duration<double>(backoff_now_s_));
  log_locked(LogLevel::Warn, describe() + ": the JACK server went away (" + reason + "); reconnecting from " +
                                 fmt_s(policy_.backoff_s) + " s backoff, " +
                                 (policy_.max_attempts > 0 ? "up to " + std::to_string(policy_.max_attempts) + " attempts"
                                                           : std::string("until stopped")));
}

void SharedJackClient::fail_locked(const std::string& message) {
  error_ = message;
  failed_.store(true, std::memory_order_release);
  log_locked(LogLevel::Error, message);
}

void SharedJackClient::try_reconnect_locked() {
  jack_status_t status{};
  jack_client_t* jc = nullptr;
  {
    QuietJack quiet;
    jc = open_client(server_arg_, client_name_, &status);
  }
  const auto now = SteadyClock::now();
  if (jc == nullptr) {
    ++attempts_;
    if (policy_.max_attempts > 0 && attempts_ >= policy_.max_attempts) {
      fail_locked(describe() + ": the JACK server did not come back after " + std::to_string(attempts_) +
                  " reconnection attempts over " + fmt_s(seconds_since(down_since_)) + " s (last: " +
                  describe_open_status(static_cast<unsigned>(status), server_, client_name_) + ")");
      return;
    }
    backoff_now_s_ = std::min(backoff_now_s_ * 2.0, std::max(policy_.backoff_s, 5.0));
    next_attempt_ = now + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(backoff_now_s_));
    return;
  }
  const double rate = static_cast<double>(jack_get_sample_rate(jc));
  if (std::abs(rate - sample_rate_hz()) > 1e-6) {
    {
      QuietJack quiet;
      jack_client_close(jc);
    }
    fail_locked(describe() + ": the JACK server came back at " + fmt_s(rate) + " Hz but the stream runs at " +
                fmt_s(sample_rate_hz()) + " Hz; cannot resume");
    return;
  }
  down_reason_.fill('\0');
  down_.store(false, std::memory_order_release);
  down_handled_ = false;
  jc_.store(jc, std::memory_order_release);
  install_callbacks_locked();
  buffer_frames_.store(jack_get_buffer_size(jc), std::memory_order_relaxed);
  for (Part p : {Part::Capture, Part::Playback}) {
    PartState& st = state(p);
    st.warned_few = false;
    if (!st.attached) continue;
    try {
      register_ports_locked(p);
    } catch (const std::exception& e) {
      log_locked(LogLevel::Error, e.what());
    }
  }
  processor_.mark_reconnected();
  reconnects_.fetch_add(1, std::memory_order_relaxed);
  log_locked(LogLevel::Info, describe() + ": the JACK server is back after " + fmt_s(seconds_since(down_since_)) +
                                 " s (" + std::to_string(attempts_ + 1) + " attempt(s)); resuming");
  activate_locked();
}

void SharedJackClient::supervise() {
  std::unique_lock lock(mu_);
  while (!quit_) {
    cv_.wait_for(lock, std::chrono::milliseconds(20));
    if (quit_) break;
    if (down_.load(std::memory_order_acquire) && !down_handled_) handle_down_locked();
    if (failed_.load(std::memory_order_acquire)) continue;
    const bool want = want_active_locked();
    if (jc_.load(std::memory_order_relaxed) == nullptr) {
      if (want && SteadyClock::now() >= next_attempt_) try_reconnect_locked();
    } else if (want && !activated_) {
      activate_locked();
    } else if (!want && activated_) {
      deactivate_locked();
    }
    if (activated_ && ports_changed_.exchange(false, std::memory_order_acq_rel)) {
      connect_locked(Part::Capture);
      connect_locked(Part::Playback);
    }
    const std::uint64_t resumes = processor_.resumes();
    if (resumes != resumes_logged_) {
      resumes_logged_ = resumes;
      const std::uint64_t gap = processor_.last_resume_gap_frames();
      log_locked(LogLevel::Warn, describe() + ": stream resumed; " + std::to_string(gap) + " frames (" +
                                     fmt_s(static_cast<double>(gap) / sample_rate_hz()) +
                                     " s) lost during the outage, reported as a gap; frame counter now " +
                                     std::to_string(processor_.frame()));
    }
  }
}

}  // namespace locus::hal::jack
