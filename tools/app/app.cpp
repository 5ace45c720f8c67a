#include "app.hpp"
#include <CLI/CLI.hpp>

#include <csignal>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <pthread.h>
#include <sstream>

#include "locus/config.hpp"
#include "locus/logging.hpp"
#include <spdlog/spdlog.h>
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"

namespace locus::app {

bool parse_log_level(const std::string& s, LogLevel& out) {
  static const std::pair<const char*, LogLevel> kLevels[] = {{"trace", LogLevel::Trace}, {"debug", LogLevel::Debug},
                                                             {"info", LogLevel::Info},   {"warn", LogLevel::Warn},
                                                             {"error", LogLevel::Error}};
  for (const auto& [name, level] : kLevels) {
    if (s == name) {
      out = level;
      return true;
    }
  }
  return false;
}

namespace {

void print_config_errors(const ConfigErrors& e) {
  for (const ConfigError& err : e.errors()) std::cerr << err.format() << "\n";
  std::cerr << e.errors().size() << (e.errors().size() == 1 ? " error" : " errors") << " in the config; nothing was run\n";
}

std::string value_text(const ParamValue& v) {
  struct V {
    std::string operator()(std::monostate) const { return "(required)"; }
    std::string operator()(bool b) const { return b ? "true" : "false"; }
    std::string operator()(std::int64_t i) const { return std::to_string(i); }
    std::string operator()(double d) const {
      std::ostringstream os;
      os << d;
      return os.str();
    }
    std::string operator()(const std::string& s) const { return s; }
    std::string operator()(const std::vector<double>& list) const {
      std::ostringstream os;
      os << "[";
      for (std::size_t i = 0; i < list.size(); ++i) os << (i ? ", " : "") << list[i];
      os << "]";
      return os.str();
    }
  };
  return std::visit(V{}, v);
}

nlohmann::json value_json(const ParamValue& v) {
  struct V {
    nlohmann::json operator()(std::monostate) const { return nullptr; }
    nlohmann::json operator()(bool b) const { return b; }
    nlohmann::json operator()(std::int64_t i) const { return i; }
    nlohmann::json operator()(double d) const { return d; }
    nlohmann::json operator()(const std::string& s) const { return s; }
    nlohmann::json operator()(const std::vector<double>& l) const { return l; }
  };
  return std::visit(V{}, v);
}

nlohmann::json schema_json(const ParamSchema& schema) {
  nlohmann::json out = nlohmann::json::array();
  for (const ParamSpec& p : schema) {
    nlohmann::json j{{"key", p.key}, {"type", std::string(param_type_name(p.type))}, {"default", value_json(p.default_value)},
                     {"required", p.required()}, {"unit", p.unit}, {"doc", p.doc}};
    if (p.min) j["min"] = *p.min;
    if (p.max) j["max"] = *p.max;
    if (!p.choices.empty()) j["choices"] = p.choices;
    out.push_back(j);
  }
  return out;
}

void print_schema(const ParamSchema& schema) {
  for (const ParamSpec& p : schema) {
    std::cout << "    " << p.key << " (" << param_type_name(p.type);
    if (!p.unit.empty()) std::cout << ", " << p.unit;
    std::cout << ") default " << value_text(p.default_value);
    if (p.min || p.max) {
      std::cout << " range [" << (p.min ? value_text(*p.min) : "-inf") << ", " << (p.max ? value_text(*p.max) : "inf") << "]";
    }
    if (!p.choices.empty()) {
      std::cout << " one of {";
      for (std::size_t i = 0; i < p.choices.size(); ++i) std::cout << (i ? ", " : "") << p.choices[i];
      std::cout << "}";
    }
    std::cout << ": " << p.doc << "\n";
  }
}

const char* kind_name(std::uint32_t kind) {
  return kind == LOCUS_PLUGIN_DETECTOR ? "detector" : kind == LOCUS_PLUGIN_LOCALIZER ? "localizer" : "unknown";
}

}  // namespace

void add_run_options(CLI::App& cmd, RunOptions& opts, bool config_required) {
  auto* config = cmd.add_option("-c,--config", opts.config_path, "node configuration (YAML), see docs/config.md");
  if (config_required) config->required();
  cmd.add_option("-o,--output", opts.output, "write JSON lines here instead of the config's output.path ('-' = stdout)");
  cmd.add_option("--log-level", opts.log_level, "trace|debug|info|warn|error (overrides the config)")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
}

sigset_t stop_signal_set() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  return set;
}

sigset_t block_stop_signals() {
  const sigset_t set = stop_signal_set();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  return set;
}

int run_node(const RunOptions& opts) {
  // Block the stop signals before any thread exists, so only sigtimedwait below ever sees them.
  const sigset_t stop_signals = block_stop_signals();
  // A daemon outlives its consumers: an output pipe whose reader went away is a counted, logged write
  // error (JsonLinesWriter), not the end of the node (which also feeds MQTT and its localizers).
  std::signal(SIGPIPE, SIG_IGN);

  Registry registry;
  register_builtins(registry);
  Config config;
  try {
    config = load_config(opts.config_path, registry);
  } catch (const ConfigErrors& e) {
    print_config_errors(e);
    return kExitBadConfig;
  }
  if (opts.output) config.output.path = *opts.output;
  LogLevel level = config.log_level;
  if (opts.log_level) parse_log_level(*opts.log_level, level);
  set_log_level(level);
  auto log = host_logger();

  try {
    PipelineOptions po;
    po.geometry = opts.geometry;
    Pipeline pipeline(config, registry, std::move(po));
    std::string node = config.file;
    if (const auto slash = node.rfind('/'); slash != std::string::npos) node = node.substr(slash + 1);
    if (const auto dot = node.rfind('.'); dot != std::string::npos && dot > 0) node = node.substr(0, dot);
    if (opts.hooks.built) opts.hooks.built(node, pipeline);
    pipeline.start();
    log->info("running {} ({} devices, {} localizers)", config.file, config.devices.size(), config.localizers.size());
    int signal_number = 0;
    while (!pipeline.finished()) {
      if (opts.hooks.tick) opts.hooks.tick(node, pipeline);
      timespec timeout{0, 50'000'000};
      const int sig = sigtimedwait(&stop_signals, nullptr, &timeout);
      if (sig > 0) {
        signal_number = sig;
        break;
      }
    }
    if (signal_number) log->info("{} received: stopping", signal_number == SIGINT ? "SIGINT" : "SIGTERM");
    pipeline.stop();
    if (opts.hooks.tick) opts.hooks.tick(node, pipeline);
    if (opts.hooks.ended) opts.hooks.ended(signal_number != 0);
    for (const DeviceStats& s : pipeline.stats()) {
      if (!s.source_error.empty()) {
        log->error("device {}: {}", s.id, s.source_error);
        return kExitFailure;
      }
    }
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    return kExitFailure;
  }
  return kExitOk;
}

int list_plugins(const std::vector<std::string>& plugin_dirs, bool json) {
  Registry registry;
  register_builtins(registry);
  int status = kExitOk;
  for (const std::string& dir : plugin_dirs) {
    for (const std::string& failure : registry.load_directory(dir)) {
      std::cerr << failure << "\n";
      status = kExitPluginLoad;
    }
  }
  if (json) {
    nlohmann::json out{{"plugins", nlohmann::json::array()}, {"sources", nlohmann::json::array()}};
    // Host-side backends other than audio sources, one array each, same shape as "sources".
    auto add_named = [&](const char* key, const auto& list, auto&& extra) {
      out[key] = nlohmann::json::array();
      for (const auto& s : list) {
        nlohmann::json j{{"name", s.name}, {"description", s.description}, {"params", schema_json(s.schema)}};
        extra(j, s);
        out[key].push_back(std::move(j));
      }
    };
    const auto none = [](nlohmann::json&, const auto&) {};
    add_named("sensor_sources", registry.sensor_sources(),
              [](nlohmann::json& j, const SensorSourceDescriptor& s) { j["kind"] = sensor_kind_name(s.kind); });
    add_named("sinks", registry.sinks(), none);
    add_named("links", registry.links(), none);
    add_named("outputs", registry.outputs(), none);
    // Optional backends this build lacks (LOCUS_WITH_<X>): what a config may not name, and why.
    out["not_built"] = nlohmann::json::array();
    for (const NotBuiltBackend& b : registry.not_built()) {
      out["not_built"].push_back({{"name", b.name}, {"reason", b.reason}});
    }
    for (const auto& entry : registry.plugins()) {
      const auto* d = entry.descriptor;
      out["plugins"].push_back({{"name", d->name}, {"kind", kind_name(d->kind)}, {"version", d->version},
                                {"origin", entry.origin}, {"description", d->description ? d->description : ""},
                                {"params", schema_json(*d->schema())}});
    }
    for (const auto& s : registry.sources()) {
      out["sources"].push_back({{"name", s.name}, {"description", s.description}, {"params", schema_json(s.schema)}});
    }
    std::cout << out.dump(2) << "\n";
    return status;
  }
  for (const auto& entry : registry.plugins()) {
    const auto* d = entry.descriptor;
    std::cout << d->name << " " << kind_name(d->kind) << " " << d->version << " " << entry.origin << "\n";
    if (d->description) std::cout << "    " << d->description << "\n";
    print_schema(*d->schema());
  }
  auto print_named = [](const auto& list, const std::string& what) {
    for (const auto& s : list) {
      std::cout << s.name << " " << what << " built-in\n    " << s.description << "\n";
      print_schema(s.schema);
    }
  };
  print_named(registry.sources(), "source");
  for (const auto& s : registry.sensor_sources()) {
    std::cout << s.name << " " << sensor_kind_name(s.kind) << "-source built-in\n    " << s.description << "\n";
    print_schema(s.schema);
  }
  print_named(registry.sinks(), "playback-sink");
  print_named(registry.links(), "link");
  print_named(registry.outputs(), "output");
  for (const NotBuiltBackend& b : registry.not_built()) {
    std::cout << b.name << " not-built-in\n    " << b.reason << "\n";
  }
  return status;
}

int check_config(const std::string& path) {
  Registry registry;
  register_builtins(registry);
  try {
    const Config config = load_config(path, registry);
    std::cout << path << ": valid (" << config.devices.size() << " devices, " << config.localizers.size()
              << " localizers)\n";
    return kExitOk;
  } catch (const ConfigErrors& e) {
    print_config_errors(e);
    return kExitBadConfig;
  }
}

}  // namespace locus::app
