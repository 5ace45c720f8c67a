// The `link` sync source (link_sync.hpp).
#include "radio/link_sync.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>
#include <stdexcept>

namespace locus::hal::radio {

namespace {

std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool valid_id(std::string_view s) noexcept {
  if (s.empty() || s.size() > NameTag::max_size()) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
  });
}

template <typename T>
bool parse_number(std::string_view s, T& out) noexcept {
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

std::vector<std::string> split_ids(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream ss(list);
  for (std::string item; std::getline(ss, item, ',');) {
    item.erase(0, item.find_first_not_of(' '));
    item.erase(item.find_last_not_of(' ') + 1);
    if (!valid_id(item))
      throw std::runtime_error("link sync: param 'sources': '" + item +
                               "' is not an id (expected ids of [A-Za-z0-9_-], at most 31 characters, separated by commas)");
    out.push_back(item);
  }
  return out;
}

}  // namespace

std::string encode_sync(const SyncMessage& m) {
  return m.source + " " + std::to_string(m.seq) + " " + std::to_string(m.sent_monotonic_ns);
}

std::optional<SyncMessage> decode_sync(std::string_view payload, std::string* why) {
  auto fail = [&](const std::string& reason) -> std::optional<SyncMessage> {
    if (why) *why = reason + " (expected '<source> <seq> <sent_monotonic_ns>')";
    return std::nullopt;
  };
  std::vector<std::string_view> parts;
  std::size_t i = 0;
  while (i <= payload.size()) {
    const std::size_t j = std::min(payload.find(' ', i), payload.size());
    parts.push_back(payload.substr(i, j - i));
    i = j + 1;
  }
  if (parts.size() != 3) return fail(std::to_string(parts.size()) + " fields separated by single spaces");
  SyncMessage m;
  if (!valid_id(parts[0])) return fail("source '" + std::string(parts[0]) + "' is not an id of [A-Za-z0-9_-] (at most 31)");
  m.source = std::string(parts[0]);
  if (!parse_number(parts[1], m.seq)) return fail("seq '" + std::string(parts[1]) + "' is not a non-negative integer");
  if (!parse_number(parts[2], m.sent_monotonic_ns) || m.sent_monotonic_ns < 0)
    return fail("sent_monotonic_ns '" + std::string(parts[2]) + "' is not a non-negative integer");
  return m;
}

std::string sync_topic(std::string_view prefix, std::string_view source) {
  return std::string(prefix) + "/" + std::string(source);
}

const ParamSchema& link_sync_schema() {
  static const ParamSchema s = {
      string_param("topic_prefix", std::string("sync"), "Link topic of the syncs: <topic_prefix>/<source>."),
      string_param("sources", std::string(""), "Senders whose syncs become RadioSync events, comma-separated ids; \"\" = any."),
      float_param("send_period_s", 0.0, 0.0, 3600.0, "s",
                  "Transmit (the radio role): one sync every this many seconds of CLOCK_MONOTONIC; 0 = receive only."),
      float_param("send_first_s", 1.0, 0.0, 3600.0, "s", "Transmit: the first sync this long after the epoch."),
      float_param("send_epoch_monotonic_s", 0.0, 0.0, 1e9, "s",
                  "Transmit: the schedule's epoch on CLOCK_MONOTONIC (several boards of one host share one: staggered "
                  "beacons stay staggered however their nodes start); 0 = when the source starts. Slots already past "
                  "at start are skipped."),
      int_param("send_count", std::int64_t{0}, 0, 1'000'000'000, "", "Transmit: this many syncs, then stop; 0 = until stopped."),
      string_param("send_as", std::string(""), "Transmit: the sender id in the topic and the message; \"\" = the device's id."),
  };
  return s;
}

struct LinkSyncSource::State {
  std::mutex mutex;
  SensorQueue* queue = nullptr;  ///< set while running (start() .. stop())
  DeviceId device;
  std::vector<std::string> sources;
  std::uint64_t received = 0, malformed = 0, ignored = 0, dropped = 0;
  std::string first_malformed;
  std::vector<double> latency_ms;  ///< per accepted message: sender's stamp -> arrival (same host only)
  std::vector<std::string> seen;   ///< sources heard

  void on_message(const LinkMessage& msg) {
    const std::int64_t now = monotonic_ns();
    std::string why;
    const std::optional<SyncMessage> m = decode_sync(msg.payload, &why);
    std::lock_guard lock(mutex);
    if (queue == nullptr) return;
    if (!m || msg.topic.substr(msg.topic.rfind('/') + 1) != m->source) {
      if (malformed++ == 0) first_malformed = msg.topic + ": " + (m ? "source is not the topic's last level" : why);
      return;
    }
    if (!sources.empty() && std::find(sources.begin(), sources.end(), m->source) == sources.end()) {
      ++ignored;
      return;
    }
    RadioSync ev;
    ev.device = device;
    ev.t_s = static_cast<double>(now) * 1e-9;
    ev.source = NameTag(m->source);
    if (!queue->try_push(Event{ev})) {
      queue->count_drop();
      ++dropped;
      return;
    }
    ++received;
    if (latency_ms.size() < 1'000'000) latency_ms.push_back(static_cast<double>(now - m->sent_monotonic_ns) * 1e-6);
    if (std::find(seen.begin(), seen.end(), m->source) == seen.end()) seen.push_back(m->source);
  }
};

LinkSyncSource::LinkSyncSource() : state_(std::make_shared<State>()) {}

LinkSyncSource::~LinkSyncSource() { stop(); }

void LinkSyncSource::open(const Params& params, HostContext& ctx) {
  link_ = &ctx.link;
  log_ = &ctx.log;
  device_ = std::string(ctx.device);
  prefix_ = params.get_string("topic_prefix");
  if (prefix_.empty() || prefix_.find_first_of("+#") != std::string::npos || prefix_.back() == '/')
    throw std::runtime_error("link sync: param 'topic_prefix': '" + prefix_ +
                             "' must be a non-empty topic without wildcards (+, #) or a trailing '/'");
  sources_ = params.get_string("sources").empty() ? std::vector<std::string>{} : split_ids(params.get_string("sources"));
  send_period_s_ = params.get_float("send_period_s");
  send_first_s_ = params.get_float("send_first_s");
  send_count_ = params.get_int("send_count");
  send_epoch_s_ = params.get_float("send_epoch_monotonic_s");
  send_as_ = params.get_string("send_as").empty() ? device_ : params.get_string("send_as");
  if (send_period_s_ > 0.0 && !valid_id(send_as_))
    throw std::runtime_error("link sync: param 'send_as': '" + send_as_ +
                             "' is not an id (expected [A-Za-z0-9_-], at most 31 characters)");
  if (send_period_s_ > 0.0 && send_period_s_ < 0.01)
    throw std::runtime_error("link sync: param 'send_period_s': expected 0 (receive only) or at least 0.01 s");
  state_->device = DeviceId(device_);
  state_->sources = sources_;
}

void LinkSyncSource::start(SensorQueue& queue) {
  {
    std::lock_guard lock(state_->mutex);
    state_->queue = &queue;
  }
  std::shared_ptr<State> st = state_;
  sub_ = link_->subscribe(prefix_ + "/+", [st](const LinkMessage& m) { st->on_message(m); });
  subscribed_ = true;
  if (send_period_s_ > 0.0) {
    std::lock_guard lock(thread_mutex_);
    stopping_ = false;
    thread_ = std::thread([this] { transmit(); });
  }
}

void LinkSyncSource::transmit() {
  using clock = std::chrono::steady_clock;  // CLOCK_MONOTONIC on Linux (libstdc++)
  const double now_s = static_cast<double>(monotonic_ns()) * 1e-9;
  const double epoch_s = send_epoch_s_ > 0.0 ? send_epoch_s_ : now_s;
  const clock::time_point t0 =
      clock::now() + std::chrono::duration_cast<clock::duration>(std::chrono::duration<double>(epoch_s - now_s));
  // the first slot not yet past (an epoch in the past skips the slots before now)
  std::uint64_t first = 0;
  if (const double behind = now_s - epoch_s - send_first_s_; behind > 0.0)
    first = static_cast<std::uint64_t>(std::ceil(behind / send_period_s_));
  std::unique_lock lock(thread_mutex_);
  for (std::uint64_t k = first; send_count_ == 0 || k < static_cast<std::uint64_t>(send_count_); ++k) {
    const auto due = t0 + std::chrono::duration_cast<clock::duration>(
                              std::chrono::duration<double>(send_first_s_ + static_cast<double>(k) * send_period_s_));
    if (wake_.wait_until(lock, due, [this] { return stopping_; })) return;
    lock.unlock();
    link_->publish(sync_topic(prefix_, send_as_), encode_sync(SyncMessage{send_as_, k, monotonic_ns()}));
    sent_.fetch_add(1, std::memory_order_relaxed);
    lock.lock();
  }
}

void LinkSyncSource::stop() {
  {
    std::lock_guard lock(thread_mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (subscribed_) {
    link_->unsubscribe(sub_);
    subscribed_ = false;
  }
  std::lock_guard lock(state_->mutex);
  if (state_->queue == nullptr) return;
  state_->queue = nullptr;
  if (log_ == nullptr) return;
  std::string lat = "no sync received";
  if (!state_->latency_ms.empty()) {
    std::vector<double> v = state_->latency_ms;
    std::sort(v.begin(), v.end());
    char buf[160];
    std::snprintf(buf, sizeof buf, "one-way latency (sender's CLOCK_MONOTONIC -> arrival; one host only) median %.3f ms, p90 %.3f ms, max %.3f ms",
                  v[v.size() / 2], v[std::min(v.size() - 1, v.size() * 9 / 10)], v.back());
    lat = buf;
  }
  std::string from;
  for (const std::string& s : state_->seen) from += (from.empty() ? "" : ",") + s;
  log_->info("link sync " + device_ + ": " + std::to_string(sent_.load()) + " sent as " + send_as_ + ", " +
             std::to_string(state_->received) + " received (from " + (from.empty() ? "none" : from) + "), " +
             std::to_string(state_->ignored) + " from other sources, " + std::to_string(state_->malformed) + " malformed, " +
             std::to_string(state_->dropped) + " dropped; " + lat);
  if (state_->malformed > 0) log_->warn("link sync " + device_ + ": first malformed message: " + state_->first_malformed);
}

std::uint64_t LinkSyncSource::sent() const noexcept { return sent_.load(std::memory_order_relaxed); }
std::uint64_t LinkSyncSource::received() const noexcept {
  std::lock_guard lock(state_->mutex);
  return state_->received;
}
std::uint64_t LinkSyncSource::malformed() const noexcept {
  std::lock_guard lock(state_->mutex);
  return state_->malformed;
}

void register_link_sync_source(Registry& registry) {
  registry.add_sensor_source(SensorSourceDescriptor{
      "link",
      "radio sync over the node's link (<topic_prefix>/<source> messages -> RadioSync at their arrival on "
      "CLOCK_MONOTONIC); optionally transmits the device's own syncs (send_period_s)",
      SensorKind::Sync,
      link_sync_schema(),
      [] { return std::unique_ptr<SensorSource>(std::make_unique<LinkSyncSource>()); },
  });
}

}  // namespace locus::hal::radio
