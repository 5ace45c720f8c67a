// `locus train SYSTEM SCENES... -o MODEL`: trains a localizer's model from labelled scenes. Added to
// the `locus` tool by tools/locus/main.cpp.
#pragma once

#include <string>
#include <vector>

#include "subcommand.hpp"

namespace locus::app {

struct TrainOptions {
  std::string system;
  std::vector<std::string> scenes, test_scenes;
  std::string output;
  double window_s = 2.0;
  int epochs = 200;
  double lambda = 1e-3;
  unsigned long long seed = 1;
};

Subcommand add_train_command(CLI::App& cli);
/// locble: EnvAware from scenes with per-reading labels (truth_ble_env.csv of `locus simulate locble`,
/// or truth-extra.yaml ble_rows of the foreign generator). Returns the exit status.
int train_locble(const TrainOptions& opt);

}  // namespace locus::app
