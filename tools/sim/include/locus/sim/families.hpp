// Scene families: a family is a function (seed, difficulty, options) -> Simulation that sets up one
// of the papers' experiments (devices, trajectories, emission protocol, room, noise, clocks).
// `locus simulate FAMILY OUT --seed N --difficulty normal -o key=value` runs one.
//
// Adding a family: write `Simulation make_<name>(const FamilyOptions&)` in tools/sim/families/<name>.cpp,
// declare it below and add one line to the table in tools/sim/families/families.cpp.
// Difficulty sets the shared knobs through difficulty_profile(); a family may scale them.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "locus/sim/engine.hpp"

namespace locus::sim {

enum class Difficulty { Easy, Normal, Hard };

/// "easy" | "normal" | "hard"; nullopt otherwise.
std::optional<Difficulty> parse_difficulty(std::string_view s);
const char* to_string(Difficulty d) noexcept;

/// The knobs difficulty sets (see docs/simulator.md for the table).
struct DifficultyProfile {
  double snr_db;                 ///< NoiseModel::snr_db (unit source at 1 m)
  double pink_fraction;
  double bursts_per_minute;
  int reflection_order;          ///< image-source order (0 = none)
  double wall_reflection;        ///< β of every wall
  double skew_ppm_max;           ///< clock skew drawn uniform in ±this
  double offset_s_max;           ///< clock offset drawn uniform in [0, this]
  LatencyModel latency;          ///< per-emission speaker latency
  double obstruction_probability;///< chance that a given pair is obstructed (NLOS) for the whole scene
  double obstruction_db;
  double imu_noise_scale;        ///< multiplies the IMU noise and bias sigmas
};
DifficultyProfile difficulty_profile(Difficulty d);

/// Family options from the command line (`-o key=value`), with typed, range-checked access.
/// Every get_* marks the key as used; finish() throws for keys no one asked for (typos).
class FamilyOptions {
 public:
  std::uint64_t seed = 1;
  Difficulty difficulty = Difficulty::Normal;
  std::optional<double> duration_s;   ///< --duration (families have their own default)

  void set(const std::string& key, const std::string& value) { values_[key] = value; }
  /// Parses "key=value"; throws std::invalid_argument otherwise.
  void set_from_assignment(const std::string& key_equals_value);

  double get_double(const std::string& key, double def, double lo, double hi) const;
  long long get_int(const std::string& key, long long def, long long lo, long long hi) const;
  bool get_bool(const std::string& key, bool def) const;
  /// One of `choices`.
  std::string get_choice(const std::string& key, const std::string& def, const std::vector<std::string>& choices) const;

  /// Throws std::invalid_argument listing unknown keys and the ones the family accepts.
  void finish(const std::string& family) const;

 private:
  std::map<std::string, std::string> values_;
  mutable std::set<std::string> used_;
  mutable std::set<std::string> known_;
};

struct FamilyOptionDoc {
  std::string key, type, default_value, doc;
};

struct Family {
  std::string name;
  std::string description;
  std::vector<FamilyOptionDoc> options;
  std::function<Simulation(const FamilyOptions&)> make;
};

/// Every built-in family, in display order.
const std::vector<Family>& families();
/// nullptr when unknown.
const Family* find_family(std::string_view name);

/// Draws a device clock from the profile (skew uniform ±skew_ppm_max, offset uniform [0, offset_s_max]).
scene::ClockTruth draw_clock(const DifficultyProfile& p, Rng& rng);
/// Applies a profile's acoustic knobs (noise, room reflection/order if a room is set) to `a`.
void apply_profile(const DifficultyProfile& p, AcousticModel& a);

// ------------------------------------------------------------------------------------------ families
/// AMIL field test (paper 004): a player draws triangles on a table and beeps at the pauses,
/// 12 listeners on a 1.22 m grid. Options: gestures (1|3), side_m, speed_mps, pause_min_s, pause_max_s.
Simulation make_amil(const FamilyOptions& opts);
/// TUM (paper 000): four two-mic devices in a 5.3×6×3.5 m room, each emits its own chirp in turn;
/// track = static | ellipse (the moving device rides a 31×58 cm elliptical track, 5.9 s per round).
Simulation make_tum(const FamilyOptions& opts);
/// Montage (paper 002): walkers in formation, Gold-coded 19 kHz tones emitted together each round.
Simulation make_montage(const FamilyOptions& opts);
/// SpyLoc (paper 001): a walker, 3-4 anchored beacons with radio sync + multitone beeps, NLOS wall.
Simulation make_spyloc(const FamilyOptions& opts);
/// LocBLE (paper 003): an observer walking an L scans 1-6 BLE tags (some clustered); no audio.
Simulation make_locble(const FamilyOptions& opts);

}  // namespace locus::sim
