// `locus replay SCENE --config CFG [--speed max|realtime] [--out FILE] [--events a,b]`: replays a scene
// directory through the real pipeline, one node per scene device (see replay.hpp, docs/config.md).
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_replay_command(CLI::App& cli);

}  // namespace locus::app
