// Host logging: spdlog behind the plugin-facing locus::Logger interface, and the steady host clock.
#pragma once

#include <memory>
#include <string>

#include "locus/host.hpp"

namespace spdlog {
class logger;
}

namespace locus {

/// [main] Sets the level of every Locus logger (they all write to stderr).
void set_log_level(LogLevel level);
/// The process-wide spdlog logger Locus writes to (stderr, created on first use).
std::shared_ptr<spdlog::logger> host_logger();

/// A Logger that prefixes messages with a component name ("onset_a: ...").
class SpdLogger final : public Logger {
 public:
  explicit SpdLogger(std::string component) : component_(std::move(component)) {}
  void log(LogLevel level, std::string_view message) override;

 private:
  std::string component_;
};

class SteadyClock final : public Clock {
 public:
  double now_s() const noexcept override;
};

}  // namespace locus
