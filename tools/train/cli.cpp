// `locus train` (see cli.hpp).
#include "train/cli.hpp"

#include <CLI/CLI.hpp>
#include <iostream>
#include <memory>

#include "app.hpp"

namespace locus::app {

Subcommand add_train_command(CLI::App& cli) {
  auto opts = std::make_shared<TrainOptions>();
  CLI::App* cmd = cli.add_subcommand("train", "train a localizer's model from labelled scenes (locble: EnvAware SVM)");
  cmd->add_option("system", opts->system, "what to train: locble")->required();
  cmd->add_option("scenes", opts->scenes, "training scenes")->required();
  cmd->add_option("-o,--output", opts->output, "model file to write (YAML)")->required();
  cmd->add_option("--test", opts->test_scenes, "held-out scenes: accuracy per class (repeatable)");
  cmd->add_option("--window-s", opts->window_s, "feature window (paper: 2 s)");
  cmd->add_option("--epochs", opts->epochs, "Pegasos epochs");
  cmd->add_option("--lambda", opts->lambda, "L2 regularisation");
  cmd->add_option("--seed", opts->seed, "trainer seed");
  return Subcommand{cmd, [opts] {
                      if (opts->system != "locble") {
                        std::cerr << "locus train: unknown system '" << opts->system << "' (expected: locble)\n";
                        return kExitBadConfig;
                      }
                      return train_locble(*opts);
                    }};
}

}  // namespace locus::app
