// Thresholds, exit status and output (table / JSON) of `locus eval`.
//
// Exit status: 0 every given threshold holds; 4 at least one threshold missed (a NaN value, i.e.
// nothing to score, misses); 2 bad input (malformed estimates line, scene or truth file, a threshold
// no scored plugin reports); 1 any other failure.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/eval/metrics.hpp"

namespace locus::eval {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitThresholdMissed = 4;

/// A threshold option: `--<option> X` requires summary[key] <= X (upper) or >= X (lower).
struct ThresholdSpec {
  std::string option;   ///< without the dashes, e.g. "max-mean-error-m"
  std::string key;      ///< summary key, e.g. "mean_error_m"
  bool upper = true;
  std::string doc;
};
/// Every threshold option `locus eval` understands.
const std::vector<ThresholdSpec>& threshold_specs();

struct Threshold {
  std::string option;
  double limit = 0.0;
};

struct ThresholdOutcome {
  std::string option;
  std::string plugin;
  std::string key;
  double limit = 0.0;
  double value = 0.0;   ///< NaN when the plugin had nothing to score
  bool pass = false;
};

/// Checks each threshold against every group whose summary has its key. Throws InputError for an
/// unknown option or a threshold that no group reports (it would otherwise pass vacuously).
std::vector<ThresholdOutcome> check_thresholds(const EvalResult& result, const std::vector<Threshold>& thresholds);

/// Human-readable report: per plugin a per-target table, the summary, warnings; then thresholds.
void print_table(std::ostream& out, const EvalResult& result, const std::vector<ThresholdOutcome>& outcomes);
/// The same content as JSON.
nlohmann::ordered_json to_json(const EvalResult& result, const std::vector<ThresholdOutcome>& outcomes, int exit_code);

/// Everything `locus eval` does after parsing its command line; returns the exit status.
struct EvalCommand {
  std::string scene_dir;
  std::string estimates_path;
  EvalOptions options;
  std::vector<Threshold> thresholds;
  bool json = false;
  std::string json_output;  ///< --json-output FILE: also write the JSON there ("" = no)
};
int run_eval(const EvalCommand& cmd, std::ostream& out, std::ostream& err);

}  // namespace locus::eval
