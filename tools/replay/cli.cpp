#include "replay/cli.hpp"
#include <CLI/CLI.hpp>

#include <memory>

#include "replay/replay.hpp"

namespace locus::app {

Subcommand add_replay_command(CLI::App& cli) {
  auto opts = std::make_shared<ReplayOptions>();
  CLI::App* cmd = cli.add_subcommand("replay", "replay a scene directory through the pipeline, one node per device");
  cmd->add_option("scene", opts->scene_dir, "scene directory (holding scene.yaml)")->required();
  cmd->add_option("-c,--config", opts->config_path, "node configuration (YAML): what runs on the devices")->required();
  cmd->add_option("--speed", opts->speed, "max (as fast as possible, exact time order) or realtime (paced)")
      ->check(CLI::IsMember({"max", "realtime"}));
  cmd->add_option("-o,--out", opts->output, "write JSON lines here ('-' = stdout; default: the config's output.path)");
  cmd->add_option("--events", opts->events, "comma-separated event types to write (default: the config's output.events, else estimate)");
  cmd->add_option("--log-level", opts->log_level, "trace|debug|info|warn|error (overrides the config)")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
  return Subcommand{cmd, [opts] { return run_replay(*opts); }};
}

}  // namespace locus::app
