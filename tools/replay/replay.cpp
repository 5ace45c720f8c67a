#include "replay/replay.hpp"

#include <pthread.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <ctime>
#include <iostream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>

#include "app.hpp"
#include "locus/config.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/json_events.hpp"
#include "locus/logging.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "locus/scene/scene.hpp"

namespace locus::app {

namespace {

/// Params for a scene source (validated against its schema like a config section).
Params scene_params(const Registry& registry, const std::string& source, bool sensor, const std::string& scene_dir,
                    const std::string& device, const std::string& speed) {
  const ParamSchema& schema =
      sensor ? registry.find_sensor_source(source)->schema : registry.find_source(source)->schema;
  std::vector<ConfigError> errors;
  Params p = validate_params(schema, {{"scene", scene_dir}, {"device", device}, {"speed", speed}}, errors);
  if (!errors.empty()) throw std::runtime_error(source + ": " + errors.front().format());
  return p;
}

/// One node's config: the device entry for `spec` (own, template or empty), with the scene streams.
Config node_config(const Config& base, const Registry& registry, const scene::Scene& sc, const scene::DeviceSpec& spec,
                   const std::string& speed, std::vector<std::string>& notes) {
  Config cfg = base;
  cfg.sample_rate_hz = sc.sample_rate_hz;
  cfg.devices.clear();
  const DeviceConfig* entry = nullptr;
  const DeviceConfig* templ = nullptr;
  for (const DeviceConfig& d : base.devices) {
    if (d.id == spec.id) entry = &d;
    if (d.is_template()) templ = &d;
  }
  DeviceConfig dev = entry != nullptr ? *entry : templ != nullptr ? *templ : DeviceConfig{};
  dev.id = spec.id;
  if (entry == nullptr && templ != nullptr) {
    // Default instance names of template detectors end in "_*": name them after the device.
    for (ComponentConfig& c : dev.detectors) {
      if (c.name.size() >= 2 && c.name.compare(c.name.size() - 2, 2, "_*") == 0) {
        c.name = c.name.substr(0, c.name.size() - 1) + spec.id;
      }
    }
  }
  const std::string scene_dir = sc.dir;
  if (!spec.audio.empty()) {
    AudioConfig a = dev.audio ? *dev.audio : AudioConfig{};
    if (dev.audio && dev.audio->source != "scene_audio") {
      notes.push_back("device " + spec.id + ": the scene's audio replaces audio source '" + dev.audio->source + "'");
    }
    a.source = "scene_audio";
    a.params = scene_params(registry, a.source, false, scene_dir, spec.id, speed);
    dev.audio = a;
  }
  const std::pair<SensorKind, const std::string*> streams[] = {
      {SensorKind::Imu, &spec.imu}, {SensorKind::Ble, &spec.ble}, {SensorKind::Sync, &spec.sync}};
  for (const auto& [kind, path] : streams) {
    if (path->empty()) continue;
    std::optional<SensorConfig>& section = dev.sensor(kind);
    SensorConfig s = section ? *section : SensorConfig{};
    const std::string name = "scene_" + std::string(sensor_kind_name(kind));
    if (section && section->source != name) {
      notes.push_back("device " + spec.id + ": the scene's " + std::string(sensor_kind_name(kind)) +
                      " stream replaces source '" + section->source + "'");
    }
    s.source = name;
    s.params = scene_params(registry, name, true, scene_dir, spec.id, speed);
    section = s;
  }
  // Detectors need one of the node's streams.
  std::uint32_t available = 0;
  if (dev.audio) available |= kInputAudio;
  if (dev.imu) available |= kInputImu;
  if (dev.ble) available |= kInputBle;
  std::vector<ComponentConfig> kept;
  for (ComponentConfig& c : dev.detectors) {
    const locus_plugin_descriptor* d = registry.find_plugin(c.plugin);
    if (d != nullptr && (d->inputs & available) == 0) {
      notes.push_back("device " + spec.id + ": detector '" + c.name + "' left out (the device has no stream it consumes)");
      continue;
    }
    kept.push_back(std::move(c));
  }
  dev.detectors = std::move(kept);
  cfg.devices.push_back(std::move(dev));
  return cfg;
}

bool has_stream(const scene::DeviceSpec& d) {
  return !d.audio.empty() || !d.imu.empty() || !d.ble.empty() || !d.sync.empty();
}

}  // namespace

int run_replay(const ReplayOptions& opts) {
  const sigset_t stop_signals = app::block_stop_signals();

  Registry registry;
  register_builtins(registry);
  Config config;
  try {
    config = load_config(opts.config_path, registry);
  } catch (const ConfigErrors& e) {
    for (const ConfigError& err : e.errors()) std::cerr << err.format() << "\n";
    std::cerr << e.errors().size() << (e.errors().size() == 1 ? " error" : " errors")
              << " in the config; nothing was run\n";
    return kExitBadConfig;
  }
  scene::Scene sc;
  try {
    sc = scene::load_scene(opts.scene_dir);
  } catch (const scene::SceneError& e) {
    for (const scene::SceneIssue& issue : e.issues()) std::cerr << issue.format() << "\n";
    std::cerr << e.issues().size() << (e.issues().size() == 1 ? " error" : " errors")
              << " in the scene; nothing was run\n";
    return kExitBadConfig;
  }
  LogLevel level = config.log_level;
  if (opts.log_level) parse_log_level(*opts.log_level, level);
  set_log_level(level);
  auto log = host_logger();

  // --events, else the config's output.events when it has one, else estimates only.
  std::vector<EventType> events{EventType::Estimate};
  if (!opts.events && config.output.events_given) events = config.output.events;
  if (opts.events) {
    events.clear();
    std::string_view rest(*opts.events);
    while (!rest.empty()) {
      const std::size_t comma = rest.find(',');
      std::string_view name = rest.substr(0, comma);
      while (!name.empty() && name.front() == ' ') name.remove_prefix(1);
      while (!name.empty() && name.back() == ' ') name.remove_suffix(1);
      EventType t{};
      if (!event_type_from_name(name, t)) {
        std::string known;
        for (std::size_t i = 0; i < kEventTypeCount; ++i) {
          known += (i ? ", " : "") + std::string(event_type_name(static_cast<EventType>(i)));
        }
        std::cerr << "--events: unknown event type '" << name << "' (known: " << known << ")\n";
        return kExitBadConfig;
      }
      if (std::find(events.begin(), events.end(), t) == events.end()) events.push_back(t);
      if (comma == std::string_view::npos) break;
      rest.remove_prefix(comma + 1);
    }
  }

  std::set<std::string> scene_ids;
  for (const auto& d : sc.devices) scene_ids.insert(d.id);
  for (const DeviceConfig& d : config.devices) {
    if (!d.is_template() && scene_ids.count(d.id) == 0) {
      log->warn("config device '{}' is not in the scene {}: ignored", d.id, sc.dir);
    }
  }

  // The link outlives the pipelines (their handlers are subscribed on it).
  InProcessLink link;
  std::unique_ptr<JsonLinesWriter> writer;
  std::mutex writer_mutex;
  std::vector<std::string> node_ids;
  std::vector<std::unique_ptr<Pipeline>> nodes;
  try {
    writer = std::make_unique<JsonLinesWriter>(opts.output ? *opts.output : config.output.path);
    const std::vector<SceneSignal> scene_emits = scene::scene_signals(sc);
    for (const scene::DeviceSpec& spec : sc.devices) {
      if (!has_stream(spec)) continue;
      std::vector<std::string> notes;
      Config node = node_config(config, registry, sc, spec, opts.speed, notes);
      for (const std::string& n : notes) log->info("{}", n);
      PipelineOptions po;
      po.link = &link;
      po.write_output = false;
      po.fft_measure = false;  // deterministic transforms: one scene, one output (docs/config.md "Replay")
      po.localizer_device = spec.id;
      GeometrySpec g = geometry_of(spec);
      g.scene_emits = scene_emits;
      po.geometry.emplace(spec.id, std::move(g));
      auto p = std::make_unique<Pipeline>(node, registry, std::move(po));
      for (EventType t : events) {
        JsonLinesWriter* w = writer.get();
        p->subscribe(t, [w, &writer_mutex](const Event& e) {
          std::lock_guard lock(writer_mutex);
          w->write(e);
        });
      }
      if (opts.hooks.built) opts.hooks.built(spec.id, *p);
      nodes.push_back(std::move(p));
      node_ids.push_back(spec.id);
    }
  } catch (const std::exception& e) {
    nodes.clear();
    link.flush();
    log->error("{}", e.what());
    std::cerr << "nothing was run\n";
    return kExitBadConfig;
  }
  if (nodes.empty()) {
    log->error("scene {} has no device with a stream (audio, imu, ble or sync): nothing to replay", sc.dir);
    return kExitBadConfig;
  }

  log->info("replaying {} ({} nodes, speed {})", sc.dir, nodes.size(), opts.speed);
  for (auto& p : nodes) p->start();
  int signal_number = 0;
  for (;;) {
    bool all = true;
    for (const auto& p : nodes) all = all && p->finished();
    if (all) break;
    if (opts.hooks.tick) {
      for (std::size_t i = 0; i < nodes.size(); ++i) opts.hooks.tick(node_ids[i], *nodes[i]);
    }
    timespec timeout{0, 20'000'000};
    const int sig = sigtimedwait(&stop_signals, nullptr, &timeout);
    if (sig > 0) {
      signal_number = sig;
      break;
    }
  }
  if (signal_number) log->warn("{} received: stopping the replay", signal_number == SIGINT ? "SIGINT" : "SIGTERM");

  // Phase (a): sources drained through the detectors, buses delivered; then the link settles.
  const auto settle = [&] {
    for (;;) {
      link.flush();
      std::size_t n = 0;
      for (auto& p : nodes) n += p->deliver_pending();
      if (n == 0) break;
    }
  };
  for (auto& p : nodes) p->stop_inputs();
  settle();
  // Phase (b): every node's localizers hand their peers what they held back (inputs_ended), the link
  // settles; so a node that finishes first still sees the last messages of the nodes after it.
  for (auto& p : nodes) p->end_localizer_inputs();
  settle();
  // Phase (c): localizers finish node by node, the link settling after each.
  for (auto& p : nodes) {
    p->finish_localizers();
    settle();
  }
  int status = signal_number ? kExitFailure : kExitOk;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    nodes[i]->flush();
    for (const DeviceStats& s : nodes[i]->stats()) {
      if (!s.source_error.empty()) {
        log->error("device {}: {}", s.id, s.source_error);
        status = kExitFailure;
      }
    }
  }
  {
    std::lock_guard lock(writer_mutex);
    writer->flush();
  }
  if (opts.hooks.tick) {
    for (std::size_t i = 0; i < nodes.size(); ++i) opts.hooks.tick(node_ids[i], *nodes[i]);
  }
  if (opts.hooks.ended) opts.hooks.ended(signal_number != 0);
  nodes.clear();  // unsubscribes nothing on the link by itself: no message is in flight any more
  return status;
}

GeometrySpec geometry_of(const scene::DeviceSpec& spec) {
  GeometrySpec g;
  if (spec.mics_m.size() > DeviceGeometry::kMaxMics) {
    throw std::runtime_error("device '" + spec.id + "' has " + std::to_string(spec.mics_m.size()) +
                             " mics; at most " + std::to_string(DeviceGeometry::kMaxMics) + " are supported");
  }
  g.geometry.mic_count = static_cast<std::uint32_t>(spec.mics_m.size());
  for (std::size_t i = 0; i < spec.mics_m.size(); ++i) g.geometry.mics_m[i] = spec.mics_m[i];
  if (spec.speaker_m) {
    g.geometry.has_speaker = true;
    g.geometry.speaker_m = *spec.speaker_m;
  }
  if (spec.anchor_position_m) {
    g.geometry.has_anchor = true;
    g.geometry.anchor_m = *spec.anchor_position_m;
  }
  g.emits = spec.emits;
  return g;
}

std::map<std::string, GeometrySpec> layout_geometry(const scene::Scene& sc) {
  std::map<std::string, GeometrySpec> out;
  const std::vector<SceneSignal> scene_emits = scene::scene_signals(sc);
  for (const scene::DeviceSpec& spec : sc.devices) {
    GeometrySpec g = geometry_of(spec);
    g.scene_emits = scene_emits;
    out.emplace(spec.id, std::move(g));
  }
  // An emitter (a beacon) records nothing; as a live node it plays its emits from its body origin.
  for (const scene::EmitterSpec& e : sc.emitters) {
    GeometrySpec g;
    g.geometry.has_speaker = true;
    if (e.anchor_position_m) {
      g.geometry.has_anchor = true;
      g.geometry.anchor_m = *e.anchor_position_m;
    }
    g.emits = e.emits;
    g.scene_emits = scene_emits;
    out.emplace(e.id, std::move(g));
  }
  return out;
}

}  // namespace locus::app
