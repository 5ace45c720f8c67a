// locus: the multi-command tool (run, check-config, plugins, version; later: simulate, replay, eval,
// record, devices). Each subcommand is a function in tools/app.
#include <iostream>
#include <CLI/CLI.hpp>

#include "app.hpp"
#include "locus/build_options.hpp"
#include "locus/plugin.hpp"
#include "subcommand.hpp"
// Tool modules (tools/<name>/cli.hpp): one include and one line in `modules` below each.
#include "devices/cli.hpp"
#include "eval/cli.hpp"
#ifdef LOCUS_WITH_FEED
#include "feed/cli.hpp"
#endif
#include "record/cli.hpp"
#include "replay/cli.hpp"
#ifdef LOCUS_WITH_ROOM
#include "room/cli.hpp"
#endif
#include "sim/cli.hpp"
#include "train/cli.hpp"

int main(int argc, char** argv) {
  CLI::App cli{"locus: localization from sound, motion and radio"};
  cli.require_subcommand(1);

  locus::app::RunOptions run_opts;
  auto* run = cli.add_subcommand("run", "run a node from a config (same as locusd)");
  locus::app::add_run_options(*run, run_opts);

  std::string config_path;
  auto* check = cli.add_subcommand("check-config", "validate a config and print every error (exit 2 if any)");
  check->add_option("config", config_path, "config file")->required();

  std::vector<std::string> plugin_dirs;
  bool json = false;
  auto* plugins = cli.add_subcommand("plugins", "list plugins and audio sources with their parameters");
  plugins->add_option("--plugin-dir", plugin_dirs, "also load every *.so in this directory (repeatable)");
  plugins->add_flag("--json", json, "machine-readable output");

#ifndef LOCUS_WITH_FEED
  auto* feed = cli.add_subcommand("feed", "play a scene's IMU and BLE into IIO and BlueZ (not built: it needs BlueZ)");
  feed->allow_extras();
#endif
#ifndef LOCUS_WITH_ROOM
  auto* room = cli.add_subcommand("room", "a hardware-in-the-loop room (not built: it needs JACK)");
  room->allow_extras();
#endif
  auto* version = cli.add_subcommand("version", "print the version, the plugin ABI and the optional backends built in");

  std::vector<locus::app::Subcommand> modules = {
      locus::app::add_devices_command(cli),
      locus::app::add_eval_command(cli),
#ifdef LOCUS_WITH_FEED
      locus::app::add_feed_command(cli),
#endif
      locus::app::add_record_command(cli),
      locus::app::add_replay_command(cli),
#ifdef LOCUS_WITH_ROOM
      locus::app::add_room_command(cli),
#endif
      locus::app::add_simulate_command(cli),
      locus::app::add_train_command(cli),
  };

  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = cli.exit(e);
    return code == 0 ? 0 : locus::app::kExitBadConfig;
  }
  if (*run) return locus::app::run_node(run_opts);
  if (*check) return locus::app::check_config(config_path);
  if (*plugins) return locus::app::list_plugins(plugin_dirs, json);
  for (const auto& m : modules) {
    if (*m.cmd) return m.run();
  }
#ifndef LOCUS_WITH_FEED
  if (*feed) {
    std::cerr << "locus feed: " << locus::build::not_built_reason(*locus::build::find_optional_backend("bluez")) << "\n";
    return locus::app::kExitBadConfig;
  }
#endif
#ifndef LOCUS_WITH_ROOM
  if (*room) {
    std::cerr << "locus room: " << locus::build::not_built_reason(*locus::build::find_optional_backend("jack")) << "\n";
    return locus::app::kExitBadConfig;
  }
#endif
  if (*version) {
    std::cout << "locus " << LOCUS_VERSION << " (plugin ABI " << LOCUS_PLUGIN_ABI_VERSION << ")\n";
    // Optional backends (LOCUS_WITH_<X>, cmake/LocusBackends.cmake): one line each, built in or why not.
    std::cout << "optional backends:\n";
    for (const locus::build::OptionalBackend& b : locus::build::kOptionalBackends) {
      std::cout << "  " << b.name << std::string(8 - b.name.size(), ' ')
                << (b.built ? "built in (" + std::string(b.library) + ")" : locus::build::not_built_reason(b)) << "\n";
    }
    return 0;
  }
  return 0;
}
