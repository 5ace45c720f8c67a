// The scene replay sources (hal/scene) through a real Pipeline, on a scene written by the test:
//   - audio frames reach the detectors exactly (every sample compared) and the onset detector finds a
//     chirp at the frame where the test put it;
//   - IMU and BLE events reach a detector interleaved with the audio by local time: an event with time
//     t is delivered after the block that contains t*fs and before the next one (checked event by event);
//   - RadioSync events (and raw IMU/BLE) reach a subscribed localizer, in time order;
//   - a device with sensors and no audio works;
//   - speed realtime takes roughly real time;
//   - a malformed row mid-file ends the stream with file:line:column, after the rows before it.
#include <gtest/gtest.h>

#include <iostream>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <numbers>
#include <sstream>

#include "locus/config.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "locus/scene/streams.hpp"
#include "scene/scene_sources.hpp"

namespace locus {
namespace {

namespace fs = std::filesystem;

constexpr double kRate = 16000.0;
constexpr std::uint64_t kFrames = 40000;        // 2.5 s
constexpr std::uint64_t kChirpFrame = 16000;    // 1.0 s
constexpr std::uint32_t kBlock = 256;

// Channel 0: low noise plus a chirp at kChirpFrame; channel 1: a value that encodes the frame number.
float sample(std::uint64_t frame, std::uint32_t c) {
  if (c == 1) return static_cast<float>(frame % 4096) / 4096.0f;
  std::uint32_t h = static_cast<std::uint32_t>(frame) * 2654435761u;
  h ^= h >> 15;
  const float noise = 1e-3f * (static_cast<float>(h & 0xffff) / 65536.0f - 0.5f);
  if (frame < kChirpFrame || frame >= kChirpFrame + 640) return noise;
  const double t = static_cast<double>(frame - kChirpFrame) / kRate;
  return noise + static_cast<float>(0.5 * std::sin(2.0 * std::numbers::pi * (1000.0 * t + 0.5 * 50000.0 * t * t)));
}

// ------------------------------------------------------------------ probes

struct Item {
  enum Kind { Audio, Imu, Ble } kind;
  std::uint64_t first_frame = 0;
  std::uint32_t frames = 0;
  double t_s = 0.0;
};

std::mutex g_mutex;
std::vector<Item> g_items;
std::uint64_t g_bad_samples = 0;
std::vector<Event> g_localizer_events;

class ProbeDetector final : public Detector {
 public:
  void configure(const StreamInfo&, const Params&, HostContext& ctx) override {
    geometry_ = ctx.geometry;
  }
  void process_audio(const AudioBlock& b, EventSink&) noexcept override {
    std::lock_guard lock(g_mutex);
    for (std::uint32_t i = 0; i < b.frames; ++i)
      for (std::uint32_t c = 0; c < b.channels; ++c)
        if (b.channel_data[c][i] != sample(b.first_frame + i, c)) ++g_bad_samples;
    g_items.push_back({Item::Audio, b.first_frame, b.frames, 0.0});
  }
  void process_imu(const ImuSample* s, std::size_t n, EventSink&) noexcept override {
    std::lock_guard lock(g_mutex);
    for (std::size_t i = 0; i < n; ++i) g_items.push_back({Item::Imu, 0, 0, s[i].t_s});
  }
  void process_ble(const BleAdvertisement* a, std::size_t n, EventSink&) noexcept override {
    std::lock_guard lock(g_mutex);
    for (std::size_t i = 0; i < n; ++i) g_items.push_back({Item::Ble, 0, 0, a[i].t_s});
  }
  const DeviceGeometry* geometry_ = nullptr;
};

class SensorLocalizer final : public Localizer {
 public:
  void configure(const Params&, HostContext&) override {}
  std::vector<EventType> subscriptions() const override {
    return {EventType::RadioSync, EventType::ImuSample, EventType::BleAdvertisement};
  }
  void on_event(const Event& e, Publisher&) override {
    std::lock_guard lock(g_mutex);
    g_localizer_events.push_back(e);
  }
};

const ParamSchema kNoParams{};
const locus_plugin_descriptor kProbe{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "probe", "1", "test probe",
                                     kInputAudio | kInputImu | kInputBle, [] { return &kNoParams; },
                                     [] { return static_cast<Detector*>(new ProbeDetector); }, nullptr};
const locus_plugin_descriptor kSensorLoc{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "sensor_loc", "1",
                                         "test localizer", 0, [] { return &kNoParams; }, nullptr,
                                         [] { return static_cast<Localizer*>(new SensorLocalizer); }};

// ------------------------------------------------------------------ the scene

struct SceneFixture : ::testing::Test {
  fs::path dir;
  std::vector<double> imu_t, ble_t, sync_t;

  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("locus_scene_replay_" + std::to_string(::getpid()) + "_" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir / "A");
    fs::create_directories(dir / "B");
    std::lock_guard lock(g_mutex);
    g_items.clear();
    g_localizer_events.clear();
    g_bad_samples = 0;
  }
  void TearDown() override { fs::remove_all(dir); }

  void write_scene(bool b_has_imu = true) {
    std::ofstream y(dir / "scene.yaml");
    y << "format: locus-scene/1\nname: replay-test\nsample_rate: " << kRate << "\nspeed_of_sound: 343.0\n"
      << "devices:\n"
      << "  - id: A\n    mics: [[0, -0.05, 0], [0, 0.05, 0]]\n    speaker: [0.01, 0, 0]\n"
      << "    emits: [{type: lfm, f0: 1000, f1: 3000, duration: 0.04}]\n"
      << "    audio: A/audio.wav\n    imu: A/imu.csv\n    ble: A/ble.csv\n    sync: A/sync.csv\n"
      << "    anchor: {position: [1.0, 2.0, 0.5]}\n"
      << "  - id: B\n    mics: [[0, 0, 0]]\n" << (b_has_imu ? "    imu: B/imu.csv\n" : "") << "    sync: B/sync.csv\n";
    y.close();
    {
      scene::WavWriter w((dir / "A/audio.wav").string(), 2, kRate, scene::WavSampleFormat::Float32);
      std::vector<float> block(2 * 1000);
      for (std::uint64_t f = 0; f < kFrames; f += 1000) {
        for (std::uint64_t i = 0; i < 1000; ++i)
          for (std::uint32_t c = 0; c < 2; ++c) block[i * 2 + c] = sample(f + i, c);
        w.write(block.data(), 1000);
      }
      w.close();
    }
    // IMU at ~100 Hz with jitter; some samples exactly on block boundaries (t*fs = k*256).
    {
      std::ofstream f(dir / "A/imu.csv");
      f << "t,ax,ay,az,gx,gy,gz\n";
      for (int i = 0; i < 260; ++i) {
        double t = -0.02 + i * 0.01 + 0.0013 * ((i * 7) % 5);
        if (i % 10 == 3) t = (kBlock * (i + 1)) / kRate;  // exactly at a block start
        if (!imu_t.empty() && t < imu_t.back()) t = imu_t.back();
        imu_t.push_back(t);
        f << scene::format_double(t) << ",0,9.81,0,0.1,0,0\n";
      }
    }
    {
      std::ofstream f(dir / "A/ble.csv");
      f << "t,address,rssi\n";
      for (int i = 0; i < 30; ++i) {
        const double t = 0.05 + i * 0.09;  // runs past the end of the audio
        ble_t.push_back(t);
        f << scene::format_double(t) << ",C4:2C:03:3A:2C:A1," << -60 - i % 7 << "\n";
      }
    }
    {
      std::ofstream f(dir / "A/sync.csv");
      f << "t,source\n";
      for (int i = 0; i < 5; ++i) {
        sync_t.push_back(0.3 + 0.5 * i);
        f << scene::format_double(sync_t.back()) << ",B1\n";
      }
    }
    {
      std::ofstream f(dir / "B/imu.csv");
      f << "t,ax,ay,az,gx,gy,gz\n";
      for (int i = 0; i < 50; ++i) f << scene::format_double(i * 0.02) << ",0,0,9.81,0,0,0\n";
    }
    {
      std::ofstream f(dir / "B/sync.csv");
      f << "t,source\n0.5,B1\n1.5,B1\n";
    }
  }

  Registry make_registry() = delete;

  static void register_all(Registry& r) {
    register_builtins(r);
    r.add_plugin(&kProbe, "test");
    r.add_plugin(&kSensorLoc, "test");
  }

  std::string device_yaml(const std::string& id, const std::string& speed, bool audio, bool imu, bool ble, bool sync,
                          const std::string& detectors) const {
    std::ostringstream y;
    const std::string params = "{scene: \"" + dir.string() + "\", device: " + id + ", speed: " + speed + "}";
    y << "  - id: " << id << "\n";
    if (audio) y << "    audio: {source: scene_audio, block_frames: " << kBlock << ", params: " << params << "}\n";
    if (imu) y << "    imu: {source: scene_imu, queue_capacity: 16, params: " << params << "}\n";
    if (ble) y << "    ble: {source: scene_ble, params: " << params << "}\n";
    if (sync) y << "    sync: {source: scene_sync, params: " << params << "}\n";
    y << "    detectors: " << detectors << "\n";
    return y.str();
  }

  /// Runs `devices_yaml` to completion; returns the stats.
  std::vector<DeviceStats> run(const std::string& devices_yaml, double* wall_s = nullptr) {
    Registry registry;
    register_all(registry);
    const std::string yaml = "sample_rate_hz: " + std::to_string(kRate) + "\nlog_level: warn\noutput: {path: \"" +
                             (dir / "out.jsonl").string() + "\", events: []}\ndevices:\n" + devices_yaml +
                             "localizers:\n  - plugin: sensor_loc\n";
    const Config config = load_config_string(yaml, "test.yaml", registry);
    Pipeline p(config, registry);
    const auto t0 = std::chrono::steady_clock::now();
    p.start();
    const auto deadline = t0 + std::chrono::seconds(60);
    while (!p.finished() && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    EXPECT_TRUE(p.finished()) << "the replay did not end within 60 s";
    if (wall_s) *wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    p.stop();
    return p.stats();
  }
};

TEST_F(SceneFixture, AudioReachesDetectorsExactlyAndOnsetFindsTheChirp) {
  write_scene();
  Registry registry;
  register_all(registry);
  const std::string yaml = "sample_rate_hz: 16000\nlog_level: warn\noutput: {path: \"" + (dir / "out.jsonl").string() +
                           "\", events: [audio_detection]}\ndevices:\n" +
                           device_yaml("A", "max", true, false, false, false,
                                       "[{plugin: probe}, {plugin: onset, params: {threshold_db: 20}}]");
  const Config config = load_config_string(yaml, "test.yaml", registry);
  std::vector<AudioDetection> detections;
  {
    Pipeline p(config, registry);
    std::mutex m;
    p.subscribe(EventType::AudioDetection, [&](const Event& e) {
      std::lock_guard lock(m);
      detections.push_back(std::get<AudioDetection>(e));
    });
    p.start();
    for (int i = 0; i < 30000 && !p.finished(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    ASSERT_TRUE(p.finished());
    p.stop();
    const auto stats = p.stats();
    ASSERT_EQ(stats.size(), 1u);
    EXPECT_EQ(stats[0].frames_processed, kFrames);
    EXPECT_EQ(stats[0].frames_lost, 0u);
    EXPECT_EQ(stats[0].source_error, "");
  }
  std::uint64_t next = 0;
  for (const Item& it : g_items) {
    ASSERT_EQ(it.kind, Item::Audio);
    EXPECT_EQ(it.first_frame, next);
    next += it.frames;
  }
  EXPECT_EQ(next, kFrames);
  EXPECT_EQ(g_bad_samples, 0u);
  // The chirp is on channel 0 only (channel 1 is a ramp the onset detector may or may not flag).
  std::vector<double> ch0;
  for (const auto& d : detections)
    if (d.channel == 0) ch0.push_back(d.frame);
  ASSERT_EQ(ch0.size(), 1u);
  EXPECT_NEAR(ch0[0], static_cast<double>(kChirpFrame), 3.0);
}

TEST_F(SceneFixture, SensorEventsInterleaveWithAudioByLocalTime) {
  write_scene();
  const auto stats = run(device_yaml("A", "max", true, true, true, true, "[{plugin: probe}]"));
  ASSERT_EQ(stats.size(), 1u);
  EXPECT_EQ(stats[0].source_error, "");
  EXPECT_EQ(stats[0].frames_processed, kFrames);
  EXPECT_EQ(stats[0].sensor_events, imu_t.size() + ble_t.size() + sync_t.size());
  EXPECT_EQ(stats[0].sensor_dropped, 0u);
  EXPECT_EQ(stats[0].events_dropped, 0u);

  // Walk the delivery order: before the block starting at F come exactly the events with t*fs < F.
  std::size_t imu_i = 0, ble_i = 0;
  std::uint64_t processed = 0;     // start of the next block
  std::uint64_t last_start = 0;    // start of the last block
  bool any_block = false;
  double last_t = -1e9;
  int checked = 0;
  for (const Item& it : g_items) {
    if (it.kind == Item::Audio) {
      ASSERT_EQ(it.first_frame, processed);
      last_start = it.first_frame;
      processed += it.frames;
      any_block = true;
      continue;
    }
    const double t = it.t_s;
    EXPECT_GE(t, last_t) << "sensor streams are merged by time";
    last_t = t;
    if (it.kind == Item::Imu) {
      EXPECT_EQ(t, imu_t[imu_i++]);
    } else {
      EXPECT_EQ(t, ble_t[ble_i++]);
    }
    // Not later than the block that starts after it ...
    if (processed < kFrames) {
      EXPECT_LT(t * kRate, static_cast<double>(processed)) << "t=" << t;
    }
    // ... and not earlier than the block that contains it.
    if (any_block) {
      EXPECT_GE(t * kRate, static_cast<double>(last_start)) << "t=" << t;
    }
    ++checked;
  }
  EXPECT_EQ(imu_i, imu_t.size());
  EXPECT_EQ(ble_i, ble_t.size());
  EXPECT_EQ(checked, static_cast<int>(imu_t.size() + ble_t.size()));
  EXPECT_EQ(g_bad_samples, 0u);

  // The localizer got every raw sensor event, RadioSync included, each stream in time order.
  std::vector<double> syncs, imus, bles;
  for (const Event& e : g_localizer_events) {
    if (const auto* r = std::get_if<RadioSync>(&e)) {
      syncs.push_back(r->t_s);
      EXPECT_EQ(r->source.view(), "B1");
      EXPECT_EQ(r->device.view(), "A");
    }
    if (const auto* s = std::get_if<ImuSample>(&e)) imus.push_back(s->t_s);
    if (const auto* a = std::get_if<BleAdvertisement>(&e)) bles.push_back(a->t_s);
  }
  EXPECT_EQ(syncs, sync_t);
  EXPECT_EQ(imus, imu_t);
  EXPECT_EQ(bles, ble_t);
}

TEST_F(SceneFixture, SensorOnlyDeviceAndGeometry) {
  write_scene();
  // B: imu + sync, no audio; the probe consumes imu, so it runs there.
  const auto stats = run(device_yaml("B", "max", false, true, false, true, "[{plugin: probe}]"));
  ASSERT_EQ(stats.size(), 1u);
  EXPECT_EQ(stats[0].source_error, "");
  EXPECT_EQ(stats[0].sensor_events, 52u);
  std::size_t imu = 0;
  for (const Item& it : g_items) imu += it.kind == Item::Imu;
  EXPECT_EQ(imu, 50u);
  std::size_t syncs = 0;
  for (const Event& e : g_localizer_events) syncs += std::holds_alternative<RadioSync>(e);
  EXPECT_EQ(syncs, 2u);
}

TEST_F(SceneFixture, AudioOnlyDetectorOnADeviceWithoutAudioIsAnError) {
  write_scene();
  Registry registry;
  register_all(registry);
  const Config config = load_config_string(
      "devices:\n" + device_yaml("B", "max", false, true, false, false, "[{plugin: onset}]"), "t.yaml", registry);
  try {
    Pipeline p(config, registry);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("detector 'onset' consumes audio"), std::string::npos) << e.what();
  }
}

TEST_F(SceneFixture, RealtimeSpeedTakesAboutRealTime) {
  write_scene();
  double wall = 0.0;
  const auto stats = run(device_yaml("A", "realtime", true, true, true, true, "[{plugin: probe}]"), &wall);
  ASSERT_EQ(stats.size(), 1u);
  EXPECT_EQ(stats[0].source_error, "");
  // The streams end at their last item's local time: audio 2.5 s, IMU ~4.06 s, BLE 2.66 s.
  const double end_s = std::max({static_cast<double>(kFrames) / kRate, imu_t.back(), ble_t.back(), sync_t.back()});
  std::cout << "realtime replay of streams ending at " << end_s << " s took " << wall << " s\n";
  EXPECT_GE(wall, end_s - 0.05);
  EXPECT_LT(wall, end_s + 2.0);  // lenient: a shared machine
  EXPECT_EQ(stats[0].frames_processed + stats[0].frames_lost, kFrames);
}

TEST_F(SceneFixture, MaxSpeedIsFasterThanRealTime) {
  write_scene();
  double wall = 0.0;
  run(device_yaml("A", "max", true, true, true, true, "[{plugin: probe}]"), &wall);
  std::cout << "max-speed replay of " << static_cast<double>(kFrames) / kRate << " s of audio took " << wall << " s\n";
  EXPECT_LT(wall, 2.0);
}

TEST_F(SceneFixture, MalformedRowEndsTheStreamWithFileLineColumnAndKeepsEarlierRows) {
  write_scene();
  {
    std::ofstream f(dir / "A/imu.csv");
    f << "t,ax,ay,az,gx,gy,gz\n";
    for (int i = 0; i < 40; ++i) f << scene::format_double(0.01 * i) << ",0,9.81,0,0,0,0\n";
    f << "0.40,0,9.81,zero,0,0,0\n";  // line 42, column 13
    for (int i = 41; i < 60; ++i) f << scene::format_double(0.01 * i) << ",0,9.81,0,0,0,0\n";
  }
  const auto stats = run(device_yaml("A", "max", true, true, false, false, "[{plugin: probe}]"));
  ASSERT_EQ(stats.size(), 1u);
  const std::string err = stats[0].source_error;
  EXPECT_NE(err.find("imu.csv:42:13"), std::string::npos) << err;
  EXPECT_EQ(err.rfind("imu source: ", 0), 0u) << err;
  std::size_t imu = 0;
  for (const Item& it : g_items) imu += it.kind == Item::Imu;
  EXPECT_EQ(imu, 40u);
  EXPECT_EQ(stats[0].frames_processed, kFrames);  // the other streams still ran to their end
}

TEST_F(SceneFixture, OpenReportsAMissingDeviceAndStream) {
  write_scene(/*b_has_imu=*/false);
  Registry registry;
  register_all(registry);
  for (const auto& [yaml, needle] : std::vector<std::pair<std::string, std::string>>{
           {device_yaml("C", "max", true, false, false, false, "[]"), "no device 'C' (devices: A, B)"},
           {device_yaml("B", "max", false, true, false, false, "[]"), "device 'B' declares no imu stream"}}) {
    const Config config = load_config_string("devices:\n" + yaml, "t.yaml", registry);
    try {
      Pipeline p(config, registry);
      ADD_FAILURE() << "expected an error for " << needle;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  }
}

TEST(SceneConfig, SensorSectionsAreValidatedLikeAudio) {
  Registry registry;
  register_builtins(registry);
  try {
    load_config_string(
        "devices:\n  - id: A\n    imu: {source: scene_ble, params: {scene: x, device: A}}\n"
        "    ble: {source: scene_blee, params: {scene: x, device: A}}\n"
        "    sync: {source: scene_sync, queue_capacity: 3, params: {scene: x}}\n",
        "c.yaml", registry);
    FAIL() << "expected errors";
  } catch (const ConfigErrors& e) {
    const std::string all = e.what();
    EXPECT_NE(all.find("c.yaml:3:19: devices[0].imu.source: 'scene_ble' is a ble source, not an imu source"),
              std::string::npos) << all;
    EXPECT_NE(all.find("devices[0].ble.source: unknown ble source 'scene_blee'; did you mean 'scene_ble'?"),
              std::string::npos) << all;
    EXPECT_NE(all.find("devices[0].sync.queue_capacity: expected an integer in [16, 16777216], got '3'"),
              std::string::npos) << all;
    EXPECT_NE(all.find("devices[0].sync.params.device: missing required key 'device'"), std::string::npos) << all;
  }
  // The template id is accepted; other non-id characters are not.
  EXPECT_NO_THROW(load_config_string("devices:\n  - id: \"*\"\n    detectors: [{plugin: onset}]\n", "c.yaml", registry));
  EXPECT_THROW(load_config_string("devices:\n  - id: \"a*\"\n", "c.yaml", registry), ConfigErrors);
}

}  // namespace
}  // namespace locus
