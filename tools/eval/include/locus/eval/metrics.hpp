// The evaluation of an estimates file against a scene's truth. How a group of estimates is scored is
// a metric (one per paper, plus generic position error) registered by its own file,
// tools/eval/metrics/<name>.cpp (locus/eval/metric.hpp); this header is what every caller needs.
// Results are plain JSON objects so the table printer, the --json writer and the threshold checks
// share one representation; docs/eval.md lists every key.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/eval/estimates.hpp"
#include "locus/eval/truth.hpp"

namespace locus::eval {

struct EvalOptions {
  /// The metric for every plugin (`--metric`, a registered name: metric_names()). Unset: the
  /// scene's `environment.family` (TruthData::family); neither is an InputError. Never guessed
  /// from a plugin's instance name.
  std::optional<std::string> metric;
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
  std::string family;                   ///< name of the metric that scored it ("amil", "position", ...)
  std::string plugin;
  std::vector<std::string> references;  ///< distinct references of its estimates
  std::vector<std::string> frames;      ///< distinct frames
  /// One object per target (expected or estimated): {"target": id, "status": "ok"|"no estimate"|
  /// "unknown target"|"no truth", "estimates": n, <family columns>...}; NaN-valued columns are null.
  nlohmann::ordered_json targets = nlohmann::ordered_json::array();
  /// Metric summary: counts and statistics (docs/eval.md); thresholds are checked against these.
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

/// Scores every plugin of `estimates` (or those in options.plugins) with the metric options.metric
/// or truth.family names. Throws InputError for estimates the scorer cannot interpret (unknown frame
/// name, a frame that needs a reference without one), naming file:line, and when no registered
/// metric is named (no --metric and no environment.family, or an unknown name: the message lists
/// the known ones).
EvalResult evaluate(const TruthData& truth, const EstimatesFile& estimates, const EvalOptions& options);

}  // namespace locus::eval
