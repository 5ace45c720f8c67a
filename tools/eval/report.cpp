// Thresholds, the table and JSON outputs, and the `locus eval` driver.
#include "locus/eval/report.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <ostream>
#include <sstream>

#include "locus/eval/error.hpp"
#include "locus/numbers.hpp"

namespace locus::eval {

namespace {

using ojson = nlohmann::ordered_json;

std::string cell(const ojson& v) {
  if (v.is_null()) return "-";
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer() || v.is_number_unsigned()) return v.dump();
  if (v.is_number_float()) {
    std::ostringstream os;
    os << std::fixed << std::setprecision(3) << v.get<double>();
    return os.str();
  }
  return v.dump();
}

double value_of(const ojson& v) { return v.is_number() ? v.get<double>() : kNaN; }

}  // namespace

const std::vector<ThresholdSpec>& threshold_specs() {
  static const std::vector<ThresholdSpec> specs = {
      {"max-mean-error-m", "mean_error_m", true,
       "mean error (m): position error; TUM: Eq. 23 over snapshots; LocBLE: final estimate per tag; Montage: trace deviation"},
      {"max-median-error-m", "median_error_m", true, "median error (m), same quantity as --max-mean-error-m"},
      {"max-p90-error-m", "p90_error_m", true, "90th percentile error (m), same quantity as --max-mean-error-m"},
      {"max-direction-error-deg", "mean_direction_error_deg", true, "AMIL: mean absolute direction error (deg)"},
      {"max-median-distance-error-pct", "median_distance_error_pct", true, "AMIL: median distance error (% of the true distance)"},
      {"max-near-median-distance-error-pct", "near_median_distance_error_pct", true,
       "AMIL: median distance error (%) of the listeners within 2.5 m"},
      {"min-near-with-distance-fraction", "near_with_distance_fraction", false,
       "AMIL: listeners within 2.5 m that have a distance / listeners within 2.5 m (0..1)"},
      {"max-unflagged-direction-error-deg", "unflagged_mean_direction_error_deg", true,
       "AMIL: mean direction error (deg) of the estimates not flagged inconsistent or weak"},
      {"min-located-fraction", "located_fraction", false, "targets located / targets expected (0..1)"},
      {"max-stride-error-m", "mean_stride_error_m", true, "Montage: mean absolute stride length error (m)"},
      {"max-unknown-targets", "unknown_target_estimates", true, "estimates whose target is not in the scene"},
  };
  return specs;
}

std::vector<ThresholdOutcome> check_thresholds(const EvalResult& result, const std::vector<Threshold>& thresholds) {
  std::vector<ThresholdOutcome> out;
  std::vector<std::string> errors;
  for (const Threshold& t : thresholds) {
    const auto& specs = threshold_specs();
    auto spec = std::find_if(specs.begin(), specs.end(), [&](const ThresholdSpec& s) { return s.option == t.option; });
    if (spec == specs.end()) {
      errors.push_back("--" + t.option + ": unknown threshold");
      continue;
    }
    if (!std::isfinite(t.limit)) {
      errors.push_back("--" + t.option + ": expected a finite number");
      continue;
    }
    bool applied = false;
    for (const GroupResult& g : result.groups) {
      if (!g.summary.contains(spec->key)) continue;
      applied = true;
      ThresholdOutcome o;
      o.option = t.option;
      o.plugin = g.plugin;
      o.key = spec->key;
      o.limit = t.limit;
      o.value = value_of(g.summary[spec->key]);
      o.pass = std::isfinite(o.value) && (spec->upper ? o.value <= t.limit : o.value >= t.limit);
      out.push_back(o);
    }
    if (!applied) {
      std::string families;
      for (const GroupResult& g : result.groups) families += (families.empty() ? "" : ", ") + g.plugin + " (" + g.family + ")";
      errors.push_back("--" + t.option + ": no scored plugin reports '" + spec->key + "' (scored: " +
                       (families.empty() ? std::string("none") : families) + ")");
    }
  }
  if (!errors.empty()) throw InputError(std::move(errors));
  return out;
}

void print_table(std::ostream& out, const EvalResult& result, const std::vector<ThresholdOutcome>& outcomes) {
  out << "scene " << result.scene_dir << ", estimates " << result.estimates_path << ": " << result.estimate_lines << " estimate, "
      << result.step_lines << " step";
  for (const auto& [type, n] : result.other_events) out << ", " << n << " " << type;
  out << " lines\n";
  for (const GroupResult& g : result.groups) {
    out << "\n== " << g.plugin << "  metric " << g.family;
    auto join = [](const std::vector<std::string>& v) {
      std::string s;
      for (const auto& x : v) s += (s.empty() ? "" : ",") + (x.empty() ? std::string("\"\"") : x);
      return s.empty() ? std::string("-") : s;
    };
    out << "  reference " << join(g.references) << "  frame " << join(g.frames) << "\n";
    // Columns: union of the rows' keys, in order of first appearance.
    std::vector<std::string> cols;
    for (const auto& row : g.targets)
      for (const auto& [k, v] : row.items())
        if (std::find(cols.begin(), cols.end(), k) == cols.end()) cols.push_back(k);
    std::vector<std::vector<std::string>> cells;
    std::vector<std::size_t> width(cols.size());
    for (std::size_t c = 0; c < cols.size(); ++c) width[c] = cols[c].size();
    for (const auto& row : g.targets) {
      std::vector<std::string> r;
      for (std::size_t c = 0; c < cols.size(); ++c) {
        r.push_back(row.contains(cols[c]) ? cell(row[cols[c]]) : "");
        width[c] = std::max(width[c], r.back().size());
      }
      cells.push_back(std::move(r));
    }
    auto line = [&](const std::vector<std::string>& r) {
      out << " ";
      for (std::size_t c = 0; c < r.size(); ++c) out << " " << std::left << std::setw(static_cast<int>(width[c])) << r[c];
      out << "\n";
    };
    if (!cols.empty()) {
      line(cols);
      for (const auto& r : cells) line(r);
    }
    out << "  summary:\n";
    for (const auto& [k, v] : g.summary.items()) out << "    " << k << " = " << cell(v) << "\n";
    for (const auto& w : g.warnings) out << "  warning: " << w << "\n";
  }
  for (const auto& w : result.warnings) out << "warning: " << w << "\n";
  if (!outcomes.empty()) {
    out << "\nthresholds:\n";
    for (const auto& o : outcomes) {
      const auto& specs = threshold_specs();
      auto spec = std::find_if(specs.begin(), specs.end(), [&](const ThresholdSpec& s) { return s.option == o.option; });
      out << "  " << (o.pass ? "PASS" : "FAIL") << "  " << o.plugin << ": " << o.key << " = "
          << (std::isfinite(o.value) ? cell(ojson(o.value)) : std::string("- (nothing scored)")) << (spec->upper ? " <= " : " >= ")
          << o.limit << "  (--" << o.option << ")\n";
    }
  }
}

ojson to_json(const EvalResult& result, const std::vector<ThresholdOutcome>& outcomes, int exit_code) {
  ojson j = ojson::object();
  j["scene"] = result.scene_dir;
  j["estimates_file"] = result.estimates_path;
  ojson lines = ojson::object();
  lines["estimate"] = result.estimate_lines;
  lines["step"] = result.step_lines;
  for (const auto& [type, n] : result.other_events) lines[type] = n;
  j["lines"] = lines;
  j["plugins"] = ojson::array();
  for (const GroupResult& g : result.groups) {
    ojson p = ojson::object();
    p["plugin"] = g.plugin;
    p["metric"] = g.family;
    p["references"] = g.references;
    p["frames"] = g.frames;
    p["summary"] = g.summary;
    p["targets"] = g.targets;
    p["details"] = g.details;
    p["warnings"] = g.warnings;
    j["plugins"].push_back(std::move(p));
  }
  j["warnings"] = result.warnings;
  j["thresholds"] = ojson::array();
  bool passed = true;
  for (const auto& o : outcomes) {
    passed = passed && o.pass;
    j["thresholds"].push_back({{"option", "--" + o.option}, {"plugin", o.plugin}, {"key", o.key}, {"limit", o.limit},
                               {"value", std::isfinite(o.value) ? ojson(o.value) : ojson(nullptr)}, {"pass", o.pass}});
  }
  j["passed"] = passed;
  j["exit_code"] = exit_code;
  return j;
}

int run_eval(const EvalCommand& cmd, std::ostream& out, std::ostream& err) {
  try {
    const TruthData truth = load_truth(cmd.scene_dir);
    const EstimatesFile estimates = read_estimates(cmd.estimates_path);
    const EvalResult result = evaluate(truth, estimates, cmd.options);
    const std::vector<ThresholdOutcome> outcomes = check_thresholds(result, cmd.thresholds);
    const bool passed = std::all_of(outcomes.begin(), outcomes.end(), [](const ThresholdOutcome& o) { return o.pass; });
    const int code = passed ? kExitOk : kExitThresholdMissed;
    const ojson j = to_json(result, outcomes, code);
    if (!cmd.json_output.empty()) {
      std::ofstream f(cmd.json_output);
      if (!f) throw std::runtime_error("cannot write " + cmd.json_output);
      f << j.dump(2) << "\n";
      if (!f) throw std::runtime_error("cannot write " + cmd.json_output);
    }
    if (cmd.json) out << j.dump(2) << "\n";
    else print_table(out, result, outcomes);
    if (!passed) err << "locus eval: a threshold was missed (exit " << kExitThresholdMissed << ")\n";
    return code;
  } catch (const InputError& e) {
    for (const auto& m : e.messages()) err << m << "\n";
    err << "locus eval: bad input (exit " << kExitBadInput << ")\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    err << "locus eval: " << e.what() << "\n";
    return kExitFailure;
  }
}

}  // namespace locus::eval
