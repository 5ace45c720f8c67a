// TUM live roles, the maths and messages: see sync.hpp.
#include "sync.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

namespace locus::plugins::tum {

namespace {

using json = nlohmann::ordered_json;

double median(std::vector<double> v) {
  const std::size_t n = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n), v.end());
  if (v.size() % 2 == 1) return v[n];
  const double hi = v[n];
  return 0.5 * (*std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n)) + hi);
}

bool finite_number(const json& j, const char* key, double& out) {
  if (!j.contains(key) || !j[key].is_number()) return false;
  out = j[key].get<double>();
  return std::isfinite(out);
}

bool string_field(const json& j, const char* key, std::string& out) {
  if (!j.contains(key) || !j[key].is_string() || j[key].get<std::string>().empty()) return false;
  out = j[key].get<std::string>();
  return true;
}

}  // namespace

std::optional<ClockEstimate> estimate_clock(const std::vector<RoundTrip>& trips, int min_samples, int max_samples) {
  const std::size_t n = std::min(trips.size(), static_cast<std::size_t>(std::max(1, max_samples)));
  if (n == 0 || static_cast<int>(n) < min_samples) return std::nullopt;
  std::vector<double> offsets, rtts;
  for (std::size_t i = trips.size() - n; i < trips.size(); ++i) {
    const double rtt = trips[i].rtt_s();
    if (!(rtt >= 0.0) || !std::isfinite(trips[i].offset_s())) return std::nullopt;
    offsets.push_back(trips[i].offset_s());
    rtts.push_back(rtt);
  }
  ClockEstimate e;
  e.offset_s = median(offsets);
  e.rtt_s = median(rtts);
  std::vector<double> dev;
  for (double o : offsets) dev.push_back(std::abs(o - e.offset_s));
  e.spread_s = median(dev);
  e.samples = static_cast<int>(n);
  return e;
}

std::optional<Election> elect(const std::vector<SyncTable>& tables, double tie_s, const std::vector<std::string>& order) {
  std::map<std::string, const SyncTable*> by_id;
  for (const SyncTable& t : tables) by_id[t.device] = &t;
  std::map<std::string, std::size_t> rank;  // `order` first, then the others by id
  for (const std::string& id : order)
    if (by_id.count(id) && !rank.count(id)) rank[id] = rank.size();
  for (const auto& [id, t] : by_id)
    if (!rank.count(id)) rank[id] = rank.size();
  struct Pair {
    std::string a, b;  // a ranks better
    double rtt;
  };
  std::vector<Pair> pairs;
  for (auto ia = by_id.begin(); ia != by_id.end(); ++ia) {
    if (!ia->second->can_work) continue;
    for (auto ib = std::next(ia); ib != by_id.end(); ++ib) {
      if (!ib->second->can_work) continue;
      double rtt = -1.0;
      if (auto f = ia->second->peers.find(ib->first); f != ia->second->peers.end()) rtt = std::max(rtt, f->second.rtt_s);
      if (auto f = ib->second->peers.find(ia->first); f != ib->second->peers.end()) rtt = std::max(rtt, f->second.rtt_s);
      if (rtt < 0.0) continue;
      if (rank[ia->first] < rank[ib->first]) pairs.push_back({ia->first, ib->first, rtt});
      else pairs.push_back({ib->first, ia->first, rtt});
    }
  }
  if (pairs.empty()) return std::nullopt;
  double best = pairs.front().rtt;
  for (const Pair& p : pairs) best = std::min(best, p.rtt);
  const Pair* won = nullptr;
  for (const Pair& p : pairs)
    if (p.rtt <= best + tie_s &&
        (!won || std::make_pair(rank[p.a], rank[p.b]) < std::make_pair(rank[won->a], rank[won->b])))
      won = &p;
  return Election{won->a, won->b, won->rtt};
}

std::int64_t next_emission_index(double t0_s, double period_s, double after_s) {
  if (!(period_s > 0.0)) return 0;
  return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil((after_s - t0_s) / period_s - 1e-9)));
}

double tone2_delay_s(double delay_s, double jitter_s, std::int64_t k) {
  std::uint64_t z = static_cast<std::uint64_t>(k) + 0x9E3779B97F4A7C15ULL;  // splitmix64
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return delay_s + jitter_s * static_cast<double>(z >> 11) * 0x1.0p-53;
}

std::int64_t frame_for(double t_other_s, double peer_offset_s, double anchor_s, std::uint64_t anchor_frame, double rate_hz) {
  const double t_local = t_other_s - peer_offset_s;  // the other clock = ours + offset
  return static_cast<std::int64_t>(anchor_frame) + static_cast<std::int64_t>(std::llround((t_local - anchor_s) * rate_hz));
}

std::string topic_ping(std::string_view prefix, std::string_view from) {
  return std::string(prefix) + "/sync/ping/" + std::string(from);
}
std::string topic_pong(std::string_view prefix, std::string_view to) {
  return std::string(prefix) + "/sync/pong/" + std::string(to);
}
std::string topic_table(std::string_view prefix, std::string_view from) {
  return std::string(prefix) + "/sync/table/" + std::string(from);
}
std::string topic_role(std::string_view prefix) { return std::string(prefix) + "/role"; }

std::string encode(const Ping& m) {
  json j;
  j["type"] = "tum_ping";
  j["from"] = m.from;
  j["seq"] = m.seq;
  j["t0"] = m.t0_s;
  return j.dump();
}

std::string encode(const Pong& m) {
  json j;
  j["type"] = "tum_pong";
  j["from"] = m.from;
  j["to"] = m.to;
  j["seq"] = m.seq;
  j["t0"] = m.t0_s;
  j["t1"] = m.t1_s;
  j["t2"] = m.t2_s;
  return j.dump();
}

std::string encode(const SyncTable& m) {
  json j;
  j["type"] = "tum_table";
  j["from"] = m.device;
  j["can_work"] = m.can_work;
  json peers = json::object();
  for (const auto& [id, e] : m.peers) peers[id] = {{"offset", e.offset_s}, {"rtt", e.rtt_s}, {"spread", e.spread_s}, {"n", e.samples}};
  j["peers"] = peers;
  return j.dump();
}

std::string encode(const Role& m) {
  json j;
  j["type"] = "tum_role";
  j["device1"] = m.election.device1;
  j["device2"] = m.election.device2;
  j["rtt"] = m.election.rtt_s;
  j["t0"] = m.t0_s;
  j["period"] = m.period_s;
  j["delay"] = m.delay_s;
  return j.dump();
}

SyncDecoded decode_sync(std::string_view prefix, std::string_view topic, std::string_view payload) {
  SyncDecoded d;
  const std::string p(prefix);
  const std::string t(topic);
  json j;
  try {
    j = json::parse(payload);
  } catch (const json::exception& e) {
    d.error = std::string("not JSON: ") + e.what();
    return d;
  }
  if (!j.is_object() || !j.contains("type") || !j["type"].is_string()) {
    d.error = "expected an object with a string 'type'";
    return d;
  }
  const std::string type = j["type"].get<std::string>();
  const auto last = [&](const std::string& head) -> std::optional<std::string> {
    if (t.rfind(head, 0) != 0 || t.size() == head.size() || t.find('/', head.size()) != std::string::npos) return std::nullopt;
    return t.substr(head.size());
  };
  if (type == "tum_ping") {
    Ping m;
    const auto who = last(p + "/sync/ping/");
    if (!string_field(j, "from", m.from) || !finite_number(j, "t0", m.t0_s) || !j.contains("seq") || !j["seq"].is_number_unsigned())
      d.error = "tum_ping: expected from (string), seq (unsigned), t0 (finite number)";
    else if (!who || *who != m.from) d.error = "tum_ping: topic " + t + " does not end in its sender '" + m.from + "'";
    else m.seq = j["seq"].get<std::uint64_t>(), d.ping = m;
  } else if (type == "tum_pong") {
    Pong m;
    const auto who = last(p + "/sync/pong/");
    if (!string_field(j, "from", m.from) || !string_field(j, "to", m.to) || !finite_number(j, "t0", m.t0_s) ||
        !finite_number(j, "t1", m.t1_s) || !finite_number(j, "t2", m.t2_s) || !j.contains("seq") || !j["seq"].is_number_unsigned())
      d.error = "tum_pong: expected from, to (strings), seq (unsigned), t0, t1, t2 (finite numbers)";
    else if (!who || *who != m.to) d.error = "tum_pong: topic " + t + " does not end in its addressee '" + m.to + "'";
    else m.seq = j["seq"].get<std::uint64_t>(), d.pong = m;
  } else if (type == "tum_table") {
    SyncTable m;
    const auto who = last(p + "/sync/table/");
    if (!string_field(j, "from", m.device) || !j.contains("can_work") || !j["can_work"].is_boolean() || !j.contains("peers") ||
        !j["peers"].is_object()) {
      d.error = "tum_table: expected from (string), can_work (bool), peers (object)";
      return d;
    }
    if (!who || *who != m.device) {
      d.error = "tum_table: topic " + t + " does not end in its sender '" + m.device + "'";
      return d;
    }
    m.can_work = j["can_work"].get<bool>();
    for (const auto& [id, e] : j["peers"].items()) {
      ClockEstimate c;
      if (id.empty() || !e.is_object() || !finite_number(e, "offset", c.offset_s) || !finite_number(e, "rtt", c.rtt_s) ||
          !finite_number(e, "spread", c.spread_s) || !e.contains("n") || !e["n"].is_number_integer() || c.rtt_s < 0.0) {
        d.error = "tum_table: peers." + id + ": expected {offset, rtt >= 0, spread, n}";
        return d;
      }
      c.samples = e["n"].get<int>();
      m.peers[id] = c;
    }
    d.table = m;
  } else if (type == "tum_role") {
    Role m;
    if (t != p + "/role") d.error = "tum_role: expected on topic " + p + "/role, got " + t;
    else if (!string_field(j, "device1", m.election.device1) || !string_field(j, "device2", m.election.device2) ||
             !finite_number(j, "rtt", m.election.rtt_s) || !finite_number(j, "t0", m.t0_s) || !finite_number(j, "period", m.period_s) ||
             !finite_number(j, "delay", m.delay_s) || !(m.period_s > 0.0) || m.election.device1 == m.election.device2)
      d.error = "tum_role: expected device1, device2 (distinct strings), rtt, t0, period > 0, delay (finite numbers)";
    else d.role = m;
  } else {
    d.error = "unknown type '" + type + "'";
  }
  return d;
}

}  // namespace locus::plugins::tum
