// `locus feed`: parse the command line into FeedOptions and run the feed.
#include "cli.hpp"
#include <CLI/CLI.hpp>

#include <memory>

#include "feed/feed.hpp"

namespace locus::app {

Subcommand add_feed_command(CLI::App& cli) {
  auto opts = std::make_shared<feed::FeedOptions>();
  auto* cmd = cli.add_subcommand(
      "feed", "play a scene device's recorded sensors in real time into the interfaces a live node reads: imu.csv into "
              "a fake IIO device, ble.csv through python3-dbusmock's BlueZ on $DBUS_SYSTEM_BUS_ADDRESS (docs/room.md)");
  cmd->add_option("scene", opts->scene_dir, "scene directory")->required();
  cmd->add_option("device", opts->device, "the scene device whose imu.csv and ble.csv are played")->required();
  cmd->add_option("--iio-root", opts->iio_root, "create the fake IIO tree here (a new directory; removed at the end); "
                                                "without it no IMU is played");
  cmd->add_option("--adapter", opts->adapter, "the BlueZ adapter the feed adds to dbusmock (AddAdapter)");
  cmd->add_flag("!--no-ble", opts->ble, "do not play ble.csv");
  cmd->add_option("--speed", opts->speed, "scene seconds per wall second (IMU stamps and adverts both compressed)")
      ->check(CLI::Range(0.01, 100.0));
  cmd->add_option("--lead-in", opts->lead_in_s, "seconds from the node being ready to the first row")->check(CLI::Range(0.0, 60.0));
  cmd->add_option("--start-timeout", opts->start_timeout_s, "seconds to wait for bluetoothd and for the node (IIO buffer open, discovery on)")
      ->check(CLI::Range(0.1, 3600.0));
  cmd->add_flag("--exit-when-done", opts->exit_when_done, "exit after the last row (default: keep the IIO device open until SIGINT/SIGTERM)");
  return Subcommand{cmd, [opts] { return feed::run_feed(*opts); }};
}

}  // namespace locus::app
