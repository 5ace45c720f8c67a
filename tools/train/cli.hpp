// `locus train SYSTEM SCENES... -o MODEL`: trains a localizer's model from labelled scenes (train.hpp).
// SYSTEM: spyloc (LoS/NLoS classifier), locble (EnvAware). Added to `locus` by tools/locus/main.cpp.
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_train_command(CLI::App& cli);

}  // namespace locus::app
