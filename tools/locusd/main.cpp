// locusd: the Locus node daemon. Runs the pipeline a config describes until its finite sources end
// or SIGINT/SIGTERM arrives, writing estimates and events as JSON lines (docs/events.md).
//
// `--scene DIR` runs the config over a recorded scene instead of the node's own devices: one node per
// scene device over one in-process link, exactly `locus replay` (tools/replay), paced by `--speed`
// (realtime by default here: the daemon behaves as if the boards were live; `max` for batch work).
//
// `--http [HOST:]PORT` also serves the live map (tools/map, docs/map.md) of whatever runs: the node,
// the replay, or with `--hub` (no config) every node of a site over MQTT. Built with LOCUS_WITH_HTTP.
#include <csignal>
#include <iostream>
#include <CLI/CLI.hpp>
#include <optional>
#include <pthread.h>
#include <string>

#include "app.hpp"
#include "locus/build_options.hpp"
#include "locus/logging.hpp"
#include "replay/replay.hpp"
#if LOCUS_HAVE_HTTP
#include "map_cli.hpp"
#endif

int main(int argc, char** argv) {
  // The stop signals are blocked before any thread exists (the map's server threads included), so
  // only the sigtimedwait of the main loop ever sees them.
  const sigset_t stop_signals = locus::app::block_stop_signals();

  CLI::App cli{"locusd: the Locus localization daemon"};
  locus::app::RunOptions opts;
  locus::app::add_run_options(cli, opts, /*config_required=*/false);
  std::optional<std::string> scene;
  std::string speed = "realtime";
  std::optional<std::string> events;
  cli.add_option("--scene", scene, "replay this scene directory through the config (one node per scene device)");
  cli.add_option("--speed", speed, "with --scene: realtime (paced like live devices, default) or max")
      ->check(CLI::IsMember({"max", "realtime"}));
  cli.add_option("--events", events, "with --scene: comma-separated event types to write (default: estimate)");
  std::optional<std::string> layout;
  cli.add_option("--layout", layout,
                 "a live node's declarations from this scene directory's scene.yaml (no stream is read): each config "
                 "device with a scene device's or emitter's id gets its mics, speaker, anchor and emits, and every plugin "
                 "the scene's signals (beacons, codes), as in a replay; they override the config's geometry: sections");
#if LOCUS_HAVE_HTTP
  locus::map::HttpCli http;
  locus::map::add_http_options(cli, http);
#else
  std::optional<std::string> http_listen;
  cli.add_option("--http", http_listen, "the live map (not built in)");
#endif
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = cli.exit(e);
    return code == 0 ? 0 : locus::app::kExitBadConfig;
  }
  if (layout) {
    if (scene) {
      std::cerr << "locusd: --layout is for a live node; --scene takes the declarations from its scene already\n";
      return locus::app::kExitBadConfig;
    }
    try {
      opts.geometry = locus::app::layout_geometry(locus::scene::load_scene(*layout));
    } catch (const std::exception& e) {
      std::cerr << "locusd: --layout " << *layout << ": " << e.what() << "\n";
      return locus::app::kExitBadConfig;
    }
  }
  if (cli.count("--speed") > 0 || events) {
    if (!scene) {
      std::cerr << "locusd: --speed and --events need --scene\n";
      return locus::app::kExitBadConfig;
    }
  }
#if LOCUS_HAVE_HTTP
  std::unique_ptr<locus::map::MapServer> map;
  std::optional<locus::SpdLogger> map_log;
  bool interrupted = false;
  if (http.hub && !http.listen) {
    std::cerr << "locusd: --hub serves a map: give --http [HOST:]PORT\n";
    return locus::app::kExitBadConfig;
  }
  if (http.hub && (scene || !opts.config_path.empty())) {
    std::cerr << "locusd: --hub runs no pipeline: it takes neither --config nor --scene\n";
    return locus::app::kExitBadConfig;
  }
  if ((!http.params.empty() && !http.listen) || (!http.hub_params.empty() && !http.hub)) {
    std::cerr << "locusd: --http-param needs --http, --hub-param needs --hub\n";
    return locus::app::kExitBadConfig;
  }
  if (!http.hub && opts.config_path.empty()) {
    std::cerr << "locusd: --config is required (except with --hub)\n";
    return locus::app::kExitBadConfig;
  }
  if (http.listen) {
    const std::optional<locus::map::MapOptions> mo = locus::map::parse_map_options(http);
    if (!mo) return locus::app::kExitBadConfig;
    if (opts.log_level) {
      locus::LogLevel level{};
      if (locus::app::parse_log_level(*opts.log_level, level)) locus::set_log_level(level);
    }
    map_log.emplace("map");
    try {
      map = std::make_unique<locus::map::MapServer>(*mo, *map_log);
    } catch (const std::exception& e) {
      std::cerr << "locusd: " << e.what() << "\n";
      return locus::app::kExitFailure;
    }
    map->start();
    // One line on stdout, so that scripts (./run demo) and people find the page.
    std::cout << "map: " << map->url() << std::endl;
    if (http.hub) {
      const int status = locus::map::run_hub(*map, http.hub_params, *map_log);
      map->stop();
      return status;
    }
    opts.hooks = locus::map::map_hooks(*map, scene ? "replay of " + *scene : "node " + opts.config_path);
    // A run stopped by SIGINT/SIGTERM does not linger: the signal meant "stop".
    opts.hooks.ended = [ended = opts.hooks.ended, &interrupted](bool stopped) {
      interrupted = stopped;
      ended(stopped);
    };
    map->set_status(scene ? "replaying " + *scene : "running " + opts.config_path, false);
  }
  const auto finish = [&](int status) {
    if (map) {
      if (!interrupted) locus::map::linger(*map, *map_log);
      map->stop();
    }
    return status;
  };
#else
  if (http_listen) {
    std::cerr << "locusd: --http: " << locus::build::not_built_reason(*locus::build::find_optional_backend("http"))
              << "\n";
    return locus::app::kExitBadConfig;
  }
  if (opts.config_path.empty()) {
    std::cerr << "locusd: --config is required\n";
    return locus::app::kExitBadConfig;
  }
  const auto finish = [](int status) { return status; };
#endif
  if (scene) {
    locus::app::ReplayOptions ro;
    ro.scene_dir = *scene;
    ro.config_path = opts.config_path;
    ro.speed = speed;
    ro.output = opts.output;
    ro.events = events;
    ro.log_level = opts.log_level;
    ro.hooks = opts.hooks;
    return finish(locus::app::run_replay(ro));
  }
  return finish(locus::app::run_node(opts));
}
