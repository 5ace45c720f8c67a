// locusd's command-line side of the live map: the --http / --http-param / --hub / --hub-param options,
// their validation (every error printed, exit 2, like a bad config), the hooks that attach the map to
// the pipelines locusd runs (node or replay), and hub mode (docs/map.md).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "app.hpp"
#include "map_server.hpp"

namespace CLI {
class App;
}  // namespace CLI

namespace locus::map {

struct HttpCli {
  std::optional<std::string> listen;     ///< --http [HOST:]PORT
  std::vector<std::string> params;       ///< --http-param KEY=VALUE (map_schema())
  bool hub = false;                      ///< --hub
  std::vector<std::string> hub_params;   ///< --hub-param KEY=VALUE (hub_schema())
};

/// Adds --http, --http-param, --hub, --hub-param.
void add_http_options(CLI::App& cli, HttpCli& o);

/// The map's options from the command line; prints every error to stderr and returns nullopt.
std::optional<MapOptions> parse_map_options(const HttpCli& o);

/// Hooks that attach `map` to every pipeline (taps, devices, link kind), refresh health about every
/// health_period_s and say when the run ended.
app::PipelineHooks map_hooks(MapServer& map, const std::string& what);

/// After a run: keeps serving for linger_s or until SIGINT/SIGTERM (which must be blocked in the
/// calling thread and every thread started after the block, as locusd does first thing).
void linger(MapServer& map, Logger& log);

/// The hub's parameters: the MQTT connection's (docs/mqtt.md) and topic_prefix (only with MQTT).
ParamSchema hub_schema();
/// True when hub mode was built in (needs the MQTT backend).
bool hub_available() noexcept;
/// Hub mode: subscribes to every node's events over MQTT and feeds `map` until SIGINT/SIGTERM.
/// Returns the exit status (2 for bad hub parameters, 1 when the broker cannot be reached).
int run_hub(MapServer& map, const std::vector<std::string>& hub_params, Logger& log);

}  // namespace locus::map
