// locusd: the Locus node daemon. Runs the pipeline a config describes until its finite sources end
// or SIGINT/SIGTERM arrives, writing estimates and events as JSON lines (docs/events.md).
//
// `--scene DIR` runs the config over a recorded scene instead of the node's own devices: one node per
// scene device over one in-process link, exactly `locus replay` (tools/replay), paced by `--speed`
// (realtime by default here: the daemon behaves as if the boards were live; `max` for batch work).
#include <iostream>
#include <CLI/CLI.hpp>
#include <optional>
#include <string>

#include "app.hpp"
#include "replay/replay.hpp"

int main(int argc, char** argv) {
  CLI::App cli{"locusd: the Locus localization daemon"};
  locus::app::RunOptions opts;
  locus::app::add_run_options(cli, opts);
  std::optional<std::string> scene;
  std::string speed = "realtime";
  std::optional<std::string> events;
  cli.add_option("--scene", scene, "replay this scene directory through the config (one node per scene device)");
  cli.add_option("--speed", speed, "with --scene: realtime (paced like live devices, default) or max")
      ->check(CLI::IsMember({"max", "realtime"}));
  cli.add_option("--events", events, "with --scene: comma-separated event types to write (default: estimate)");
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = cli.exit(e);
    return code == 0 ? 0 : locus::app::kExitBadConfig;
  }
  if (scene) {
    locus::app::ReplayOptions ro;
    ro.scene_dir = *scene;
    ro.config_path = opts.config_path;
    ro.speed = speed;
    ro.output = opts.output;
    ro.events = events;
    ro.log_level = opts.log_level;
    return locus::app::run_replay(ro);
  }
  if (cli.count("--speed") > 0 || events) {
    std::cerr << "locusd: --speed and --events need --scene\n";
    return locus::app::kExitBadConfig;
  }
  return locus::app::run_node(opts);
}
