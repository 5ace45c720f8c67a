// `locus room`: a hardware-in-the-loop room (docs/room.md). A JACK client that is the acoustic channel
// between live nodes (RoomRenderer), a fake IIO IMU per device fed from the layout's trajectories, and
// the ground truth of what it rendered, written as a scene directory (scene.yaml + truth.csv) that
// `locus eval` scores exactly like a replayed scene.
//
// Ports (client `client_name`, default "room"): per layout device `<id>_spk` (input: the device's node
// plays into it) and `<id>_mic_<k>` (outputs, k = 1..mics: the node captures them). A node is a
// board config with `audio: {source: jack, params: {connect: "^room:<id>_mic_[0-9]+$"}}`,
// `playback: {sink: jack, params: {connect: "^room:<id>_spk$"}}` and
// `imu: {source: iio, params: {root: <out>/iio/<id>}}`.
//
// Time: room time = room frame / fs from the room's first JACK cycle (its CLOCK_MONOTONIC time is
// written to scene.yaml as environment.room_origin_monotonic_s); the layout's time 0 starts
// `lead_in_s` after every device's ports are connected (or after start_timeout_s). The truth clock
// of a device relates its node's audio frames to room time: its node's audio frame 0 on
// CLOCK_MONOTONIC (which locusd logs at exit: "device X: audio frame 0 at CLOCK_MONOTONIC T s") is read
// from `node_origins` when the room stops.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "locus/room/layout.hpp"
#include "locus/room/renderer.hpp"

namespace locus::room {

struct RoomOptions {
  std::string layout_dir;
  std::string out_dir;                 ///< the run's scene (truth) and the IIO trees (out/iio/<id>)
  std::string server;                  ///< JACK server ("" = $JACK_DEFAULT_SERVER or default)
  std::string client_name = "room";
  double lead_in_s = 2.0;              ///< layout time 0 this long after every device connected
  double start_timeout_s = 120.0;      ///< start anyway (warning) after this long
  RendererConfig renderer;
  std::string skew = "none";           ///< none | scene (the layout's truth clocks) | DEV=PPM[,DEV=PPM...]
  double imu_rate_hz = 100.0;
  double imu_error_scale = 1.0;        ///< × the simulator's phone IMU errors (sim::motion::PhoneImu)
  bool imu = true;                     ///< fake IIO IMU per device
  /// The IMUs also carry a magnetometer (IIO magn channels) reading the layout's
  /// truth.magnetic_field_world in each device's body frame, with the simulator's phone magnetometer
  /// errors (noise, hard iron): what an attitude detector needs for an absolute heading (TUM).
  bool magnetometer = false;
  std::string node_origins;            ///< CSV device,audio_origin_monotonic_s read at stop ("" = none)
  std::optional<double> stop_after_s;  ///< stop this long after the layout ended (else at SIGINT/SIGTERM)
};

/// Parses --skew for `layout` (one value per device). Throws std::invalid_argument naming what is wrong.
std::vector<double> parse_skew(const std::string& spec, const Layout& layout);

/// Runs the room until SIGINT/SIGTERM (or stop_after_s). Returns the exit status (app.hpp: 0 ok,
/// 1 runtime failure such as no JACK server, 2 bad layout or options).
int run_room(const RoomOptions& opts);

}  // namespace locus::room
