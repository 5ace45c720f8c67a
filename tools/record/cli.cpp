#include "record/cli.hpp"
#include <CLI/CLI.hpp>

#include <memory>

#include "record/record.hpp"

namespace locus::app {

Subcommand add_record_command(CLI::App& cli) {
  auto opts = std::make_shared<RecordOptions>();
  CLI::App* cmd = cli.add_subcommand("record", "record a node's live streams into a scene directory (replayable)");
  cmd->add_option("out", opts->out_dir, "scene directory to write (created; must be empty unless --overwrite)")
      ->required();
  cmd->add_option("-c,--config", opts->config_path, "node configuration (YAML): the devices and their sources")
      ->required();
  cmd->add_option("-d,--duration", opts->duration_s,
                  "seconds of audio to record per device (default: until every stream ends or Ctrl-C)");
  cmd->add_flag("--overwrite", opts->overwrite, "replace an existing scene directory");
  cmd->add_option("--sample-format", opts->sample_format,
                  "WAV encoding: auto (as the source delivers), float32, int16, int24, int32")
      ->check(CLI::IsMember({"auto", "float32", "int16", "int24", "int32"}));
  cmd->add_option("--name", opts->name, "scene name written to scene.yaml (default: the directory's name)");
  cmd->add_option("--log-level", opts->log_level, "trace|debug|info|warn|error (overrides the config)")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
  return Subcommand{cmd, [opts] { return run_record(*opts); }};
}

}  // namespace locus::app
