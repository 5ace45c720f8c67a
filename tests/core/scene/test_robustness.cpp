// Robustness: randomly corrupted bytes (flips, truncation, insertion) of valid files are fed to every
// reader; the only acceptable outcomes are success or a SceneError with a non-empty message, never a
// crash, hang, other exception type or runaway allocation. Run under ASan/UBSan as well.
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "locus/scene/streams.hpp"
#include "scene_test_util.hpp"

using namespace locus;
using namespace locus::scene;
using namespace locus::scene::test;

namespace {

std::string corrupt(const std::string& in, std::mt19937& rng) {
  std::string s = in;
  std::uniform_int_distribution<int> mode(0, 3);
  auto pos = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n ? n - 1 : 0)(rng); };
  switch (mode(rng)) {
    case 0: {  // flip a few bytes, biased towards the head where the structure is
      const int k = 1 + static_cast<int>(rng() % 6);
      for (int i = 0; i < k && !s.empty(); ++i) {
        const std::size_t p = (rng() % 2) ? pos(std::min<std::size_t>(s.size(), 64)) : pos(s.size());
        s[p] = static_cast<char>(rng() & 0xFF);
      }
      break;
    }
    case 1:  // truncate
      s.resize(pos(s.size() + 1));
      break;
    case 2: {  // insert random bytes
      const std::size_t p = pos(s.size() + 1);
      std::string ins(1 + rng() % 8, '\0');
      for (char& c : ins) c = static_cast<char>("0123456789,.-\"\n\r:[]{} abcE\x00\xff"[rng() % 29]);
      s.insert(p, ins);
      break;
    }
    default: {  // duplicate a slice
      const std::size_t a = pos(s.size()), b = pos(s.size());
      if (a < b) s.insert(pos(s.size() + 1), s.substr(a, b - a));
      break;
    }
  }
  return s;
}

void fuzz(const std::string& name, const std::string& valid, const std::string& path,
          const std::function<void()>& consume, int iterations, std::uint32_t seed) {
  std::mt19937 rng(seed);
  int ok = 0, rejected = 0;
  ASSERT_NO_THROW({
    write_file(path, valid);
    consume();
  }) << name << ": the valid file must be accepted";
  for (int i = 0; i < iterations; ++i) {
    const std::string bad = corrupt(valid, rng);
    write_file(path, bad);
    try {
      consume();
      ++ok;
    } catch (const SceneError& e) {
      ++rejected;
      ASSERT_FALSE(std::string(e.what()).empty());
      ASSERT_FALSE(e.issues().empty());
      ASSERT_NE(std::string(e.what()).find(path), std::string::npos) << "error must name the file: " << e.what();
    } catch (const std::exception& e) {
      FAIL() << name << " iteration " << i << ": unexpected exception type: " << e.what();
    }
  }
  EXPECT_GT(rejected, 0) << name;  // the corruption did reach the validation
  ::testing::Test::RecordProperty(name + "_accepted", ok);
}

}  // namespace

TEST(SceneRobustness, CorruptedFilesGiveSceneErrorOrSuccess) {
  TempDir tmp;
  const int kIter = 400;
  // WAV in every format, plus an extensible one
  std::uint32_t seed = 100;
  for (auto fmt : {WavSampleFormat::Int16, WavSampleFormat::Int24, WavSampleFormat::Int32, WavSampleFormat::Float32}) {
    const std::string src = tmp / (std::string("src_") + to_string(fmt) + ".wav");
    {
      WavWriter w(src, 2, 48000, fmt);
      std::vector<float> x(2 * 300);
      for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(std::sin(0.01 * i));
      w.write(x.data(), 300);
    }
    const std::string p = tmp / "fuzz.wav";
    fuzz(std::string("wav_") + to_string(fmt), read_file(src), p,
         [&] {
           WavReader r(p);
           std::vector<float> buf(64 * static_cast<std::size_t>(r.info().channels));
           std::uint64_t total = 0;
           while (std::size_t n = r.read(buf.data(), 64)) total += n;
           if (total != r.info().frames) throw std::logic_error("frame count mismatch");
         },
         kIter, seed++);
  }
  RawWav ext;
  ext.tag = 0xFFFE;
  ext.sub_tag = 3;
  ext.bits = 32;
  ext.channels = 3;
  ext.data = std::string(3 * 4 * 50, '\x11');
  fuzz("wav_extensible", build_wav(ext), tmp / "fuzz_ext.wav",
       [&] {
         WavReader r(tmp / "fuzz_ext.wav");
         std::vector<float> buf(16 * static_cast<std::size_t>(r.info().channels));
         while (r.read(buf.data(), 16)) {
         }
       },
       kIter, seed++);

  // CSV streams
  std::string imu = "t,ax,ay,az,gx,gy,gz,mx,my,mz\n";
  std::string ble = "t,address,rssi,tx_power,channel\n";
  std::string sync = "t,source\n";
  std::string truth = "t,id,x,y,z,qw,qx,qy,qz\n";
  for (int i = 0; i < 40; ++i) {
    const std::string t = format_double(0.01 * i);
    imu += t + ",0.1,-0.2,9.81,0.01,0.02,-0.03,12.5,-3,44\n";
    ble += t + ",C4:2C:03:3A:2C:A1,-61.5,-59,37\n";
    sync += t + ",\"B1\"\n";
    truth += t + ",A,1,2,3,1,0,0,0\n";
  }
  fuzz("imu", imu, tmp / "imu.csv", [&] { ImuCsvReader r(tmp / "imu.csv", "A"); ImuSample s; while (r.next(s)) {} }, kIter, seed++);
  fuzz("ble", ble, tmp / "ble.csv", [&] { BleCsvReader r(tmp / "ble.csv", "A"); BleAdvertisement a; while (r.next(a)) {} }, kIter, seed++);
  fuzz("sync", sync, tmp / "sync.csv", [&] { SyncCsvReader r(tmp / "sync.csv", "A"); RadioSync s; while (r.next(s)) {} }, kIter, seed++);
  fuzz("truth", truth, tmp / "truth.csv", [&] { TruthTrajectories::load(tmp / "truth.csv").pose_at("A", 0.1); }, kIter, seed++);

  // scene.yaml (its referenced files exist)
  const std::string dir = tmp / "scene";
  write_file(dir + "/A/audio.wav", "");
  write_file(dir + "/truth.csv", "");
  const std::string yaml = R"(format: locus-scene/1
name: fuzz
sample_rate: 48000
temperature_c: 21
environment: {room: [5, 6, 3]}
devices:
  - id: A
    mics: [[0, 0, 0], [0.1, 0, 0]]
    speaker: [0, 0, 0]
    emits:
      - {type: lfm, f0: 2000, f1: 8000, duration: 0.04, fade: 0.005, sync_delay_s: 0.1}
      - {type: gold, degree: 7, index: 3, carrier: 19000, chip_samples: 4}
    audio: A/audio.wav
    anchor: {position: [1, 2, 3]}
emitters:
  - id: B1
    emits: [{type: multitone, tones_hz: [18000, 18500], duration: 0.05}]
  - id: tag7
    emits: [{type: ble, address: "C4:2C:03:3A:2C:A1", tx_power_dbm: -59, interval_s: 0.1}]
truth:
  clocks:
    A: {offset_s: 0.1, skew_ppm: 20}
  trajectories: truth.csv
  magnetic_field_world: [12, 14, -44]
)";
  fuzz("scene_yaml", yaml, dir + "/scene.yaml",
       [&] {
         const Scene s = load_scene(dir);
         require_known_signal_types(s);
       },
       kIter, seed++);
}
