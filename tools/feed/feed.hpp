// `locus feed SCENE DEVICE`: a scene device's recorded sensors played, in real time on the scene's
// clock, into the real interfaces a live node reads (docs/room.md, "LocBLE"):
//   - imu.csv -> a fake IIO device (hal/iio/fake_iio_tree.hpp: the sysfs tree and a FIFO for the
//     buffered character device) at --iio-root, one packed accel+gyro scan per row, stamped with the
//     CLOCK_MONOTONIC instant of the row (as the kernel stamps a scan at its interrupt), written once
//     that instant has passed; the full scale of each sensor is the LSM6DSL's smallest range that
//     holds the recording (printed);
//   - ble.csv -> BlueZ's D-Bus API as python3-dbusmock's `bluez5` template serves it (the private system
//     bus of $DBUS_SYSTEM_BUS_ADDRESS): an adapter; a tag's first advertisement makes its
//     org.bluez.Device1 object appear with that RSSI (and TxPower) in one InterfacesAdded, as
//     bluetoothd announces a discovered device; each later one is one `RSSI` property change at the
//     row's instant — what bluetoothd does per advertisement once a discovery filter is set
//     (docs/hal-bluez.md). (dbusmock's own AddDevice would announce an arbitrary RSSI of -79.)
//
// Protocol on stdout (tools/hil/hil.py reads it): `feed: ready ...` once the tree and the adapter exist;
// the clock starts when the node has opened the IIO buffer and the adapter is discovering, then
// `feed: scene time 0 at CLOCK_MONOTONIC <s> s (speed <x>)`; at the end one `feed: done ...` line
// with the counts, the lateness of the writes and the instant of the last advertisement. It then
// keeps the FIFO open (the node's IMU does not end) until SIGINT/SIGTERM, unless --exit-when-done.
#pragma once

#include <string>

namespace locus::feed {

struct FeedOptions {
  std::string scene_dir;
  std::string device;          ///< scene device whose imu.csv / ble.csv are played
  std::string iio_root;        ///< fake IIO tree (created; must not exist); "" = no IMU
  std::string adapter = "hci0";
  bool ble = true;             ///< play ble.csv through dbusmock's BlueZ
  double speed = 1.0;          ///< scene seconds per wall second
  double lead_in_s = 0.5;      ///< from "the node is ready" to scene time 0 (plus the first row's time)
  double start_timeout_s = 60.0;
  bool exit_when_done = false;
};

/// Runs the feed; returns the exit status (0, 1 failure, 2 bad input, 130 interrupted before the end).
int run_feed(const FeedOptions& opts);

}  // namespace locus::feed
