// `locus devices [--json] [--jack-server NAME] [--iio-root DIR]`: lists what every HAL backend can see
// (ALSA PCMs/cards, JACK ports, IIO devices, BLE adapters); see device_list.hpp.
#pragma once

#include "subcommand.hpp"

namespace locus::app {

Subcommand add_devices_command(CLI::App& cli);

}  // namespace locus::app
