// `locus room LAYOUT OUT [options]`: a hardware-in-the-loop room on a JACK server (room.hpp,
// docs/room.md). Only in builds with JACK (LOCUS_WITH_JACK); without it `locus room` says so.
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_room_command(CLI::App& cli);

}  // namespace locus::app
