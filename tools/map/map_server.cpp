#include "map_server.hpp"

#include <algorithm>
#include <httplib.h>

#include <arpa/inet.h>
#include <sys/socket.h>
#include <ctime>

#include <chrono>
#include <cstring>
#include <string_view>

#include "locus/json_events.hpp"
#include "map_assets.hpp"

namespace locus::map {

namespace {

std::string fmt_host_port(const std::string& host, int port) {
  const bool v6 = host.find(':') != std::string::npos;
  return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

/// seconds -> (sec, usec) for cpp-httplib's timeouts.
std::pair<time_t, time_t> split_s(double s) {
  const auto sec = static_cast<time_t>(s);
  return {sec, static_cast<time_t>((s - static_cast<double>(sec)) * 1e6)};
}

}  // namespace

ParamSchema map_schema() {
  return {
      int_param("max_clients", std::int64_t{8}, 1, 256, "", "Event streams (open pages) served at once; one more gets 503."),
      float_param("read_timeout_s", 5.0, 0.1, 300.0, "s", "A client that sends nothing this long in the middle of a request is disconnected."),
      float_param("write_timeout_s", 5.0, 0.1, 300.0, "s", "A client that reads nothing this long is disconnected (a slow page never holds events up)."),
      int_param("backlog", std::int64_t{1024}, 16, 1 << 20, "", "Stream messages kept for clients that are behind; one further behind reloads the state."),
      int_param("trace_points", std::int64_t{300}, 1, 100000, "", "Positions kept per estimated target (its trace on the map)."),
      int_param("tap_capacity", std::int64_t{4096}, 16, 1 << 20, "", "Events each pipeline hands over to the map before it drops (counted)."),
      float_param("health_period_s", 0.5, 0.05, 60.0, "s", "How often device health (frames lost, xruns, link) is refreshed on the page."),
      float_param("linger_s", 0.0, 0.0, 86400.0, "s", "Keep serving the map this long after the run ended (a replay), or until SIGINT/SIGTERM."),
      string_param("events", std::string("estimate,audio_detection"), "Comma-separated event types the map receives and streams (estimate and audio_detection feed the map and the SNR column)."),
      string_param("title", std::string("Locus"), "Page title."),
  };
}

bool is_loopback(const std::string& host) {
  if (host == "localhost") return true;
  in_addr a4{};
  if (inet_pton(AF_INET, host.c_str(), &a4) == 1) return (ntohl(a4.s_addr) >> 24) == 127;
  in6_addr a6{};
  if (inet_pton(AF_INET6, host.c_str(), &a6) == 1) return IN6_IS_ADDR_LOOPBACK(&a6);
  return false;
}

MapOptions map_options(const std::string& listen, const Params& params) {
  MapOptions o;
  std::string port_text = listen;
  if (!listen.empty() && listen.front() == '[') {
    const auto close = listen.find(']');
    if (close == std::string::npos || close + 1 >= listen.size() || listen[close + 1] != ':') {
      throw MapError("--http: '" + listen + "': expected PORT, HOST:PORT or [IPV6]:PORT");
    }
    o.host = listen.substr(1, close - 1);
    port_text = listen.substr(close + 2);
  } else if (const auto colon = listen.rfind(':'); colon != std::string::npos) {
    if (listen.find(':') != colon) throw MapError("--http: '" + listen + "': write an IPv6 address as [ADDR]:PORT");
    o.host = listen.substr(0, colon);
    port_text = listen.substr(colon + 1);
    if (o.host.empty()) throw MapError("--http: '" + listen + "': empty host (omit it for 127.0.0.1)");
  }
  if (port_text.empty() || port_text.find_first_not_of("0123456789") != std::string::npos || port_text.size() > 5 ||
      std::stoi(port_text) > 65535) {
    throw MapError("--http: '" + listen + "': the port must be a number in [0, 65535] (0 = any free port)");
  }
  o.port = std::stoi(port_text);
  if (o.host != "localhost") {
    in_addr a4{};
    in6_addr a6{};
    if (inet_pton(AF_INET, o.host.c_str(), &a4) != 1 && inet_pton(AF_INET6, o.host.c_str(), &a6) != 1) {
      throw MapError("--http: '" + o.host + "' is not an IP address (give the address to listen on, e.g. 127.0.0.1 or 0.0.0.0)");
    }
  }
  o.max_clients = static_cast<int>(params.get_int("max_clients"));
  o.read_timeout_s = params.get_float("read_timeout_s");
  o.write_timeout_s = params.get_float("write_timeout_s");
  o.backlog = static_cast<int>(params.get_int("backlog"));
  o.trace_points = static_cast<int>(params.get_int("trace_points"));
  o.tap_capacity = static_cast<int>(params.get_int("tap_capacity"));
  o.health_period_s = params.get_float("health_period_s");
  o.linger_s = params.get_float("linger_s");
  o.title = params.get_string("title");
  o.events.clear();
  std::string_view rest = params.get_string("events");
  while (!rest.empty()) {
    const auto comma = rest.find(',');
    std::string_view name = rest.substr(0, comma);
    while (!name.empty() && name.front() == ' ') name.remove_prefix(1);
    while (!name.empty() && name.back() == ' ') name.remove_suffix(1);
    EventType t{};
    if (!event_type_from_name(name, t)) {
      std::string known;
      for (std::size_t i = 0; i < kEventTypeCount; ++i) known += (i ? ", " : "") + std::string(event_type_name(static_cast<EventType>(i)));
      throw MapError("--http-param events: unknown event type '" + std::string(name) + "' (known: " + known + ")");
    }
    bool seen = false;
    for (EventType e : o.events) seen |= e == t;
    if (!seen) o.events.push_back(t);
    if (comma == std::string_view::npos) break;
    rest.remove_prefix(comma + 1);
  }
  if (o.events.empty()) throw MapError("--http-param events: name at least one event type (e.g. estimate)");
  return o;
}

bool EventTap::push(const Event& event) noexcept {
  TappedEvent t;
  t.event = event;
  t.mono_ns = mono_ns();
  if (queue_.try_push(t)) return true;
  dropped_.fetch_add(1, std::memory_order_relaxed);
  return false;
}

MapServer::MapServer(MapOptions options, Logger& log)
    : opt_(std::move(options)), log_(log), http_(std::make_unique<httplib::Server>()), state_(opt_.trace_points) {
  state_.set_title(opt_.title);
  // One pool thread per event stream, plus a few for pages, state and assets.
  const std::size_t threads = static_cast<std::size_t>(opt_.max_clients) + 4;
  http_->new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  const auto [rs, rus] = split_s(opt_.read_timeout_s);
  const auto [ws, wus] = split_s(opt_.write_timeout_s);
  http_->set_read_timeout(rs, rus);
  http_->set_write_timeout(ws, wus);
  http_->set_keep_alive_timeout(std::max<time_t>(1, rs));
  http_->set_payload_max_length(64 * 1024);
  // SO_REUSEADDR only: cpp-httplib's default also sets SO_REUSEPORT, with which a second locusd would
  // silently share the port instead of failing.
  http_->set_socket_options([](int sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });  // no route takes a body; a large one is refused (413)
  routes();
  if (opt_.port == 0) {
    port_ = http_->bind_to_any_port(opt_.host);
    if (port_ <= 0) {
      throw MapError("map: cannot listen on " + fmt_host_port(opt_.host, 0) + ": " + std::strerror(errno));
    }
  } else {
    if (!http_->bind_to_port(opt_.host, opt_.port)) {
      throw MapError("map: cannot listen on " + fmt_host_port(opt_.host, opt_.port) + ": " + std::strerror(errno));
    }
    port_ = opt_.port;
  }
  if (!is_loopback(opt_.host)) {
    log_.warn("listening on " + fmt_host_port(opt_.host, port_) +
              ", reachable from other machines; the map has no authentication (use 127.0.0.1 and an SSH tunnel or a "
              "reverse proxy with TLS and a password)");
  }
}

MapServer::~MapServer() { stop(); }

std::string MapServer::url() const { return "http://" + fmt_host_port(opt_.host, port_) + "/"; }

EventTap& MapServer::add_tap(const std::string& node) {
  taps_.push_back(std::make_unique<EventTap>(node, static_cast<std::size_t>(opt_.tap_capacity)));
  return *taps_.back();
}

void MapServer::attach(const std::string& node, Pipeline& pipeline) {
  EventTap* tap = &add_tap(node);
  for (EventType t : opt_.events) {
    pipeline.subscribe(t, [tap](const Event& e) { tap->push(e); });
  }
  std::lock_guard lock(mutex_);
  for (const DeviceStats& s : pipeline.live_stats()) state_.add_device(node, s.id);
}

namespace {

/// The host name of a Host header ("127.0.0.1:8080" -> "127.0.0.1", "[::1]:80" -> "::1").
std::string host_name(const std::string& header) {
  if (!header.empty() && header.front() == '[') {
    const auto close = header.find(']');
    return close == std::string::npos ? header : header.substr(1, close - 1);
  }
  const auto colon = header.find(':');
  return colon == std::string::npos ? header : header.substr(0, colon);
}

}  // namespace

void MapServer::routes() {
  // DNS rebinding: a web page from elsewhere could point its own host name at 127.0.0.1 and read the
  // map through the visitor's browser. A map bound to loopback therefore answers only requests whose
  // Host names a loopback address or localhost (any port: SSH tunnels change it).
  if (is_loopback(opt_.host)) {
    http_->set_pre_routing_handler([](const httplib::Request& req, httplib::Response& res) {
      const std::string host = host_name(req.get_header_value("Host"));
      if (is_loopback(host)) return httplib::Server::HandlerResponse::Unhandled;
      res.status = 403;
      res.set_content("forbidden: Host '" + host + "' is not a loopback address (the map listens on loopback only)\n",
                      "text/plain");
      return httplib::Server::HandlerResponse::Handled;
    });
  }
  for (std::size_t i = 0; i < kAssetCount; ++i) {
    const Asset& a = kAssets[i];
    const std::string path = a.path == "index.html" ? "/" : "/" + std::string(a.path);
    http_->Get(path, [&a](const httplib::Request&, httplib::Response& res) {
      res.set_header("Cache-Control", "no-cache");
      res.set_header("X-Content-Type-Options", "nosniff");
      res.set_content(a.body.data(), a.body.size(), std::string(a.content_type).c_str());
    });
  }
  http_->Get("/api/state", [this](const httplib::Request&, httplib::Response& res) {
    nlohmann::ordered_json s = snapshot();
    res.set_header("Cache-Control", "no-store");
    res.set_content(s.dump(), "application/json");
  });
  http_->Get("/healthz", [](const httplib::Request&, httplib::Response& res) { res.set_content("ok\n", "text/plain"); });
  http_->Get("/events", [this](const httplib::Request& req, httplib::Response& res) {
    std::uint64_t start = 0;
    {
      std::lock_guard lock(mutex_);
      if (stats_.clients_now >= static_cast<std::uint64_t>(opt_.max_clients)) {
        ++stats_.clients_refused;
        res.status = 503;
        res.set_header("Retry-After", "5");
        res.set_content("too many event streams (max_clients = " + std::to_string(opt_.max_clients) + ")\n", "text/plain");
        return;
      }
      ++stats_.clients_now;
      ++stats_.clients_total;
      start = seq_;
      // A reconnecting EventSource says where it was (Last-Event-ID); the page opens the stream with
      // ?after=SEQ, the seq of the state it loaded, so that nothing falls between the two.
      std::string id;
      if (req.has_header("Last-Event-ID")) id = req.get_header_value("Last-Event-ID");
      else if (req.has_param("after")) id = req.get_param_value("after");
      {
        if (!id.empty() && id.size() < 20 && id.find_first_not_of("0123456789") == std::string::npos) {
          const std::uint64_t last = std::stoull(id);
          if (last <= seq_) start = last;
        }
      }
    }
    auto last = std::make_shared<std::uint64_t>(start);
    {
      std::lock_guard lock(mutex_);
      streams_.insert(last);
    }
    res.set_header("Cache-Control", "no-store");
    res.set_header("X-Accel-Buffering", "no");
    res.set_chunked_content_provider(
        "text/event-stream",
        [this, last](std::size_t, httplib::DataSink& sink) {
          std::string out;
          {
            std::unique_lock lock(mutex_);
            changed_.wait_for(lock, std::chrono::seconds(1), [&] { return stopping_ || seq_ > *last; });
            if (stopping_) return false;
            if (seq_ > *last) {
              if (backlog_.empty() || backlog_.front().seq > *last + 1) {
                // Fell behind the backlog: the page reloads /api/state and continues from now.
                ++stats_.resets;
                out = "id: " + std::to_string(seq_) + "\nevent: reset\ndata: {}\n\n";
              } else {
                // backlog_ holds consecutive seqs: the first message after *last is at this index.
                const std::size_t first = static_cast<std::size_t>(*last + 1 - backlog_.front().seq);
                for (std::size_t i = first; i < backlog_.size(); ++i) out += backlog_[i].text;
              }
              *last = seq_;
            }
          }
          if (out.empty()) out = ": keep-alive\n\n";  // also how a vanished client is noticed
          const bool ok = sink.write(out.data(), out.size());
          changed_.notify_all();  // stop() waits for every stream to have sent what it had
          return ok;
        },
        [this, last](bool) {
          std::lock_guard lock(mutex_);
          --stats_.clients_now;
          streams_.erase(last);
        });
  });
  http_->set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    std::string what;
    switch (res.status) {
      case 404: what = "not found: " + req.path + " (the map is /; its data /api/state and /events)"; break;
      case 400: what = "bad request"; break;
      case 413: what = "request body too large"; break;
      case 414: what = "request URI too long"; break;
      default: what = "error " + std::to_string(res.status); break;
    }
    res.set_content(what + "\n", "text/plain");
  });
  http_->set_exception_handler([this](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
    std::string what = "unknown error";
    try {
      if (ep) std::rethrow_exception(ep);
    } catch (const std::exception& e) {
      what = e.what();
    } catch (...) {
    }
    log_.error(req.path + ": " + what);
    res.status = 500;
    res.set_content("internal error\n", "text/plain");
  });
}

void MapServer::start() {
  if (started_) return;
  started_ = true;
  pump_thread_ = std::thread([this] { pump(); });
  http_thread_ = std::thread([this] { http_->listen_after_bind(); });
  log_.info(url());
}

void MapServer::stop() {
  if (!started_) return;
  started_ = false;
  // What was handed over before stop() (a node's final estimates, published as it stops) reaches the
  // open streams: the pump stops, the taps are drained once more here (their only consumer now), and
  // every open stream gets up to kStopFlush to send the backlog up to that point; then they close.
  pump_stop_.store(true);
  if (pump_thread_.joinable()) pump_thread_.join();
  drain_taps();
  {
    std::unique_lock lock(mutex_);
    const std::uint64_t target = seq_;
    changed_.wait_for(lock, kStopFlush, [&] {
      return std::all_of(streams_.begin(), streams_.end(), [&](const auto& last) { return *last >= target; });
    });
    stopping_ = true;
  }
  changed_.notify_all();
  http_->stop();
  if (http_thread_.joinable()) http_thread_.join();
}

void MapServer::append_locked(std::string event_name, const nlohmann::ordered_json& data) {
  ++seq_;
  ++stats_.sse_messages;
  std::string text = "id: " + std::to_string(seq_) + "\nevent: " + event_name + "\ndata: ";
  text += data.dump();
  text += "\n\n";
  backlog_.push_back(Message{seq_, std::move(text)});
  while (backlog_.size() > static_cast<std::size_t>(opt_.backlog)) backlog_.pop_front();
}

void MapServer::post_json(const std::string& node, const nlohmann::ordered_json& event, std::int64_t ns) {
  {
    std::lock_guard lock(mutex_);
    if (!state_.add_event(node, event)) return;
    ++stats_.events;
    append_locked("locus", {{"node", node}, {"mono_ns", ns}, {"event", event}});
  }
  changed_.notify_all();
}

void MapServer::set_link_state(const std::string& node, const std::string& state) {
  std::lock_guard lock(mutex_);
  state_.set_link(node, state);
  health_dirty_ = true;
}

void MapServer::set_health(const std::string& node, const std::vector<DeviceStats>& stats) {
  std::lock_guard lock(mutex_);
  state_.set_health(node, stats);
  health_dirty_ = true;
}

void MapServer::set_status(const std::string& status, bool finished) {
  {
    std::lock_guard lock(mutex_);
    state_.set_status(status, finished);
    append_locked("status", {{"status", status}, {"finished", finished}});
  }
  changed_.notify_all();
}

void MapServer::drain_taps() {
  // JSON is made outside the lock; events are folded in under it, in tap order.
  std::vector<std::pair<const EventTap*, TappedEvent>> batch;
  for (const auto& tap : taps_) {
    TappedEvent t;
    while (batch.size() < 4096 && tap->pop(t)) batch.emplace_back(tap.get(), t);
  }
  if (batch.empty()) return;
  std::vector<nlohmann::ordered_json> json;
  json.reserve(batch.size());
  for (const auto& [tap, t] : batch) json.push_back(event_to_json(t.event));
  {
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < batch.size(); ++i) {
      const std::string& node = batch[i].first->node();
      if (!state_.add_event(node, json[i])) continue;
      ++stats_.events;
      append_locked("locus", {{"node", node}, {"mono_ns", batch[i].second.mono_ns}, {"event", std::move(json[i])}});
    }
  }
  changed_.notify_all();
}

void MapServer::pump() {
  auto next_health = std::chrono::steady_clock::now();
  while (!pump_stop_.load()) {
    drain_taps();
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_health) {
      next_health = now + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                              std::chrono::duration<double>(opt_.health_period_s));
      bool sent = false;
      {
        std::lock_guard lock(mutex_);
        if (health_dirty_) {
          health_dirty_ = false;
          append_locked("health", {{"devices", state_.devices_json()}});
          sent = true;
        }
      }
      if (sent) changed_.notify_all();
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // at most 5 ms added to an event's way
  }
  drain_taps();
}

MapServer::Stats MapServer::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = stats_;
  for (const auto& tap : taps_) s.tap_dropped += tap->dropped();
  return s;
}

nlohmann::ordered_json MapServer::snapshot() const {
  std::uint64_t dropped = 0;
  for (const auto& tap : taps_) dropped += tap->dropped();
  std::lock_guard lock(mutex_);
  nlohmann::ordered_json s = state_.snapshot();
  s["seq"] = seq_;
  s["tap_dropped"] = dropped;
  return s;
}

}  // namespace locus::map
