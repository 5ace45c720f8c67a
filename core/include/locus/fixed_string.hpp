// Fixed-capacity, trivially copyable string for identifiers carried in real-time events.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>

namespace locus {

/// Holds up to N-1 bytes plus a terminating NUL; longer input is truncated (ids are validated to be
/// short by the config layer, so truncation never happens for configured names).
template <std::size_t N>
struct FixedString {
  char data[N] = {};

  FixedString() = default;
  FixedString(std::string_view s) noexcept { assign(s); }  // NOLINT: implicit by design
  FixedString(const char* s) noexcept { assign(s ? std::string_view(s) : std::string_view()); }  // NOLINT

  void assign(std::string_view s) noexcept {
    const std::size_t n = std::min(s.size(), N - 1);
    std::memcpy(data, s.data(), n);
    std::memset(data + n, 0, N - n);
  }
  std::string_view view() const noexcept { return std::string_view(data, ::strnlen(data, N)); }
  std::string str() const { return std::string(view()); }
  bool empty() const noexcept { return data[0] == '\0'; }
  static constexpr std::size_t max_size() noexcept { return N - 1; }

  friend bool operator==(const FixedString& a, const FixedString& b) noexcept { return a.view() == b.view(); }
  friend bool operator==(const FixedString& a, std::string_view b) noexcept { return a.view() == b; }
};

}  // namespace locus
