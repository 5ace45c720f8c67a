// `locus feed SCENE DEVICE [options]`: a scene device's imu.csv into a fake IIO device and its ble.csv
// through dbusmock's BlueZ, in real time (feed.hpp, docs/room.md). Only in builds with BlueZ
// (LOCUS_WITH_BLUEZ); without it `locus feed` says so.
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_feed_command(CLI::App& cli);

}  // namespace locus::app
