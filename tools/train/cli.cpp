// CLI11 wiring of `locus train spyloc` (train.hpp).
#include "cli.hpp"

#include <CLI/CLI.hpp>
#include <memory>

#include "train.hpp"

namespace locus::app {

Subcommand add_train_command(CLI::App& cli) {
  auto opts = std::make_shared<TrainOptions>();
  CLI::App* sub = cli.add_subcommand("train", "train a localizer's model from labelled scenes (docs/spyloc.md)");
  CLI::App* spy = sub->add_subcommand("spyloc", "SpyLoc LoS/NLoS classifier: naive Bayes, per-feature GMM on T5..T30");
  spy->add_option("scenes", opts->scenes, "labelled scene directories (truth-extra.yaml beeps or truth_los.csv)")->required();
  spy->add_option("-o,--output", opts->output, "model file to write (YAML)")->required();
  spy->add_option("--components", opts->components, "mixture components per feature and class (paper: 4)")
      ->capture_default_str()->check(CLI::Range(1, 16));
  spy->add_option("--detector-params", opts->detector_params,
                  "extra multitone detector params as a YAML flow mapping, e.g. '{tail_s: 0.15}' (must match the run-time config)");
  sub->require_subcommand(1);
  Subcommand out;
  out.cmd = sub;
  out.run = [opts]() { return run_train_spyloc(*opts); };
  return out;
}

}  // namespace locus::app
