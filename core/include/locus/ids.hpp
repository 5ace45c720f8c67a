// Ids and instance names: one rule for every id Locus reads (config device ids and instance names,
// scene device and emitter ids, ids in link messages), see docs/config.md and docs/scene-format.md.
//
// An id is [A-Za-z0-9_-]+ and at most kMaxIdLength (31) characters. Why the cap: ids travel inside
// events in fixed 32-byte fields (DeviceId, NameTag: 31 characters and a terminator), so a longer id
// could not be told apart from its first 31 characters once it is on the bus. Header-only: [RT].
#pragma once

#include <cstddef>
#include <string_view>

#include "locus/events.hpp"

namespace locus {

/// The longest id or instance name (characters).
inline constexpr std::size_t kMaxIdLength = NameTag::max_size();
static_assert(kMaxIdLength == DeviceId::max_size(), "device ids and name tags carry the same ids");

/// What is wrong with a would-be id (the characters are judged before the length).
enum class IdProblem {
  None,          ///< a valid id
  Empty,         ///< ""
  BadCharacter,  ///< a character other than A-Z, a-z, 0-9, '_', '-'
  TooLong,       ///< more than kMaxIdLength characters
};

/// True for A-Z, a-z, 0-9, '_' and '-'.
constexpr bool is_id_char(char c) noexcept {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
}

/// [RT] What is wrong with `s` as an id (IdProblem::None when nothing is).
constexpr IdProblem id_problem(std::string_view s) noexcept {
  if (s.empty()) return IdProblem::Empty;
  for (char c : s) {
    if (!is_id_char(c)) return IdProblem::BadCharacter;
  }
  return s.size() > kMaxIdLength ? IdProblem::TooLong : IdProblem::None;
}

/// [RT] True when `s` is a valid id: [A-Za-z0-9_-]+, at most kMaxIdLength characters.
constexpr bool valid_id(std::string_view s) noexcept { return id_problem(s) == IdProblem::None; }

}  // namespace locus
