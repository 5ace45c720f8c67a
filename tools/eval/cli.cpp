// CLI11 wiring of `locus eval` (options → EvalCommand → run_eval).
#include "cli.hpp"
#include <CLI/CLI.hpp>

#include <iostream>
#include <map>
#include <memory>
#include <optional>

#include "locus/eval/metric.hpp"
#include "locus/eval/report.hpp"

namespace locus::app {

Subcommand add_eval_command(CLI::App& cli) {
  struct State {
    eval::EvalCommand cmd;
    std::string metric;
    std::map<std::string, std::optional<double>> limits;
  };
  auto st = std::make_shared<State>();
  CLI::App* sub = cli.add_subcommand("eval", "score estimates (JSON lines) against a scene's ground truth (docs/eval.md); "
                                             "exit 0 all thresholds hold, 4 one missed, 2 bad input, 1 failure");
  sub->add_option("scene", st->cmd.scene_dir, "scene directory (scene.yaml with a truth section)")->required();
  sub->add_option("estimates", st->cmd.estimates_path, "JSON-lines file with estimate/step events ('-' = stdin)")->required();
  std::string metric_help = "metric for every plugin (default: the scene's environment.family):";
  for (const eval::Metric* m : eval::metrics()) metric_help += "\n  " + std::string(m->name) + ": " + std::string(m->summary);
  sub->add_option("--metric", st->metric, metric_help)->check(CLI::IsMember(eval::metric_names()));
  sub->add_option("--plugin", st->cmd.options.plugins, "score only this localizer instance (repeatable)");
  sub->add_flag("--json", st->cmd.json, "write the results as JSON instead of the table");
  sub->add_option("--json-output", st->cmd.json_output, "also write the JSON results to this file");
  sub->add_option("--snapshot-tolerance-s", st->cmd.options.snapshot_tolerance_s,
                  "estimates of one plugin closer than this in t_s form one snapshot (relative frames, TUM)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  sub->add_option("--step-match-tolerance-s", st->cmd.options.step_match_tolerance_s,
                  "a step event matches a true step this close in true time (Montage)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  for (const auto& spec : eval::threshold_specs()) {
    sub->add_option("--" + spec.option, st->limits[spec.option], spec.doc + (spec.upper ? " must be <= X" : " must be >= X"));
  }
  Subcommand out;
  out.cmd = sub;
  out.run = [st]() {
    if (!st->metric.empty()) st->cmd.options.metric = st->metric;
    st->cmd.thresholds.clear();
    for (const auto& spec : eval::threshold_specs()) {
      const auto& v = st->limits[spec.option];
      if (v) st->cmd.thresholds.push_back({spec.option, *v});
    }
    return eval::run_eval(st->cmd, std::cout, std::cerr);
  };
  return out;
}

}  // namespace locus::app
