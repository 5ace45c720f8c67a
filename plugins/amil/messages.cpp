// AMIL link messages and arrival pairing: see messages.hpp.
#include "messages.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <limits>
#include <nlohmann/json.hpp>

#include "locus/ids.hpp"

namespace locus::plugins::amil {

namespace {

using json = nlohmann::ordered_json;

// Field readers: false with a reason when absent or of the wrong type.
bool get_string(const json& j, const char* key, std::string& out, std::string& err) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_string()) {
    err = std::string("field '") + key + "': expected a string";
    return false;
  }
  out = it->get<std::string>();
  return true;
}

bool get_number(const json& j, const char* key, double& out, std::string& err) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number() || !std::isfinite(it->get<double>())) {
    err = std::string("field '") + key + "': expected a finite number";
    return false;
  }
  out = it->get<double>();
  return true;
}

bool get_count(const json& j, const char* key, std::uint64_t& out, std::string& err) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number_unsigned()) {
    err = std::string("field '") + key + "': expected a non-negative integer";
    return false;
  }
  out = it->get<std::uint64_t>();
  return true;
}

}  // namespace

std::string topic_hello(std::string_view prefix, std::string_view listener) {
  return std::string(prefix) + "/hello/" + std::string(listener);
}
std::string topic_arrival(std::string_view prefix, std::string_view listener) {
  return std::string(prefix) + "/arrivals/" + std::string(listener);
}
std::string topic_done(std::string_view prefix, std::string_view listener) {
  return std::string(prefix) + "/done/" + std::string(listener);
}
std::string topic_filter(std::string_view prefix) { return std::string(prefix) + "/#"; }

std::string encode(const ArrivalMessage& m) {
  json j{{"type", "amil_arrival"}, {"listener", m.listener}, {"seq", m.seq},          {"frame", m.frame},
         {"sample_rate_hz", m.sample_rate_hz}, {"t_s", m.t_s()},      {"channel", m.channel}, {"snr_db", m.snr_db},
         {"confidence", m.confidence}};
  if (m.carrier_period > 0.0) {
    j["envelope_frame"] = m.envelope_frame;
    j["carrier_period"] = m.carrier_period;
  }
  return j.dump();
}
std::string encode(const DoneMessage& m) {
  return json{{"type", "amil_done"}, {"listener", m.listener}, {"arrivals", m.arrivals}}.dump();
}
std::string encode(const HelloMessage& m) {
  return json{{"type", "amil_hello"}, {"listener", m.listener}, {"channel", m.channel}, {"mic_offset_m", m.mic_offset_m}}
      .dump();
}

Decoded decode(std::string_view prefix, std::string_view topic, std::string_view payload) {
  Decoded out;
  const std::string head = std::string(prefix) + "/";
  if (topic.substr(0, head.size()) != head) {
    out.error = "topic is not under '" + head + "'";
    return out;
  }
  const std::string_view rest = topic.substr(head.size());
  const std::size_t slash = rest.find('/');
  if (slash == std::string_view::npos) {
    out.error = "topic: expected " + head + "<hello|arrivals|done>/<listener>";
    return out;
  }
  const std::string_view kind = rest.substr(0, slash);
  const std::string_view topic_listener = rest.substr(slash + 1);
  if (!valid_id(topic_listener)) {
    out.error = "topic: expected a device id after '" + head + std::string(kind) + "/'";
    return out;
  }
  const char* expected_type = kind == "hello" ? "amil_hello" : kind == "arrivals" ? "amil_arrival"
                              : kind == "done"  ? "amil_done"
                                                : nullptr;
  if (expected_type == nullptr) {
    out.error = "topic: unknown message kind '" + std::string(kind) + "' (expected hello, arrivals or done)";
    return out;
  }
  json j;
  try {
    j = json::parse(payload);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e400
    out.error = std::string("payload is not JSON: ") + e.what();
    return out;
  }
  if (!j.is_object()) {
    out.error = "payload: expected a JSON object";
    return out;
  }
  std::string type, listener, err;
  if (!get_string(j, "type", type, err) || !get_string(j, "listener", listener, err)) {
    out.error = "payload: " + err;
    return out;
  }
  if (type != expected_type) {
    out.error = "payload: type '" + type + "' on a '" + std::string(kind) + "' topic (expected '" + expected_type + "')";
    return out;
  }
  if (listener != topic_listener) {
    out.error = "payload: listener '" + listener + "' differs from the topic's '" + std::string(topic_listener) + "'";
    return out;
  }
  if (kind == "arrivals") {
    ArrivalMessage m;
    m.listener = listener;
    std::uint64_t channel = 0;
    if (!get_count(j, "seq", m.seq, err) || !get_number(j, "frame", m.frame, err) ||
        !get_number(j, "sample_rate_hz", m.sample_rate_hz, err) || !get_count(j, "channel", channel, err) ||
        !get_number(j, "snr_db", m.snr_db, err)) {
      out.error = "payload: " + err;
      return out;
    }
    if (!(m.sample_rate_hz > 0.0) || m.frame < 0.0 || channel > 0xffffu) {
      out.error = "payload: expected sample_rate_hz > 0, frame >= 0 and channel < 65536";
      return out;
    }
    if (j.contains("confidence")) {
      if (!get_number(j, "confidence", m.confidence, err) || m.confidence < 0.0 || m.confidence > 1.0) {
        out.error = "payload: field 'confidence': expected a number in [0, 1]";
        return out;
      }
    }
    if (j.contains("carrier_period") || j.contains("envelope_frame")) {
      if (!get_number(j, "carrier_period", m.carrier_period, err) || !get_number(j, "envelope_frame", m.envelope_frame, err) ||
          !(m.carrier_period > 0.0) || !(std::fabs(m.envelope_frame - m.frame) <= 64.0 * m.carrier_period)) {
        out.error = "payload: fields 'envelope_frame' and 'carrier_period': expected both, carrier_period > 0 and "
                    "envelope_frame within 64 periods of frame";
        return out;
      }
    }
    m.channel = static_cast<std::uint32_t>(channel);
    out.arrival = m;
  } else if (kind == "done") {
    DoneMessage m;
    m.listener = listener;
    if (!get_count(j, "arrivals", m.arrivals, err)) {
      out.error = "payload: " + err;
      return out;
    }
    out.done = m;
  } else {
    HelloMessage m;
    m.listener = listener;
    std::uint64_t channel = 0;
    if (!get_count(j, "channel", channel, err) || channel > 0xffffu) {
      out.error = "payload: " + (err.empty() ? std::string("field 'channel': expected an integer < 65536") : err);
      return out;
    }
    m.channel = static_cast<std::uint32_t>(channel);
    if (j.contains("mic_offset_m")) {
      if (!get_number(j, "mic_offset_m", m.mic_offset_m, err) || m.mic_offset_m < 0.0 || m.mic_offset_m > 10.0) {
        out.error = "payload: field 'mic_offset_m': expected a number in [0, 10] (metres)";
        return out;
      }
    }
    out.hello = m;
  }
  return out;
}

std::vector<double> match_arrivals(const std::vector<double>& beeps_s, const std::vector<double>& arrivals_s,
                                   double tolerance_s, int* matched) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> best(beeps_s.size(), nan);
  int best_count = 0;
  double best_spread = std::numeric_limits<double>::infinity();
  std::vector<double> sorted = arrivals_s;
  sorted.erase(std::remove_if(sorted.begin(), sorted.end(), [](double a) { return !std::isfinite(a); }), sorted.end());
  std::sort(sorted.begin(), sorted.end());
  std::vector<double> cand(beeps_s.size());
  std::vector<char> used(sorted.size());
  for (double b0 : beeps_s) {
    if (!std::isfinite(b0)) continue;
    for (double a0 : sorted) {
      const double offset = a0 - b0;
      std::fill(used.begin(), used.end(), 0);
      int count = 0;
      double sum = 0.0, sum2 = 0.0;
      for (std::size_t k = 0; k < beeps_s.size(); ++k) {
        cand[k] = nan;
        if (!std::isfinite(beeps_s[k])) continue;
        const double want = beeps_s[k] + offset;
        const auto it = std::lower_bound(sorted.begin(), sorted.end(), want - tolerance_s);
        std::size_t pick = sorted.size();
        double pick_err = tolerance_s;
        for (auto j = it; j != sorted.end() && *j <= want + tolerance_s; ++j) {
          const std::size_t idx = static_cast<std::size_t>(j - sorted.begin());
          if (!used[idx] && std::abs(*j - want) <= pick_err) {
            pick = idx;
            pick_err = std::abs(*j - want);
          }
        }
        if (pick == sorted.size()) continue;
        used[pick] = 1;
        cand[k] = sorted[pick];
        const double r = sorted[pick] - beeps_s[k];
        sum += r;
        sum2 += r * r;
        ++count;
      }
      const double spread = count > 0 ? std::sqrt(std::max(0.0, sum2 / count - (sum / count) * (sum / count))) : 0.0;
      if (count > best_count || (count == best_count && count > 0 && spread < best_spread)) {
        best_count = count;
        best_spread = spread;
        best = cand;
      }
    }
  }
  if (matched != nullptr) *matched = best_count;
  return best;
}

}  // namespace locus::plugins::amil
