// Scene replay through the real pipeline (`locus replay`).
//
// The scene declares the devices; the config says what runs on them. For every scene device that
// records any stream (audio, imu, ble, sync) one node (one Pipeline) is built:
//   - its device entry is the config's `devices:` entry with the same id, else the template entry
//     `id: "*"`, else an empty one (no detectors);
//   - the streams the scene declares for the device are read by the scene sources (scene_audio,
//     scene_imu, scene_ble, scene_sync) at the chosen speed; they replace any source the config names
//     for those streams (the scene wins); streams the scene does not declare keep the config's source
//     (hardware in the loop);
//   - detectors whose inputs the node has no stream for are left out (logged);
//   - every localizer of the config runs on every node, with HostContext::device = the device id;
//   - plugins get the device's geometry from scene.yaml (HostContext::geometry).
// All nodes share one InProcessLink (as boards share an MQTT broker) and one JSON-lines writer.
//
// Shutdown, once every stream ended: (a) every node drains its sources through its detectors and
// delivers its bus; the link is flushed and buses re-delivered until quiet; (b) node by node, in scene
// order, the localizers finish, each followed by the same settling; then the output is flushed.
#pragma once

#include <map>
#include <optional>
#include <string>

#include "app.hpp"
#include "locus/pipeline.hpp"
#include "locus/scene/scene.hpp"

namespace locus::app {

struct ReplayOptions {
  std::string scene_dir;
  std::string config_path;
  std::string speed = "max";                 ///< max | realtime
  std::optional<std::string> output;         ///< JSON lines path ("-" = stdout); default: config output.path
  std::optional<std::string> events;         ///< comma-separated event type names; default: estimate
  std::optional<std::string> log_level;
  PipelineHooks hooks;                       ///< the live map of locusd --scene --http
};

/// Runs the replay. Exit status: 0 success; 2 a bad scene, config or option (nothing ran, every error
/// printed); 1 a stream failed mid-way or the replay was interrupted (after flushing everything that
/// was accepted before).
int run_replay(const ReplayOptions& options);

/// A scene device's declarations as the geometry its plugins get (mics, speaker, anchor, emits).
/// Throws std::runtime_error when it has more microphones than DeviceGeometry holds.
GeometrySpec geometry_of(const scene::DeviceSpec& spec);

/// Every device's and every emitter's declarations in `sc` by id, each with the scene's signals
/// (`scene_emits`): what `locus replay` gives the plugins, for a live node that runs against a layout
/// (`locusd --layout DIR`). An emitter (a beacon: it records nothing) gets a speaker at its body
/// origin, its anchor and its emits.
std::map<std::string, GeometrySpec> layout_geometry(const scene::Scene& sc);

}  // namespace locus::app
