// Shared implementation of the command-line tools (locusd, locus): each command is a function
// returning the process exit status, so the binaries stay thin and tests can call commands directly.
//
// Exit status: 0 success, 1 runtime failure, 2 bad config or usage, 3 a plugin library failed to load.
#pragma once

#include <csignal>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

// CLI11 is not included here: it costs ~10 s of compile time per translation unit (its headers define
// validator objects with static constructors); only the files that build command lines include it.
namespace CLI {
class App;
}  // namespace CLI

#include "locus/host.hpp"
#include "locus/pipeline.hpp"

namespace locus {
class Pipeline;
}  // namespace locus

namespace locus::app {

/// What an embedder (locusd's live map) gets to see of the pipelines a command runs; every hook is
/// optional and runs on the main thread.
struct PipelineHooks {
  /// Each node's pipeline once built, before it starts (subscribe here). `node`: the node's name (the
  /// scene device id in a replay, the config file's stem for a node).
  std::function<void(const std::string& node, Pipeline& pipeline)> built;
  /// About every 50 ms while the pipelines run, for each node (read live_stats() here).
  std::function<void(const std::string& node, const Pipeline& pipeline)> tick;
  /// Once, after everything was flushed (`interrupted`: stopped by SIGINT/SIGTERM).
  std::function<void(bool interrupted)> ended;
};

/// SIGINT and SIGTERM: the signals that stop a command (its main thread waits for them with
/// sigtimedwait()).
sigset_t stop_signal_set();
/// Blocks stop_signal_set() in the calling thread and in every thread it starts later, so that only
/// the command's own sigtimedwait() sees them; call before any thread exists. Returns the set.
sigset_t block_stop_signals();

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitBadConfig = 2;
inline constexpr int kExitPluginLoad = 3;

struct RunOptions {
  std::string config_path;
  std::optional<std::string> output;  ///< overrides output.path
  std::optional<std::string> log_level;
  PipelineHooks hooks;
  /// Declarations by device id that override the config's `geometry:` sections (locusd --layout:
  /// a scene's devices and emitters, with the scene's signals).
  std::map<std::string, GeometrySpec> geometry;
};

/// "trace" | "debug" | "info" | "warn" | "error" -> LogLevel; false for anything else.
bool parse_log_level(const std::string& s, LogLevel& out);

/// Adds the options of RunOptions to a CLI11 (sub)command. `config_required` = false leaves the check
/// of --config to the caller (locusd --hub runs without one).
void add_run_options(CLI::App& cmd, RunOptions& opts, bool config_required = true);

/// Runs a node from a config until its finite sources end or SIGINT/SIGTERM arrives; flushes all
/// output before returning.
int run_node(const RunOptions& opts);

/// Lists built-in and loaded plugins (and audio sources) with their parameter schemas, then the
/// optional backends this build lacks ("jack not-built-in" + the reason; JSON: "not_built").
int list_plugins(const std::vector<std::string>& plugin_dirs, bool json);

/// Validates a config and prints every error; 0 when valid, 2 otherwise.
int check_config(const std::string& path);

}  // namespace locus::app
