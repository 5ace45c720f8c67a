// CLI11 wiring of `locus train spyloc|locble` (train.hpp).
#include "cli.hpp"

#include <CLI/CLI.hpp>
#include <memory>

#include "app.hpp"
#include "train.hpp"

namespace locus::app {

Subcommand add_train_command(CLI::App& cli) {
  CLI::App* sub = cli.add_subcommand("train", "train a localizer's model from labelled scenes (spyloc, locble)");

  auto spy_opts = std::make_shared<SpyLocTrainOptions>();
  CLI::App* spy = sub->add_subcommand("spyloc", "SpyLoc LoS/NLoS classifier: naive Bayes, per-feature GMM on T5..T30 (docs/spyloc.md)");
  spy->add_option("scenes", spy_opts->scenes, "labelled scene directories (truth-extra.yaml beeps or truth_los.csv)")->required();
  spy->add_option("-o,--output", spy_opts->output, "model file to write (YAML)")->required();
  spy->add_option("--test", spy_opts->test_scenes, "held-out labelled scenes: LoS/NLoS accuracy per class (repeatable)");
  spy->add_option("--components", spy_opts->components, "mixture components per feature and class (paper: 4)")
      ->capture_default_str()->check(CLI::Range(1, 16));
  spy->add_option("--detector-params", spy_opts->detector_params,
                  "extra multitone detector params as a YAML flow mapping, e.g. '{tail_s: 0.15}' (must match the run-time config)");

  auto ble_opts = std::make_shared<LocBleTrainOptions>();
  CLI::App* ble = sub->add_subcommand("locble", "LocBLE EnvAware: 9 RSS features, linear SVM LOS/pLOS/NLOS (docs/locble.md)");
  ble->add_option("scenes", ble_opts->scenes, "training scenes (truth_ble_env.csv or truth-extra.yaml ble_rows)")->required();
  ble->add_option("-o,--output", ble_opts->output, "model file to write (YAML)")->required();
  ble->add_option("--test", ble_opts->test_scenes, "held-out scenes: accuracy per class (repeatable)");
  ble->add_option("--window-s", ble_opts->window_s, "feature window (paper: 2 s)")->capture_default_str();
  ble->add_option("--epochs", ble_opts->epochs, "Pegasos epochs")->capture_default_str();
  ble->add_option("--lambda", ble_opts->lambda, "L2 regularisation")->capture_default_str();
  ble->add_option("--seed", ble_opts->seed, "trainer seed")->capture_default_str();

  sub->require_subcommand(1);
  Subcommand out;
  out.cmd = sub;
  out.run = [spy, spy_opts, ble_opts]() {
    if (spy->parsed()) return run_train_spyloc(*spy_opts);
    return train_locble(*ble_opts);
  };
  return out;
}

}  // namespace locus::app
