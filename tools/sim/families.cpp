// Difficulty profiles and option parsing shared by every family (families.hpp). The families
// themselves are one file each in tools/sim/families/; their table is generated (CMakeLists.txt).
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "locus/sim/families.hpp"

namespace locus::sim {

std::optional<Difficulty> parse_difficulty(std::string_view s) {
  if (s == "easy") return Difficulty::Easy;
  if (s == "normal") return Difficulty::Normal;
  if (s == "hard") return Difficulty::Hard;
  return std::nullopt;
}

const char* to_string(Difficulty d) noexcept {
  switch (d) {
    case Difficulty::Easy: return "easy";
    case Difficulty::Normal: return "normal";
    case Difficulty::Hard: return "hard";
  }
  return "?";
}

DifficultyProfile difficulty_profile(Difficulty d) {
  switch (d) {
    case Difficulty::Easy:
      return {/*snr_db*/ 40.0, /*pink*/ 0.0, /*bursts/min*/ 0.0, /*order*/ 1, /*beta*/ 0.5,
              /*skew*/ 10.0, /*offset*/ 0.5, LatencyModel{0.02, 0.05}, /*p_obstr*/ 0.0, /*obstr_db*/ 0.0,
              /*imu*/ 0.5};
    case Difficulty::Normal:
      return {25.0, 0.5, 2.0, 2, 0.7, 40.0, 2.0, LatencyModel{0.02, 0.15}, 0.0, 0.0, 1.0};
    case Difficulty::Hard:
      return {12.0, 0.8, 8.0, 3, 0.85, 80.0, 5.0, LatencyModel{0.02, 0.30}, 0.25, 15.0, 2.0};
  }
  throw std::invalid_argument("difficulty_profile: bad difficulty");
}

scene::ClockTruth draw_clock(const DifficultyProfile& p, Rng& rng) {
  scene::ClockTruth c;
  c.skew_ppm = rng.uniform(-p.skew_ppm_max, p.skew_ppm_max);
  c.offset_s = rng.uniform(0.0, p.offset_s_max);
  return c;
}

void set_burst_kind(NoiseModel& nm, const std::string& kind, double min_s, double max_s) {
  if (kind == "white") return;
  nm.burst_kind = kind == "babble" ? NoiseModel::BurstKind::Babble
                  : kind == "music" ? NoiseModel::BurstKind::Music
                                    : NoiseModel::BurstKind::Mixed;
  nm.burst_min_s = min_s;
  nm.burst_max_s = max_s;
}

void apply_profile(const DifficultyProfile& p, AcousticModel& a) {
  a.noise.snr_db = p.snr_db;
  a.noise.pink_fraction = p.pink_fraction;
  a.noise.bursts_per_minute = p.bursts_per_minute;
  if (a.room) {
    a.room->max_order = p.reflection_order;
    a.room->set_reflection(p.wall_reflection);
  }
}

// ------------------------------------------------------------------------------------------ options

void FamilyOptions::set_from_assignment(const std::string& kv) {
  const auto eq = kv.find('=');
  if (eq == std::string::npos || eq == 0) throw std::invalid_argument("option '" + kv + "': expected key=value");
  set(kv.substr(0, eq), kv.substr(eq + 1));
}

namespace {
double parse_number(const std::string& key, const std::string& v) {
  std::size_t used = 0;
  double x = 0.0;
  try {
    x = std::stod(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size() || v.empty() || !std::isfinite(x))
    throw std::invalid_argument("option '" + key + "': expected a number, got '" + v + "'");
  return x;
}
}  // namespace

double FamilyOptions::get_double(const std::string& key, double def, double lo, double hi) const {
  known_.insert(key);
  auto it = values_.find(key);
  if (it == values_.end()) return def;
  used_.insert(key);
  const double x = parse_number(key, it->second);
  if (x < lo || x > hi)
    throw std::invalid_argument("option '" + key + "': " + it->second + " is out of range [" + scene::format_double(lo) +
                                ", " + scene::format_double(hi) + "]");
  return x;
}

long long FamilyOptions::get_int(const std::string& key, long long def, long long lo, long long hi) const {
  known_.insert(key);
  auto it = values_.find(key);
  if (it == values_.end()) return def;
  used_.insert(key);
  const double x = parse_number(key, it->second);
  if (x != std::floor(x)) throw std::invalid_argument("option '" + key + "': expected an integer, got '" + it->second + "'");
  if (x < static_cast<double>(lo) || x > static_cast<double>(hi))
    throw std::invalid_argument("option '" + key + "': " + it->second + " is out of range [" + std::to_string(lo) + ", " +
                                std::to_string(hi) + "]");
  return static_cast<long long>(x);
}

bool FamilyOptions::get_bool(const std::string& key, bool def) const {
  known_.insert(key);
  auto it = values_.find(key);
  if (it == values_.end()) return def;
  used_.insert(key);
  if (it->second == "true" || it->second == "1" || it->second == "yes") return true;
  if (it->second == "false" || it->second == "0" || it->second == "no") return false;
  throw std::invalid_argument("option '" + key + "': expected true or false, got '" + it->second + "'");
}

std::string FamilyOptions::get_choice(const std::string& key, const std::string& def,
                                      const std::vector<std::string>& choices) const {
  known_.insert(key);
  auto it = values_.find(key);
  if (it == values_.end()) return def;
  used_.insert(key);
  if (std::find(choices.begin(), choices.end(), it->second) != choices.end()) return it->second;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
  throw std::invalid_argument("option '" + key + "': expected one of " + list + ", got '" + it->second + "'");
}

void FamilyOptions::finish(const std::string& family) const {
  std::string unknown;
  for (const auto& [k, v] : values_)
    if (!used_.count(k)) unknown += (unknown.empty() ? "" : ", ") + k;
  if (unknown.empty()) return;
  std::string known;
  for (const auto& k : known_) known += (known.empty() ? "" : ", ") + k;
  throw std::invalid_argument("family '" + family + "': unknown option(s) " + unknown + " (accepted: " +
                              (known.empty() ? "none" : known) + ")");
}

// ------------------------------------------------------------------------------------------ table

const Family* find_family(std::string_view name) {
  for (const Family* f : families())
    if (f->name == name) return f;
  return nullptr;
}

}  // namespace locus::sim
