// Resources the host owns and injects into every plugin (as PipeWire injects its support interfaces):
// a logger, a clock, an FFT planner, the link, and an event publisher. Plugins never create their
// own threads for these and never reach for globals.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "locus/emitter.hpp"
#include "locus/events.hpp"
#include "locus/fft.hpp"
#include "locus/link.hpp"
#include "locus/signal.hpp"

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

/// Where the parts of the device a plugin instance serves are, and what it and the scene emit (part of
/// the plugin ABI).
///
/// The host fills it when it knows the device: `locus replay` from the scene's scene.yaml (mics,
/// speaker, emits, anchor of that device, docs/scene-format.md); a node run from a config with a
/// `geometry:` section from that (no signals); a node run from a config alone has no geometry
/// (HostContext::geometry == nullptr). Positions are metres; mics and speaker in the device body frame
/// (Android convention), the anchor in the world frame. The object and the signals its spans point to
/// are owned by the host and stay valid and unchanged for the plugin instance's lifetime; the signals
/// were validated by the host (check_signal finds nothing wrong with them, though their type may be
/// one this build does not know: see is_known_signal_type).
struct DeviceGeometry {
  static constexpr std::uint32_t kMaxMics = 32;
  std::uint32_t mic_count = 0;                           ///< valid rows of mics_m = audio channels
  std::array<std::array<double, 3>, kMaxMics> mics_m{};  ///< one per audio channel, channel order
  bool has_speaker = false;                              ///< false: the device cannot emit
  std::array<double, 3> speaker_m{};
  bool has_anchor = false;                               ///< true: the device's position is known
  std::array<double, 3> anchor_m{};                      ///< world frame
  /// The device's `emits` list, in scene order (empty when it emits nothing).
  std::span<const SignalSpec> emits;
  /// Every signal any device or emitter of the scene emits, with its emitter's id, in scene order
  /// (empty when the host knows no scene). Lets a listener's detector take its template from the
  /// scene instead of its config.
  std::span<const SceneSignal> scene_emits;
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
  /// Geometry of `device` when the host knows it (replay), else nullptr. See DeviceGeometry.
  const DeviceGeometry* geometry = nullptr;
  /// The device's emitter when it has a `playback:` section (a live node), else nullptr (replay: the
  /// scene already holds what was played). See emitter.hpp.
  Emitter* emitter = nullptr;
};

}  // namespace locus
