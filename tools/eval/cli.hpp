// `locus eval SCENE ESTIMATES`: scores a localizer's estimates against a scene's ground truth
// (docs/eval.md). Added to the `locus` tool by tools/locus/main.cpp.
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_eval_command(CLI::App& cli);

}  // namespace locus::app
