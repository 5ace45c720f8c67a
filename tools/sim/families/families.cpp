// The family table, difficulty profiles and option parsing shared by every family (families.hpp).
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

const std::vector<Family>& families() {
  static const std::vector<Family> table = {
      {"amil",
       "AMIL field test (paper 004): a player draws triangles on a table and beeps (18-22 kHz, 50 ms) at the "
       "pauses; 12 listeners on a 1.22 m grid in a 3x5 m hallway; player IMU",
       {{"gestures", "int", "1", "triangles drawn (1 or 3)"},
        {"side_m", "double", "0.305", "triangle half-base and height (paper: 30.5 cm)"},
        {"speed_mps", "double", "0.45", "mean stroke speed (min-jerk strokes)"},
        {"pause_min_s", "double", "0.4", "shortest pause at a corner (the beep is played in it)"},
        {"pause_max_s", "double", "0.7", "longest pause at a corner"}},
       make_amil},
      {"tum",
       "TUM (paper 000): four two-mic devices in a 5.3x6x3.5 m room, each emits its own 2-8 kHz 40 ms chirp in "
       "turn; static or the elliptical track (31x58 cm, 5.9 s/round); IMU attitude",
       {{"track", "static|ellipse", "static", "the moving device is static or rides the elliptical track"},
        {"round_s", "double", "0.333", "period of one tone-exchange round (all four devices)"}},
       make_tum},
      {"montage",
       "Montage (paper 002): 2-8 walkers in formation (pairs side by side), every phone emits its Gold code "
       "(r=5) on 19 kHz at once each round; IMU with magnetometer; truth_steps.csv",
       {{"walkers", "int", "4", "number of walkers (2..8)"},
        {"path", "straight|L|loop", "L", "the formation's route"},
        {"period_s", "double", "1.0", "ranging round period (all phones emit together)"},
        {"spacing_m", "double", "1.5", "side-by-side spacing in a pair"},
        {"row_gap_m", "double", "2.0", "distance between pairs (one behind the other)"},
        {"chip_samples", "int", "100", "samples per Gold chip (paper example: 100)"},
        {"carrier_hz", "double", "19000", "BPSK carrier"},
        {"room", "none|hall", "none", "free field (outdoor) or a 40x30x6 m hall"}},
       make_montage},
      {"spyloc",
       "SpyLoc (paper 001): a walker with a phone, 3-4 anchored beacons sending radio sync + 10-tone 18-20.25 kHz "
       "beeps; an interior wall makes NLOS stretches; IMU 50 Hz; truth_steps.csv, truth_los.csv",
       {{"beacons", "int", "3", "number of beacons (3 or 4)"},
        {"beep_period_s", "double", "1.0", "time between beeps of one beacon"},
        {"sync_delay_s", "double", "0.05", "radio message to beep delay (known)"},
        {"pace", "normal|fast", "normal", "step frequency 1.7 or 2.2 Hz"},
        {"nlos_db", "double", "20", "direct-path attenuation behind the wall"},
        {"laps", "int", "1", "laps of the 16x8 m loop"}},
       make_spyloc},
      {"locble",
       "LocBLE (paper 003): an observer walks an L (3.5-5 m) scanning BLE; 1-6 tags 4-9 m away, some clustered "
       "within 1 m of the target; log-distance RSS with LOS/p-LOS/NLOS exponents; IMU; no audio",
       {{"tags", "int", "3", "number of tags (1..6); tag1 is the target"},
        {"clustered", "int", "min(2, tags-1)", "tags placed within 0.3-1 m of the target"},
        {"env", "los|plos|nlos|mixed", "los", "propagation class (mixed: NLOS then LOS, people crossing)"},
        {"turn", "left|right", "left", "direction of the L's turn (the target is on that side)"},
        {"interval_s", "double", "0.1", "advertising interval (paper: 10 Hz)"}},
       make_locble},
  };
  return table;
}

const Family* find_family(std::string_view name) {
  for (const auto& f : families())
    if (f.name == name) return &f;
  return nullptr;
}

}  // namespace locus::sim
