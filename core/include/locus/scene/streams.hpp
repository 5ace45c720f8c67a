// Streaming readers and writers for the stream files of a scene (docs/scene-format.md):
// <device>/audio.wav, imu.csv, ble.csv, sync.csv and truth.csv.
//
// Every reader streams: it holds one block (or one CSV row) in memory, never the whole file, so hours
// of recording replay with bounded memory. Readers are strict about what the format requires and
// tolerant of what it allows; every problem is thrown as a SceneError (scene.hpp) whose issue names
// the file and the line:column (CSV) or byte offset (WAV) and what was expected.
//
// Threading: each object is single-threaded; distinct objects are independent. None of this is
// real-time safe (file I/O); the replay backend reads ahead on a non-RT thread.
//
// One header per format: wav.hpp (audio.wav), csv.hpp (the CSV reader/writer and number formatting),
// imu_csv.hpp, ble_csv.hpp (with BLE address text), sync_csv.hpp, truth.hpp (truth.csv and the
// trajectories) and pose.hpp (pose interpolation). This header includes them all.
#pragma once

#include "locus/scene/ble_csv.hpp"
#include "locus/scene/csv.hpp"
#include "locus/scene/imu_csv.hpp"
#include "locus/scene/pose.hpp"
#include "locus/scene/sync_csv.hpp"
#include "locus/scene/truth.hpp"
#include "locus/scene/wav.hpp"
