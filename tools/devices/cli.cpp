#include "devices/cli.hpp"
#include <CLI/CLI.hpp>

#include <memory>

#include "devices/device_list.hpp"

namespace locus::app {

Subcommand add_devices_command(CLI::App& cli) {
  auto opts = std::make_shared<DevicesOptions>();
  CLI::App* cmd = cli.add_subcommand("devices", "list audio devices, JACK ports, IIO sensors and BLE adapters");
  cmd->add_flag("--json", opts->json, "machine-readable output (a JSON array)");
  cmd->add_option("--jack-server", opts->jack_server, "JACK server name (default: $JACK_DEFAULT_SERVER or 'default')");
  cmd->add_option("--iio-root", opts->iio_root, "root prefix of the IIO sysfs tree and /dev (default: /)");
  return Subcommand{cmd, [opts] { return run_devices(*opts); }};
}

}  // namespace locus::app
