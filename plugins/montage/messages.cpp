// Encoding of the `montage` link messages (see messages.hpp). Pure functions, unit-tested alone.
#include "messages.hpp"

#include <cmath>
#include <iomanip>
#include <sstream>

namespace locus::plugins::montage {

namespace {

constexpr double kMaxAbsTime = 1e6;

template <class T>
std::optional<T> fail(std::string* why, const std::string& w) {
  if (why) *why = w;
  return std::nullopt;
}

bool finite_in(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

bool trailing(std::istringstream& is, std::string* why) {
  std::string rest;
  if (is >> rest) {
    if (why) *why = "trailing text '" + rest + "' after the message";
    return true;
  }
  return false;
}

std::ostringstream stream() {
  std::ostringstream os;
  os << std::setprecision(17);
  return os;
}

}  // namespace

std::string topic_round(std::string_view prefix, std::string_view device) {
  return std::string(prefix) + "/round/" + std::string(device);
}
std::string topic_step(std::string_view prefix, std::string_view device) {
  return std::string(prefix) + "/step/" + std::string(device);
}
std::string topic_progress(std::string_view prefix, std::string_view device) {
  return std::string(prefix) + "/progress/" + std::string(device);
}

std::string encode(const RoundMessage& m) {
  std::ostringstream os = stream();
  os << m.device << ' ' << m.tau_own_s << ' ' << m.self_m << ' ' << m.arrivals.size();
  for (const auto& [user, dt] : m.arrivals) os << ' ' << user << ' ' << dt;
  return os.str();
}

std::string encode(const StepMessage& m) {
  std::ostringstream os = stream();
  os << m.device << ' ' << m.tau_s << ' ' << m.t_s << ' ' << m.stride_m << ' ' << m.heading_rad << ' '
     << (m.offset_valid ? m.offset_rad : 0.0) << ' ' << (m.offset_valid ? 1 : 0);
  return os.str();
}

std::string encode(const ProgressMessage& m) {
  std::ostringstream os = stream();
  os << m.device << ' ' << m.tau_s;
  return os.str();
}

std::optional<RoundMessage> decode_round(std::string_view payload, std::string* why) {
  std::istringstream is{std::string(payload)};
  RoundMessage m;
  long long n = 0;
  if (!(is >> m.device)) return fail<RoundMessage>(why, "empty message (expected \"<device> <tau_own_s> <self_m> <n> [<user> <dt_s>]*n\")");
  if (!(is >> m.tau_own_s >> m.self_m >> n)) return fail<RoundMessage>(why, "expected tau_own_s self_m n after the device");
  if (!finite_in(m.tau_own_s, -kMaxAbsTime, kMaxAbsTime)) return fail<RoundMessage>(why, "tau_own_s not finite or beyond 1e6 s");
  if (!finite_in(m.self_m, 0.0, 10.0)) return fail<RoundMessage>(why, "self_m not in [0, 10] m");
  if (n < 0 || n > 64) return fail<RoundMessage>(why, "n = " + std::to_string(n) + " arrivals: expected 0..64");
  for (long long k = 0; k < n; ++k) {
    std::string user;
    double dt = 0.0;
    if (!(is >> user >> dt)) return fail<RoundMessage>(why, "expected " + std::to_string(n) + " (user, dt_s) pairs, got " + std::to_string(k));
    if (!finite_in(dt, -kMaxAbsTime, kMaxAbsTime)) return fail<RoundMessage>(why, "dt_s of '" + user + "' not finite or beyond 1e6 s");
    if (user == m.device) return fail<RoundMessage>(why, "an arrival of the device's own code ('" + user + "')");
    m.arrivals.emplace_back(std::move(user), dt);
  }
  if (trailing(is, why)) return std::nullopt;
  return m;
}

std::optional<StepMessage> decode_step(std::string_view payload, std::string* why) {
  std::istringstream is{std::string(payload)};
  StepMessage m;
  int valid = -1;
  if (!(is >> m.device)) return fail<StepMessage>(why, "empty message (expected \"<device> <tau_s> <t_s> <stride_m> <heading_rad> <offset_rad> <offset_valid>\")");
  if (!(is >> m.tau_s >> m.t_s >> m.stride_m >> m.heading_rad >> m.offset_rad >> valid))
    return fail<StepMessage>(why, "expected tau_s t_s stride_m heading_rad offset_rad offset_valid after the device");
  if (!finite_in(m.tau_s, -kMaxAbsTime, kMaxAbsTime) || !finite_in(m.t_s, -kMaxAbsTime, kMaxAbsTime))
    return fail<StepMessage>(why, "tau_s / t_s not finite or beyond 1e6 s");
  if (!finite_in(m.stride_m, 0.0, 5.0)) return fail<StepMessage>(why, "stride_m not in [0, 5] m");
  if (!finite_in(m.heading_rad, -1e4, 1e4) || !finite_in(m.offset_rad, -1e4, 1e4))
    return fail<StepMessage>(why, "heading_rad / offset_rad not finite");
  if (valid != 0 && valid != 1) return fail<StepMessage>(why, "offset_valid must be 0 or 1");
  m.offset_valid = valid == 1;
  if (trailing(is, why)) return std::nullopt;
  return m;
}

std::optional<ProgressMessage> decode_progress(std::string_view payload, std::string* why) {
  std::istringstream is{std::string(payload)};
  ProgressMessage m;
  if (!(is >> m.device)) return fail<ProgressMessage>(why, "empty message (expected \"<device> <tau_s>\")");
  if (!(is >> m.tau_s)) return fail<ProgressMessage>(why, "expected tau_s after the device");
  if (!finite_in(m.tau_s, -kMaxAbsTime, kMaxAbsTime)) return fail<ProgressMessage>(why, "tau_s not finite or beyond 1e6 s");
  if (trailing(is, why)) return std::nullopt;
  return m;
}

}  // namespace locus::plugins::montage
