// `locus room`: parse the command line into RoomOptions and run the room.
#include "cli.hpp"
#include <CLI/CLI.hpp>

#include <cmath>
#include <iostream>
#include <memory>
#include <sstream>

#include "app.hpp"
#include "locus/room/room.hpp"

namespace locus::app {

Subcommand add_room_command(CLI::App& cli) {
  auto opts = std::make_shared<room::RoomOptions>();
  auto room_size = std::make_shared<std::string>();
  auto noise_snr_db = std::make_shared<double>(40.0);
  auto stop_after = std::make_shared<double>(-1.0);
  auto* cmd = cli.add_subcommand(
      "room", "a hardware-in-the-loop room: a JACK client rendering every device's speaker into every device's "
              "microphones (delay, 1/r, reflections, noise, clock skew), a fake IIO IMU per device, and the truth "
              "(docs/room.md)");
  cmd->add_option("layout", opts->layout_dir, "scene directory whose devices and truth.csv trajectories are the layout")->required();
  cmd->add_option("out", opts->out_dir, "the run's directory: its truth as a scene (scene.yaml, truth.csv) and the IIO trees (iio/<id>)")
      ->required();
  cmd->add_option("--server", opts->server, "JACK server name (default: $JACK_DEFAULT_SERVER, else default)");
  cmd->add_option("--client-name", opts->client_name, "JACK client name; ports <name>:<id>_spk and <name>:<id>_mic_<k>");
  cmd->add_option("--lead-in", opts->lead_in_s, "seconds from the last device connecting to the layout's time 0")
      ->check(CLI::Range(0.0, 3600.0));
  cmd->add_option("--start-timeout", opts->start_timeout_s, "start the layout anyway after this many seconds (warning)")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_option("--level-at-1m", opts->renderer.level_at_1m, "amplitude at 1 m of a full-scale speaker signal")
      ->check(CLI::Range(1e-6, 10.0));
  cmd->add_option("--self-gain", opts->renderer.self_gain,
                  "extra gain of a device's own speaker into its own microphones (coupling through the case)")
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_option("--noise-snr-db", *noise_snr_db,
                  "white noise per microphone: SNR of a full-scale sine at 1 m (the simulator's definition); 200 = none")
      ->check(CLI::Range(-20.0, 200.0));
  cmd->add_option("--reflections", opts->renderer.reflection_order, "image-source order: 0 (direct only) or 1 (six walls)")
      ->check(CLI::Range(0, 1));
  cmd->add_option("--reflection-coefficient", opts->renderer.reflection, "pressure reflection coefficient of the walls")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--room", *room_size, "room size X,Y,Z in metres (the box from the origin), else the layout's environment.room");
  cmd->add_option("--skew", opts->skew, "clock skew of the devices' microphones: none, scene (the layout's truth clocks) or DEV=PPM,...");
  cmd->add_option("--max-duration", opts->renderer.max_duration_s, "longest run in seconds (the headroom of a slow clock)")
      ->check(CLI::Range(1.0, 86400.0));
  cmd->add_option("--imu-rate-hz", opts->imu_rate_hz, "IMU scans per second per device")->check(CLI::Range(1.0, 2000.0));
  cmd->add_option("--imu-error-scale", opts->imu_error_scale, "x the simulator's phone IMU errors (0 = ideal)")->check(CLI::Range(0.0, 10.0));
  cmd->add_flag("!--no-imu", opts->imu, "no fake IIO IMUs");
  cmd->add_flag("--magnetometer", opts->magnetometer,
                "the IMUs also have a magnetometer reading the layout's truth.magnetic_field_world (needs it)");
  cmd->add_option("--seed", opts->renderer.seed, "noise and IMU errors");
  cmd->add_option("--node-origins", opts->node_origins,
                  "CSV device,seconds read when the room stops: each node's audio frame 0 on CLOCK_MONOTONIC (locusd logs it), "
                  "for the truth clocks");
  cmd->add_option("--stop-after", *stop_after, "stop this many seconds after the layout ended (default: at SIGINT/SIGTERM)")
      ->check(CLI::Range(0.0, 86400.0));
  return Subcommand{cmd, [opts, room_size, noise_snr_db, stop_after]() -> int {
    room::RoomOptions o = *opts;
    if (!room_size->empty()) {
      std::stringstream ss(*room_size);
      Eigen::Vector3d v;
      char c1 = 0, c2 = 0;
      if (!(ss >> v.x() >> c1 >> v.y() >> c2 >> v.z()) || c1 != ',' || c2 != ',' || !ss.eof() || (v.array() <= 0.0).any()) {
        std::cerr << "locus room: --room: expected X,Y,Z (three positive sizes in metres), got '" << *room_size << "'\n";
        return kExitBadConfig;
      }
      o.renderer.room_size_m = v;
    }
    // The simulator's definition: SNR of a sine of amplitude level_at_1m (RMS level/sqrt 2) against the noise RMS.
    o.renderer.noise_rms = *noise_snr_db >= 200.0 ? 0.0 : o.renderer.level_at_1m / std::sqrt(2.0) * std::pow(10.0, -*noise_snr_db / 20.0);
    if (*stop_after >= 0.0) o.stop_after_s = *stop_after;
    return room::run_room(o);
  }};
}

}  // namespace locus::app
