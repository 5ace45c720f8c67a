// Scene families: a family is a function (seed, difficulty, options) -> Simulation that sets up one
// of the papers' experiments (devices, trajectories, emission protocol, room, noise, clocks).
// `locus simulate FAMILY OUT --seed N --difficulty normal -o key=value` runs one.
//
// Adding a family is adding one file, tools/sim/families/<name>.cpp, that defines
// `const Family& locus::sim::registered_families::<name>()` (its name, description, options and make
// function). tools/sim/CMakeLists.txt globs that folder and generates the table families() from the
// file names (cmake/LocusTable.cmake). The name is the one the scene's `environment.family`, the eval
// metric (tools/eval/metrics/<name>.cpp) and the replay config (config/<name>.yaml) use.
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

/// Every registered family, in name order (generated from tools/sim/families/*.cpp).
const std::vector<const Family*>& families();
/// nullptr when unknown.
const Family* find_family(std::string_view name);

/// Draws a device clock from the profile (skew uniform ±skew_ppm_max, offset uniform [0, offset_s_max]).
scene::ClockTruth draw_clock(const DifficultyProfile& p, Rng& rng);
/// Applies a profile's acoustic knobs (noise, room reflection/order if a room is set) to `a`.
void apply_profile(const DifficultyProfile& p, AcousticModel& a);
/// Noise bursts of kind `kind` (white | babble | music | mixed: babble or music each burst), lasting
/// min_s..max_s; white leaves the model's bursts as they are (the difficulty's white noise).
void set_burst_kind(NoiseModel& nm, const std::string& kind, double min_s, double max_s);

}  // namespace locus::sim
