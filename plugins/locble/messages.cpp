// Encoding of the `locble` link message (see messages.hpp). Pure functions, unit-tested alone.
#include "messages.hpp"

#include <cmath>
#include <cstdio>
#include <iomanip>
#include <sstream>

namespace locus::plugins::locble {

namespace {

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

std::string format_address(const std::array<std::uint8_t, 6>& address) {
  char buf[18];
  std::snprintf(buf, sizeof buf, "%02X:%02X:%02X:%02X:%02X:%02X", address[0], address[1], address[2], address[3],
                address[4], address[5]);
  return buf;
}

std::optional<std::array<std::uint8_t, 6>> parse_address(std::string_view text) {
  if (text.size() != 17) return std::nullopt;
  std::array<std::uint8_t, 6> a{};
  for (std::size_t i = 0; i < 6; ++i) {
    const int hi = hex_digit(text[3 * i]), lo = hex_digit(text[3 * i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    if (i < 5 && text[3 * i + 2] != ':') return std::nullopt;
    a[i] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  return a;
}

std::string encode(const TargetMotion& m) {
  std::ostringstream os;
  os << std::setprecision(17) << format_address(m.address) << ' ' << m.t_s << ' ' << m.east_m << ' ' << m.north_m;
  return os.str();
}

std::optional<TargetMotion> decode(std::string_view payload, std::string* why) {
  auto fail = [&](const std::string& w) -> std::optional<TargetMotion> {
    if (why) *why = w;
    return std::nullopt;
  };
  std::istringstream is{std::string(payload)};
  std::string addr;
  TargetMotion m;
  if (!(is >> addr)) return fail("empty message (expected \"<address> <t_s> <east_m> <north_m>\")");
  const auto a = parse_address(addr);
  if (!a) return fail("'" + addr + "' is not a BLE address (expected AA:BB:CC:DD:EE:FF)");
  m.address = *a;
  if (!(is >> m.t_s >> m.east_m >> m.north_m)) return fail("expected three numbers after the address: t_s east_m north_m");
  std::string rest;
  if (is >> rest) return fail("trailing text '" + rest + "' after the message");
  if (!std::isfinite(m.t_s) || !std::isfinite(m.east_m) || !std::isfinite(m.north_m)) return fail("non-finite number");
  return m;
}

}  // namespace locus::plugins::locble
