// The metric families (one per paper, plus generic position error) and the evaluation of an
// estimates file against a scene's truth. Results are plain JSON objects so the table printer, the
// --json writer and the threshold checks share one representation; docs/eval.md lists every key.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/eval/estimates.hpp"
#include "locus/eval/truth.hpp"

namespace locus::eval {

enum class Family {
  Position,  ///< generic: per-estimate position error in any frame
  Tum,       ///< TUM Eq. 23: mean absolute pairwise distance error per snapshot
  Amil,      ///< AMIL: per-listener direction / distance / position error, listeners located
  Montage,   ///< Montage: stride error (step events vs truth_steps.csv) and trace deviation
  Spyloc,    ///< SpyLoc: position error CDF (median, 80th, 90th), LoS/NLoS split when flagged
  Locble,    ///< LocBLE: per-tag position error of the final estimate
};

std::string_view family_name(Family f) noexcept;
std::optional<Family> family_from_name(std::string_view name) noexcept;
/// Auto-detection from a localizer instance name (contains tum/spyloc/montage/locble/amil,
/// case-insensitive) or else its frame (player_start → AMIL, observer_start → LocBLE); else Position.
Family detect_family(std::string_view plugin, std::string_view frame) noexcept;

struct EvalOptions {
  std::optional<Family> metric;        ///< force one family for every plugin (else auto-detect)
  std::vector<std::string> plugins;    ///< score only these plugin instances (empty = all)
  double snapshot_tolerance_s = 1e-3;  ///< estimates of one plugin this close in t_s form one snapshot
  double step_match_tolerance_s = 0.3; ///< a step event matches a true step this close in true time
};

/// Linear-interpolation percentile of sorted values (q in [0,1]); NaN when empty.
double percentile_sorted(const std::vector<double>& sorted, double q);

/// Summary statistics of a sample (NaN fields when empty).
struct Stats {
  std::size_t n = 0;
  double mean = 0, median = 0, p80 = 0, p90 = 0, max = 0, rms = 0;
};
Stats stats_of(std::vector<double> values);

/// The score of one plugin instance.
struct GroupResult {
  Family family = Family::Position;
  std::string plugin;
  std::vector<std::string> references;  ///< distinct references of its estimates
  std::vector<std::string> frames;      ///< distinct frames
  /// One object per target (expected or estimated): {"target": id, "status": "ok"|"no estimate"|
  /// "unknown target"|"no truth", "estimates": n, <family columns>...}; NaN-valued columns are null.
  nlohmann::ordered_json targets = nlohmann::ordered_json::array();
  /// Family summary: counts and statistics (docs/eval.md); thresholds are checked against these.
  nlohmann::ordered_json summary = nlohmann::ordered_json::object();
  /// Extra family data (TUM per-snapshot errors, SpyLoc CDF, Montage steps, ...).
  nlohmann::ordered_json details = nlohmann::ordered_json::object();
  std::vector<std::string> warnings;    ///< reported, never silent: unknown targets, extrapolation...
};

struct EvalResult {
  std::string scene_dir;
  std::string estimates_path;
  std::size_t estimate_lines = 0;
  std::size_t step_lines = 0;
  std::map<std::string, std::size_t> other_events;
  std::vector<GroupResult> groups;
  std::vector<std::string> warnings;    ///< not tied to one plugin (e.g. no estimates at all)
};

/// Scores every plugin of `estimates` (or those in options.plugins). Throws InputError for estimates
/// the scorer cannot interpret (unknown frame name, a frame that needs a reference without one),
/// naming file:line.
EvalResult evaluate(const TruthData& truth, const EstimatesFile& estimates, const EvalOptions& options);

}  // namespace locus::eval
