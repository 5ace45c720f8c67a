// The steps that build a Pipeline from a validated Config. Pipeline::Pipeline calls them in this order:
//
//   choose_link          the link: the embedder's, config.link's type, or an in-process one
//   add_config_geometry  every device's `geometry:` section as the GeometrySpec its plugins get
//   build_device         per device (see there): open_audio, open_playback, open_sensors,
//                        create_detectors, wire_device
//   served_device,       the localizers, on the device they serve
//   open_localizer
//   open_output          config.outputs
//
// Why: each step is a plain function over plain parts (a Config, a Registry, the host services), so a
// test can run one step without the rest, and every plugin instance gets its HostContext from one
// factory (HostServices::context). Everything here runs on the main thread, before start().
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "locus/config.hpp"
#include "locus/event_bus.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/logging.hpp"
#include "locus/pipeline.hpp"
#include "locus/playback.hpp"
#include "locus/registry.hpp"

namespace locus::pipeline_steps {

/// [main] What every plugin instance of one pipeline shares. context() is the one place a
/// HostContext is made: sources, sinks, sensors, detectors and localizers all get theirs here.
struct HostServices {
  const Clock& clock;
  FftPlanner& fft;
  Link& link;  ///< the pipeline's dispatched link (handlers run on the dispatcher thread)

  /// The context of instance `instance` serving `device` ("" = node-wide). The views, `log`,
  /// `geometry` and `emitter` must outlive the instance (the pipeline owns them all).
  HostContext context(Logger& log, std::string_view instance, std::string_view device,
                      const DeviceGeometry* geometry = nullptr, Emitter* emitter = nullptr) const {
    return HostContext{log, clock, fft, link, instance, device, geometry, emitter};
  }
};

/// The link a pipeline talks through. `link` is what to use; the rest is what the pipeline owns.
struct LinkChoice {
  Link* link = nullptr;
  std::unique_ptr<Link> owned;               ///< config.link's type or an in-process link
  InProcessLink* inprocess = nullptr;        ///< `owned` when it is in-process (the pipeline flushes it)
  std::unique_ptr<SpdLogger> log;            ///< the config link's logger
};

/// [main] `shared` when given (not owned); else config.link's type from the registry; else a new
/// InProcessLink. Throws std::runtime_error "link: unknown type 'x'" or "link 'x': <reason>".
LinkChoice choose_link(const Config& config, const Registry& registry, Link* shared);

/// [main] A device's `geometry:` section as its plugins get it (mics beyond kMaxMics are dropped).
GeometrySpec geometry_from_config(const GeometryConfig& g);

/// [main] Adds the geometry of every non-template device with a `geometry:` section that `geometry`
/// does not list yet (the embedder's wins), then points each DeviceGeometry's JSON fields at its
/// spec's strings. Call it once `geometry` no longer changes (the pointers go into its nodes).
void add_config_geometry(const Config& config, std::map<std::string, GeometrySpec>& geometry);

/// The geometry of device `id`, or nullptr.
const DeviceGeometry* find_geometry(const std::map<std::string, GeometrySpec>& geometry, const std::string& id);

/// Throws std::runtime_error "<what> runs at X Hz but the node is configured for Y Hz
/// (sample_rate_hz)" unless the rates agree (within 1e-6 Hz). `what` names the device and component.
void require_node_rate(const std::string& what, double actual_hz, double node_hz);

/// One device of a pipeline: its streams, sink, detectors and the runners that merge them.
struct Device {
  std::string id;
  const DeviceGeometry* geometry = nullptr;
  std::unique_ptr<SpdLogger> source_log;
  std::unique_ptr<AudioSource> source;
  std::unique_ptr<AudioRing> ring;
  std::unique_ptr<SpdLogger> sink_log;
  std::unique_ptr<AudioSink> sink;              // `playback:` section
  std::unique_ptr<PlaybackScheduler> scheduler;
  std::unique_ptr<SchedulerEmitter> emitter;
  struct Sensor {
    SensorKind kind;
    std::string name;
    std::unique_ptr<SpdLogger> log;
    std::unique_ptr<SensorSource> source;
    std::unique_ptr<SensorQueue> queue;
  };
  std::vector<Sensor> sensors;
  std::vector<std::unique_ptr<SpdLogger>> detector_logs;
  std::vector<std::unique_ptr<Detector>> detectors;
  RtEventQueue* queue = nullptr;
  std::unique_ptr<AudioBlockRunner> runner;
  std::unique_ptr<DeviceRunner> device_runner;
  std::thread thread;
  std::atomic<bool> stop_requested{false};
  std::atomic<bool> done{false};
  bool has_streams() const { return source != nullptr || !sensors.empty(); }
};

/// One localizer of a pipeline.
struct LocalizerInstance {
  std::string name;
  std::unique_ptr<SpdLogger> log;
  std::unique_ptr<Localizer> localizer;
};

/// What a device's detectors are configured with before its streams are open: no channels, the node
/// rate, the audio section's block size (256 without audio).
StreamInfo initial_stream_info(const DeviceConfig& dc, double node_rate_hz);

/// [main] Creates and opens the device's audio source and its ring, and fills `info` from the source.
/// Throws std::runtime_error "device 'A': audio source 'x': <reason>" (also for a rate other than
/// the node's).
void open_audio(Device& dev, const AudioConfig& ac, const Registry& registry, const HostServices& host,
                double node_rate_hz, StreamInfo& info);

/// [main] Creates and opens the device's playback sink, its scheduler and emitter. Throws
/// std::runtime_error "device 'A': playback sink 'x': <reason>".
void open_playback(Device& dev, const PlaybackConfig& pc, const Registry& registry, const HostServices& host,
                   double node_rate_hz);

/// [main] Creates and opens the device's imu, ble and sync sources (in that order) with their queues.
/// Returns the summed queue capacity. Throws std::runtime_error "device 'A': imu source 'x': <reason>".
std::size_t open_sensors(Device& dev, const DeviceConfig& dc, const Registry& registry, const HostServices& host);

/// The kInput* bits of the streams `dev` has (audio, imu, ble; sync feeds no detector).
std::uint32_t available_inputs(const Device& dev);

/// The detectors of a device, by the stream that feeds them (one detector may be in several lists).
struct DetectorRoutes {
  std::vector<Detector*> audio, imu, ble;
};

/// [main] Creates and configures the device's detectors (they get the device's emitter) and routes
/// each to the streams it consumes. Throws std::runtime_error naming the device and detector, also
/// for a detector that consumes none of the device's streams.
DetectorRoutes create_detectors(Device& dev, const DeviceConfig& dc, const Registry& registry,
                                const HostServices& host, const StreamInfo& info);

/// [main] The device's event queue on `bus` (4096 + twice the sensor queues' capacity) and its
/// runners: the audio block runner and every sensor stream with the detectors that consume it.
void wire_device(Device& dev, const DeviceConfig& dc, EventBus& bus, std::size_t sensor_capacity,
                 double sample_rate_hz, DetectorRoutes routes);

/// [main] One device, built by the steps above. A device without streams gets no runners (and may
/// have no detectors). Throws std::runtime_error naming the device and the component.
std::unique_ptr<Device> build_device(const DeviceConfig& dc, const Registry& registry, const HostServices& host,
                                     const std::map<std::string, GeometrySpec>& geometry, double node_rate_hz,
                                     EventBus& bus);

/// The device the localizers serve: `localizer_device` when given, else the only real device of the
/// node, else "" (node-wide).
std::string served_device(const Config& config, const std::string& localizer_device);

/// [main] Creates and configures one localizer serving `served` (with that device's geometry and
/// emitter, when known), logging as `log_name`. Throws std::runtime_error "localizer 'x': <reason>".
std::unique_ptr<LocalizerInstance> open_localizer(const ComponentConfig& cc, const Registry& registry,
                                                  const HostServices& host, const std::string& log_name,
                                                  const std::string& served, const DeviceGeometry* geometry,
                                                  Emitter* emitter);

/// [main] Creates one `outputs:` entry, logging through a new logger appended to `logs`. Throws
/// std::runtime_error "output: unknown type 'x'" or "output 'x': <reason>".
std::unique_ptr<EventOutput> open_output(const EventOutputConfig& oc, const Registry& registry,
                                         std::vector<std::unique_ptr<SpdLogger>>& logs);

}  // namespace locus::pipeline_steps
