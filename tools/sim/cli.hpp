// `locus simulate FAMILY OUT --seed N [--difficulty easy|normal|hard] [--duration S] [-o key=value]...`
// and `locus simulate --list`: renders a scene family into a scene directory (docs/simulator.md).
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_simulate_command(CLI::App& cli);

}  // namespace locus::app
