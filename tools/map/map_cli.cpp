#include "map_cli.hpp"

#include <CLI/CLI.hpp>

#include <csignal>
#include <ctime>
#include <iostream>
#include <map>

#include "app.hpp"
#include "locus/build_options.hpp"
#include "locus/config.hpp"

namespace locus::map {

namespace {

std::vector<std::pair<std::string, std::string>> split_kv(const std::vector<std::string>& items, const char* option,
                                                          std::vector<std::string>& errors) {
  std::vector<std::pair<std::string, std::string>> kv;
  for (const std::string& item : items) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0) {
      errors.push_back(std::string(option) + ": '" + item + "': expected KEY=VALUE");
      continue;
    }
    kv.emplace_back(item.substr(0, eq), item.substr(eq + 1));
  }
  return kv;
}

}  // namespace

void add_http_options(CLI::App& cli, HttpCli& o) {
  cli.add_option("--http", o.listen,
                 "serve the live map at [HOST:]PORT (HOST defaults to 127.0.0.1; 0 = any free port; "
                 "another address only when given here)");
  cli.add_option("--http-param", o.params, "a map parameter KEY=VALUE (repeatable; docs/map.md)");
  cli.add_flag("--hub", o.hub, "hub mode: no pipeline; show every node's estimates received over MQTT (needs --http)");
  cli.add_option("--hub-param", o.hub_params, "a hub parameter KEY=VALUE: the MQTT connection (host, port, ...) and topic_prefix");
}

std::optional<MapOptions> parse_map_options(const HttpCli& o) {
  std::vector<std::string> errors;
  const auto kv = split_kv(o.params, "--http-param", errors);
  std::vector<ConfigError> config_errors;
  const Params params = validate_params(map_schema(), kv, config_errors);
  for (const ConfigError& e : config_errors) errors.push_back("--http-param " + e.key + ": " + e.message);
  std::optional<MapOptions> out;
  if (errors.empty()) {
    try {
      out = map_options(*o.listen, params);
    } catch (const MapError& e) {
      errors.push_back(e.what());
    }
  }
  for (const std::string& e : errors) std::cerr << "locusd: " << e << "\n";
  if (!errors.empty()) return std::nullopt;
  return out;
}

app::PipelineHooks map_hooks(MapServer& map, const std::string& what) {
  app::PipelineHooks h;
  auto next = std::make_shared<std::map<std::string, double>>();
  h.built = [&map](const std::string& node, Pipeline& p) {
    map.attach(node, p);
    map.set_link_state(node, p.link_kind());
  };
  h.tick = [&map, next](const std::string& node, const Pipeline& p) {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    const double now = static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
    double& due = (*next)[node];
    if (now < due) return;
    due = now + map.options().health_period_s;
    map.set_health(node, p.live_stats());
  };
  h.ended = [&map, what](bool interrupted) { map.set_status(what + (interrupted ? ": stopped" : ": finished"), true); };
  return h;
}

void linger(MapServer& map, Logger& log) {
  const double s = map.options().linger_s;
  if (s <= 0.0) return;
  log.info("still serving " + map.url() + " for " + std::to_string(static_cast<int>(s)) +
           " s (linger_s); SIGINT/SIGTERM ends it");
  const sigset_t stop_signals = app::stop_signal_set();
  timespec timeout{static_cast<time_t>(s), static_cast<long>((s - static_cast<double>(static_cast<time_t>(s))) * 1e9)};
  sigtimedwait(&stop_signals, nullptr, &timeout);
}

#if !LOCUS_HAVE_MQTT
bool hub_available() noexcept { return false; }
int run_hub(MapServer&, const std::vector<std::string>&, Logger&) {
  std::cerr << "locusd: --hub needs MQTT: " << build::not_built_reason(*build::find_optional_backend("mqtt")) << "\n";
  return 2;
}
#endif

}  // namespace locus::map
