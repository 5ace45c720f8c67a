// What the scene stream files' readers share (wav.cpp, csv.cpp, imu_csv.cpp, ble_csv.cpp,
// sync_csv.cpp, truth.cpp): SceneError throwers and CSV field helpers. Internal to locus_scene.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <string_view>

#include "locus/scene/csv.hpp"
#include "locus/scene/scene.hpp"

namespace locus::scene::detail {

/// Throws a SceneError at byte offset `byte` of `file`.
[[noreturn]] inline void throw_at_byte(const std::string& file, long long byte, const std::string& msg) {
  SceneIssue is;
  is.file = file;
  is.byte_offset = byte;
  is.message = msg;
  throw SceneError({is});
}

/// Throws a SceneError about `file` as a whole.
[[noreturn]] inline void throw_file(const std::string& file, const std::string& msg) {
  SceneIssue is;
  is.file = file;
  is.message = msg;
  throw SceneError({is});
}

/// `s` without leading and trailing blanks (spaces, tabs).
inline std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

/// A field as an error shows it: quoted, cut after 40 characters.
inline std::string shown(std::string_view s) {
  if (s.size() > 40) return "'" + std::string(s.substr(0, 40)) + "...'";
  return "'" + std::string(s) + "'";
}

/// Field `col` of the current row as a float (a finite number within float range).
inline float to_float(const CsvReader& csv, std::size_t col) {
  const double v = csv.number(col);
  if (std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max()))
    csv.fail(col, "value " + format_double(v) + " is out of float range");
  return static_cast<float>(v);
}

}  // namespace locus::scene::detail
