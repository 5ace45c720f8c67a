// Resources the host owns and injects into every plugin (as PipeWire injects its support interfaces):
// a logger, a clock, an FFT planner, the link, and an event publisher. Plugins never create their
// own threads for these and never reach for globals.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "locus/events.hpp"
#include "locus/fft.hpp"
#include "locus/link.hpp"

namespace locus {

enum class LogLevel : std::uint8_t { Trace, Debug, Info, Warn, Error };

/// [main] Logging for plugins. Never call it from an [RT] method: count there, report later.
class Logger {
 public:
  virtual ~Logger() = default;
  virtual void log(LogLevel level, std::string_view message) = 0;
  void debug(std::string_view m) { log(LogLevel::Debug, m); }
  void info(std::string_view m) { log(LogLevel::Info, m); }
  void warn(std::string_view m) { log(LogLevel::Warn, m); }
  void error(std::string_view m) { log(LogLevel::Error, m); }
};

/// Monotonic host time, for the [main] side only (timeouts, pacing). Measurements never use it:
/// they carry stream time (frame counters, device-local sensor time).
class Clock {
 public:
  virtual ~Clock() = default;
  virtual double now_s() const noexcept = 0;
};

/// Where a localizer sends what it produces. [main] (the dispatcher thread).
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual void publish(const Event& event) = 0;
};

/// Everything a plugin instance gets from its host at configure() time. References stay valid until
/// the instance is destroyed.
struct HostContext {
  Logger& log;
  const Clock& clock;
  FftPlanner& fft;
  Link& link;                  ///< for localizers; handlers are delivered on the dispatcher thread
  std::string_view instance;   ///< this instance's name from the config
  std::string_view device;     ///< the device this instance serves ("" for node-wide localizers)
};

}  // namespace locus
