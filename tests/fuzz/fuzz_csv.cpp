// The scene CSV readers (imu.csv, ble.csv, sync.csv, truth.csv), one target each: the source is built
// once per reader with -DLOCUS_FUZZ_CSV=<0..3>. Every row is read; SceneError is the only exception.
#include <cstdint>

#include "fuzz_support.hpp"
#include "locus/scene/ble_csv.hpp"
#include "locus/scene/imu_csv.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/sync_csv.hpp"
#include "locus/scene/truth.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
#if LOCUS_FUZZ_CSV == 0
    const std::string path = locus::fuzz::write_input("imu.csv", data, size);
    locus::scene::ImuCsvReader r(path, locus::DeviceId("D"));
    locus::ImuSample s{};
    while (r.next(s)) {
    }
#elif LOCUS_FUZZ_CSV == 1
    const std::string path = locus::fuzz::write_input("ble.csv", data, size);
    locus::scene::BleCsvReader r(path, locus::DeviceId("D"));
    locus::BleAdvertisement a{};
    while (r.next(a)) {
    }
#elif LOCUS_FUZZ_CSV == 2
    const std::string path = locus::fuzz::write_input("sync.csv", data, size);
    locus::scene::SyncCsvReader r(path, locus::DeviceId("D"));
    locus::RadioSync s{};
    while (r.next(s)) {
    }
#else
    const std::string path = locus::fuzz::write_input("truth.csv", data, size);
    locus::scene::TruthCsvReader r(path);
    locus::scene::TruthRow row{};
    while (r.next(row)) {
    }
#endif
  } catch (const locus::scene::SceneError&) {
  }
  return 0;
}
