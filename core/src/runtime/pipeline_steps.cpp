// The steps that build a Pipeline (see pipeline_steps.hpp for the order and why).
#include "pipeline_steps.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locus::pipeline_steps {

namespace {

std::uint32_t plugin_inputs(const Registry& registry, const std::string& plugin) {
  const locus_plugin_descriptor* d = registry.find_plugin(plugin);
  return d != nullptr ? d->inputs : 0u;
}

/// "audio imu ble" as the detector-inputs error has always spelled it ("audio", " imu", " ble").
std::string consumed_inputs_text(std::uint32_t inputs) {
  return ((inputs & kInputAudio) ? std::string("audio") : std::string()) +
         ((inputs & kInputImu) ? std::string(" imu") : std::string()) +
         ((inputs & kInputBle) ? std::string(" ble") : std::string());
}

}  // namespace

LinkChoice choose_link(const Config& config, const Registry& registry, Link* shared) {
  LinkChoice choice;
  if (shared != nullptr) {
    choice.link = shared;
  } else if (config.link) {
    const LinkDescriptor* d = registry.find_link(config.link->type);
    if (d == nullptr) throw std::runtime_error("link: unknown type '" + config.link->type + "'");
    choice.log = std::make_unique<SpdLogger>("link/" + config.link->type);
    try {
      choice.owned = d->create(config.link->params, *choice.log);
    } catch (const std::exception& e) {
      throw std::runtime_error("link '" + config.link->type + "': " + e.what());
    }
    choice.link = choice.owned.get();
  } else {
    auto inprocess = std::make_unique<InProcessLink>();
    choice.inprocess = inprocess.get();
    choice.owned = std::move(inprocess);
    choice.link = choice.owned.get();
  }
  return choice;
}

GeometrySpec geometry_from_config(const GeometryConfig& g) {
  GeometrySpec spec;
  spec.geometry.mic_count = static_cast<std::uint32_t>(std::min<std::size_t>(g.mics_m.size(), DeviceGeometry::kMaxMics));
  for (std::uint32_t i = 0; i < spec.geometry.mic_count; ++i) spec.geometry.mics_m[i] = g.mics_m[i];
  spec.geometry.has_speaker = g.speaker_m.has_value();
  if (g.speaker_m) spec.geometry.speaker_m = *g.speaker_m;
  spec.geometry.has_anchor = g.anchor_m.has_value();
  if (g.anchor_m) spec.geometry.anchor_m = *g.anchor_m;
  return spec;
}

void add_config_geometry(const Config& config, std::map<std::string, GeometrySpec>& geometry) {
  for (const DeviceConfig& dc : config.devices) {
    if (dc.is_template() || !dc.geometry || geometry.count(dc.id) > 0) continue;
    geometry.emplace(dc.id, geometry_from_config(*dc.geometry));
  }
  for (auto& [id, spec] : geometry) {
    spec.geometry.emits = spec.emits;
    spec.geometry.scene_emits = spec.scene_emits;
  }
}

const DeviceGeometry* find_geometry(const std::map<std::string, GeometrySpec>& geometry, const std::string& id) {
  const auto it = geometry.find(id);
  return it == geometry.end() ? nullptr : &it->second.geometry;
}

void require_node_rate(const std::string& what, double actual_hz, double node_hz) {
  if (std::abs(actual_hz - node_hz) > 1e-6) {
    throw std::runtime_error(what + " runs at " + std::to_string(actual_hz) + " Hz but the node is configured for " +
                             std::to_string(node_hz) + " Hz (sample_rate_hz)");
  }
}

StreamInfo initial_stream_info(const DeviceConfig& dc, double node_rate_hz) {
  StreamInfo info;
  info.device = DeviceId(dc.id);
  info.channels = 0;
  info.sample_rate_hz = node_rate_hz;
  info.max_block_frames = dc.audio ? dc.audio->block_frames : 256;
  return info;
}

void open_audio(Device& dev, const AudioConfig& ac, const Registry& registry, const HostServices& host,
                double node_rate_hz, StreamInfo& info) {
  const std::string what = "device '" + dev.id + "': audio source '" + ac.source + "'";
  dev.source_log = std::make_unique<SpdLogger>(dev.id + "/" + ac.source);
  HostContext ctx = host.context(*dev.source_log, ac.source, dev.id, dev.geometry);
  try {
    dev.source = registry.create_source(ac.source);
    dev.source->open(ac.params, ctx);
  } catch (const std::exception& e) {
    throw std::runtime_error(what + ": " + e.what());
  }
  require_node_rate(what, dev.source->sample_rate_hz(), node_rate_hz);
  dev.ring = std::make_unique<AudioRing>(dev.source->channels(), ac.ring_frames);
  info.channels = dev.source->channels();
  info.sample_rate_hz = dev.source->sample_rate_hz();
}

void open_playback(Device& dev, const PlaybackConfig& pc, const Registry& registry, const HostServices& host,
                   double node_rate_hz) {
  const std::string what = "device '" + dev.id + "': playback sink '" + pc.sink + "'";
  dev.sink_log = std::make_unique<SpdLogger>(dev.id + "/" + pc.sink + " (playback)");
  HostContext ctx = host.context(*dev.sink_log, pc.sink, dev.id, dev.geometry);
  const SinkDescriptor* d = registry.find_sink(pc.sink);
  try {
    if (d == nullptr) throw std::runtime_error("unknown playback sink");
    dev.sink = d->create();
    if (!dev.sink) throw std::runtime_error("the factory returned no instance");
    dev.sink->open(pc.params, ctx);
  } catch (const std::exception& e) {
    throw std::runtime_error(what + ": " + e.what());
  }
  require_node_rate(what, dev.sink->sample_rate_hz(), node_rate_hz);
  dev.scheduler = std::make_unique<PlaybackScheduler>(dev.sink->sample_rate_hz(), pc.max_pending);
  dev.emitter = std::make_unique<SchedulerEmitter>(*dev.scheduler);
}

std::size_t open_sensors(Device& dev, const DeviceConfig& dc, const Registry& registry, const HostServices& host) {
  std::size_t capacity = 0;
  for (const SensorKind kind : {SensorKind::Imu, SensorKind::Ble, SensorKind::Sync}) {
    const std::optional<SensorConfig>& sc = dc.sensor(kind);
    if (!sc) continue;
    const std::string what = std::string(sensor_kind_name(kind)) + " source '" + sc->source + "'";
    Device::Sensor s{kind, sc->source, std::make_unique<SpdLogger>(dc.id + "/" + sc->source), nullptr, nullptr};
    HostContext ctx = host.context(*s.log, sc->source, dc.id, dev.geometry);
    try {
      s.source = registry.create_sensor_source(sc->source);
      if (s.source->kind() != kind) {
        throw std::runtime_error("produces " + std::string(sensor_kind_name(s.source->kind())) + " events");
      }
      s.source->open(sc->params, ctx);
    } catch (const std::exception& e) {
      throw std::runtime_error("device '" + dc.id + "': " + what + ": " + e.what());
    }
    s.queue = std::make_unique<SensorQueue>(sc->queue_capacity);
    capacity += s.queue->capacity();
    dev.sensors.push_back(std::move(s));
  }
  return capacity;
}

std::uint32_t available_inputs(const Device& dev) {
  std::uint32_t available = 0;
  if (dev.source) available |= kInputAudio;
  for (const auto& s : dev.sensors) {
    if (s.kind == SensorKind::Imu) available |= kInputImu;
    if (s.kind == SensorKind::Ble) available |= kInputBle;
  }
  return available;
}

DetectorRoutes create_detectors(Device& dev, const DeviceConfig& dc, const Registry& registry,
                                const HostServices& host, const StreamInfo& info) {
  DetectorRoutes routes;
  const std::uint32_t available = available_inputs(dev);
  for (const ComponentConfig& cc : dc.detectors) {
    const std::uint32_t inputs = plugin_inputs(registry, cc.plugin);
    if ((inputs & available) == 0) {
      throw std::runtime_error("device '" + dc.id + "': detector '" + cc.name + "' consumes " +
                               consumed_inputs_text(inputs) + " but the device has no such stream");
    }
    auto log = std::make_unique<SpdLogger>(cc.name);
    HostContext ctx = host.context(*log, cc.name, dc.id, dev.geometry, dev.emitter.get());
    try {
      auto det = registry.create_detector(cc.plugin);
      det->configure(info, cc.params, ctx);
      if ((inputs & kInputAudio) && dev.source) routes.audio.push_back(det.get());
      if ((inputs & kInputImu)) routes.imu.push_back(det.get());
      if ((inputs & kInputBle)) routes.ble.push_back(det.get());
      dev.detectors.push_back(std::move(det));
    } catch (const std::exception& e) {
      throw std::runtime_error("device '" + dc.id + "': detector '" + cc.name + "': " + e.what());
    }
    dev.detector_logs.push_back(std::move(log));
  }
  return routes;
}

void wire_device(Device& dev, const DeviceConfig& dc, EventBus& bus, std::size_t sensor_capacity,
                 double sample_rate_hz, DetectorRoutes routes) {
  dev.queue = &bus.make_rt_queue(dc.id, 4096 + 2 * sensor_capacity);
  dev.device_runner = std::make_unique<DeviceRunner>(sample_rate_hz, *dev.queue, dev.queue);
  if (dev.source) {
    dev.runner = std::make_unique<AudioBlockRunner>(*dev.ring, dc.audio->block_frames, std::move(routes.audio),
                                                    *dev.queue);
    dev.device_runner->set_audio(*dev.runner, *dev.ring, *dev.source, dc.audio->block_frames);
  }
  for (auto& s : dev.sensors) {
    dev.device_runner->add_sensor(*s.queue, *s.source,
                                  s.kind == SensorKind::Imu   ? routes.imu
                                  : s.kind == SensorKind::Ble ? routes.ble
                                                              : std::vector<Detector*>{});
  }
}

std::unique_ptr<Device> build_device(const DeviceConfig& dc, const Registry& registry, const HostServices& host,
                                     const std::map<std::string, GeometrySpec>& geometry, double node_rate_hz,
                                     EventBus& bus) {
  auto dev = std::make_unique<Device>();
  dev->id = dc.id;
  dev->geometry = find_geometry(geometry, dc.id);
  StreamInfo info = initial_stream_info(dc, node_rate_hz);
  if (dc.audio) open_audio(*dev, *dc.audio, registry, host, node_rate_hz, info);
  if (dc.playback) open_playback(*dev, *dc.playback, registry, host, node_rate_hz);
  const std::size_t sensor_capacity = open_sensors(*dev, dc, registry, host);
  if (!dev->has_streams()) {
    if (!dc.detectors.empty()) {
      throw std::runtime_error("device '" + dc.id + "' has detectors but no stream (audio, imu, ble or sync)");
    }
    return dev;
  }
  DetectorRoutes routes = create_detectors(*dev, dc, registry, host, info);
  wire_device(*dev, dc, bus, sensor_capacity, info.sample_rate_hz, std::move(routes));
  return dev;
}

std::string served_device(const Config& config, const std::string& localizer_device) {
  if (!localizer_device.empty()) return localizer_device;
  const DeviceConfig* only = nullptr;
  std::size_t real = 0;
  for (const DeviceConfig& dc : config.devices) {
    if (dc.is_template()) continue;
    ++real;
    only = &dc;
  }
  return real == 1 ? only->id : std::string();
}

std::unique_ptr<LocalizerInstance> open_localizer(const ComponentConfig& cc, const Registry& registry,
                                                  const HostServices& host, const std::string& log_name,
                                                  const std::string& served, const DeviceGeometry* geometry,
                                                  Emitter* emitter) {
  auto inst = std::make_unique<LocalizerInstance>();
  inst->name = cc.name;
  inst->log = std::make_unique<SpdLogger>(log_name);
  HostContext ctx = host.context(*inst->log, cc.name, served, geometry, emitter);
  try {
    inst->localizer = registry.create_localizer(cc.plugin);
    inst->localizer->configure(cc.params, ctx);
  } catch (const std::exception& e) {
    throw std::runtime_error("localizer '" + cc.name + "': " + e.what());
  }
  return inst;
}

std::unique_ptr<EventOutput> open_output(const EventOutputConfig& oc, const Registry& registry,
                                         std::vector<std::unique_ptr<SpdLogger>>& logs) {
  const OutputDescriptor* d = registry.find_output(oc.type);
  if (d == nullptr) throw std::runtime_error("output: unknown type '" + oc.type + "'");
  logs.push_back(std::make_unique<SpdLogger>("output/" + oc.type));
  try {
    return d->create(oc.params, *logs.back());
  } catch (const std::exception& e) {
    throw std::runtime_error("output '" + oc.type + "': " + e.what());
  }
}

}  // namespace locus::pipeline_steps
