// `locus train spyloc SCENES... -o MODEL [--components M] [--detector-params YAML]`: trains the SpyLoc
// LoS/NLoS classifier (plugins/spyloc/classifier.hpp) on labelled scenes (train.hpp).
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_train_command(CLI::App& cli);

}  // namespace locus::app
