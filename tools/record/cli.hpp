// `locus record --config CFG OUT [--duration S] [--overwrite] [--sample-format F] [--name N]`: records the
// live streams of a node config into a scene directory OUT (see record.hpp, docs/record.md).
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_record_command(CLI::App& cli);

}  // namespace locus::app
