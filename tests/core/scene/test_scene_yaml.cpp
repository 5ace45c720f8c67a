// scene.yaml: load(write(x)) == x with every field, the public spec's example, absent optional fields,
// unknown keys, unknown signal types, and the cross-file WAV header checks.
#include <gtest/gtest.h>

#include "locus/scene/streams.hpp"
#include "scene_test_util.hpp"

using namespace locus;
using namespace locus::scene;
using namespace locus::scene::test;

namespace {

void expect_same_signal(const dsp::SignalSpec& a, const dsp::SignalSpec& b) {
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.amplitude, b.amplitude);
  EXPECT_EQ(a.f0_hz, b.f0_hz);
  EXPECT_EQ(a.f1_hz, b.f1_hz);
  EXPECT_EQ(a.duration_s, b.duration_s);
  EXPECT_EQ(a.fade_s, b.fade_s);
  EXPECT_EQ(a.tones_hz, b.tones_hz);
  EXPECT_EQ(a.degree, b.degree);
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.carrier_hz, b.carrier_hz);
  EXPECT_EQ(a.chip_samples, b.chip_samples);
  EXPECT_EQ(a.chips, b.chips);
  EXPECT_EQ(a.address, b.address);
  EXPECT_EQ(a.tx_power_dbm, b.tx_power_dbm);
  EXPECT_EQ(a.interval_s, b.interval_s);
  EXPECT_EQ(a.sync_delay_s, b.sync_delay_s);
}

void expect_same(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.format, b.format);
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz);
  EXPECT_EQ(a.speed_of_sound_mps, b.speed_of_sound_mps);
  EXPECT_EQ(a.temperature_c, b.temperature_c);
  EXPECT_EQ(a.environment_yaml, b.environment_yaml);
  ASSERT_EQ(a.devices.size(), b.devices.size());
  for (std::size_t i = 0; i < a.devices.size(); ++i) {
    const auto &x = a.devices[i], &y = b.devices[i];
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.mics_m, y.mics_m);
    EXPECT_EQ(x.speaker_m, y.speaker_m);
    EXPECT_EQ(x.audio, y.audio);
    EXPECT_EQ(x.imu, y.imu);
    EXPECT_EQ(x.ble, y.ble);
    EXPECT_EQ(x.sync, y.sync);
    EXPECT_EQ(x.anchor_position_m, y.anchor_position_m);
    ASSERT_EQ(x.emits.size(), y.emits.size());
    for (std::size_t k = 0; k < x.emits.size(); ++k) expect_same_signal(x.emits[k], y.emits[k]);
  }
  ASSERT_EQ(a.emitters.size(), b.emitters.size());
  for (std::size_t i = 0; i < a.emitters.size(); ++i) {
    const auto &x = a.emitters[i], &y = b.emitters[i];
    EXPECT_EQ(x.id, y.id);
    EXPECT_EQ(x.anchor_position_m, y.anchor_position_m);
    ASSERT_EQ(x.emits.size(), y.emits.size());
    for (std::size_t k = 0; k < x.emits.size(); ++k) expect_same_signal(x.emits[k], y.emits[k]);
  }
  ASSERT_EQ(a.truth.has_value(), b.truth.has_value());
  if (a.truth) {
    EXPECT_EQ(a.truth->trajectories, b.truth->trajectories);
    EXPECT_EQ(a.truth->magnetic_field_world_ut, b.truth->magnetic_field_world_ut);
    ASSERT_EQ(a.truth->clocks.size(), b.truth->clocks.size());
    for (const auto& [id, c] : a.truth->clocks) {
      ASSERT_TRUE(b.truth->clocks.count(id)) << id;
      EXPECT_EQ(c.offset_s, b.truth->clocks.at(id).offset_s);
      EXPECT_EQ(c.skew_ppm, b.truth->clocks.at(id).skew_ppm);
    }
  }
}

Scene full_scene(const std::string& dir) {
  Scene s;
  s.dir = dir;
  s.name = "meeting: room \"4\"";
  s.sample_rate_hz = 44100;
  s.speed_of_sound_mps = 331.3 + 0.606 * 21.5;
  s.temperature_c = 21.5;
  s.environment_yaml = "room: [5.3, 6, 3.5]\nwalls: {absorption: 0.3}";
  DeviceSpec a;
  a.id = "A";
  a.mics_m = {{0.0, -0.07, 0.0}, {0.0, 0.07, 0.1 + 0.2}};
  a.speaker_m = Vec3{0.02, -0.07, 1e-9};
  dsp::SignalSpec lfm;
  lfm.type = "lfm";
  lfm.f0_hz = 2000;
  lfm.f1_hz = 8000.5;
  lfm.duration_s = 0.04;
  lfm.fade_s = 0.005;
  lfm.amplitude = 0.7;
  lfm.sync_delay_s = 0.0123;
  dsp::SignalSpec gold;
  gold.type = "gold";
  gold.degree = 7;
  gold.index = 3;
  gold.carrier_hz = 19000;
  gold.chip_samples = 4;
  gold.amplitude = 0.5;
  a.emits = {lfm, gold};
  a.audio = "A/audio.wav";
  a.imu = "A/imu.csv";
  a.ble = "A/ble.csv";
  a.sync = "A/sync.csv";
  a.anchor_position_m = Vec3{1.0, 2.0, 1.2};
  DeviceSpec b;
  b.id = "phone_2-x";
  b.imu = "phone_2-x/imu.csv";
  s.devices = {a, b};
  EmitterSpec e1;
  e1.id = "B1";
  dsp::SignalSpec mt;
  mt.type = "multitone";
  mt.tones_hz = {18000, 18250, 18500};
  mt.duration_s = 0.05;
  mt.fade_s = 0.0;
  mt.amplitude = 1.0;
  dsp::SignalSpec gc;
  gc.type = "gold";
  gc.degree = 4;
  gc.index = 0;
  gc.chips = "100010011010111";
  gc.carrier_hz = 0;
  gc.chip_samples = 1;
  e1.emits = {mt, gc};
  e1.anchor_position_m = Vec3{0.0, 0.0, 2.5};
  EmitterSpec e2;
  e2.id = "tag7";
  dsp::SignalSpec ble;
  ble.type = "ble";
  ble.address = "C4:2C:03:3A:2C:A1";
  ble.tx_power_dbm = -59;
  ble.interval_s = 0.1;
  e2.emits = {ble};
  s.emitters = {e1, e2};
  Truth t;
  t.clocks["A"] = ClockTruth{0.137, 21.0};
  t.clocks["phone_2-x"] = ClockTruth{-3.25, -7.5};
  t.trajectories = "truth.csv";
  t.magnetic_field_world_ut = Vec3{12.1, 14.6, -44.0};
  s.truth = t;
  return s;
}

void touch_files(const Scene& s) {
  for (const auto& d : s.devices)
    for (const std::string* f : {&d.audio, &d.imu, &d.ble, &d.sync})
      if (!f->empty()) write_file(s.path(*f), "");
  if (s.truth && !s.truth->trajectories.empty()) write_file(s.path(s.truth->trajectories), "");
}

}  // namespace

TEST(SceneYaml, WriteThenLoadReproducesEveryField) {
  TempDir tmp;
  const Scene s = full_scene(tmp / "scene1");
  touch_files(s);
  write_scene_yaml(s);
  const Scene l = load_scene(s.dir);
  EXPECT_EQ(l.dir, s.dir);
  expect_same(s, l);
  // line numbers and emits positions are recorded for diagnostics
  EXPECT_GT(l.devices[0].line, 1);
  ASSERT_EQ(l.devices[0].emits_at.size(), 2u);
  EXPECT_GT(l.devices[0].emits_at[1].first, l.devices[0].emits_at[0].first);
  // writing what was loaded gives the same file (fixed point)
  const std::string first = read_file(s.path("scene.yaml"));
  Scene l2 = l;
  write_scene_yaml(l2);
  EXPECT_EQ(read_file(s.path("scene.yaml")), first);
  EXPECT_EQ(l.find_device("phone_2-x"), &l.devices[1]);
  EXPECT_EQ(l.find_emitter("tag7"), &l.emitters[1]);
  EXPECT_EQ(l.find_device("tag7"), nullptr);
}

TEST(SceneYaml, PublicSpecExampleLoads) {
  TempDir tmp;
  const std::string dir = tmp / "spec";
  write_file(dir + "/scene.yaml", R"(format: locus-scene/1
name: meeting-room-4           # free text
sample_rate: 44100             # Hz, the audio rate of every audio.wav in the scene
speed_of_sound: 343.2          # m/s; or give temperature_c and derive c = 331.3 + 0.606*T
environment: {room: [5.3, 6.0, 3.5]}   # free-form, informational

devices:
  - id: A                      # [A-Za-z0-9_-]+, unique
    mics:                      # metres, device body frame, one row per audio channel, in channel order
      - [0.0, -0.07, 0.0]
      - [0.0,  0.07, 0.0]
    speaker: [0.02, -0.07, 0.0]          # optional: absent = cannot emit
    emits:                               # optional: the signal(s) this device plays, see "Signals"
      - {type: lfm, f0: 2000, f1: 8000, duration: 0.040, fade: 0.005}
    audio: A/audio.wav                   # optional
    imu: A/imu.csv                       # optional
    ble: A/ble.csv                       # optional
    sync: A/sync.csv                     # optional
    anchor: {position: [1.0, 2.0, 1.2]}  # optional: position KNOWN to the system (infrastructure)

emitters:                      # optional: things that transmit but record nothing
  - id: B1
    emits: [{type: multitone, tones_hz: [18000, 18250, 18500], duration: 0.050}]
    anchor: {position: [0.0, 0.0, 2.5]}    # known position (SpyLoc beacons); omit when unknown
  - id: tag7
    emits: [{type: ble, address: "C4:2C:03:3A:2C:A1", tx_power_dbm: -59, interval_s: 0.1}]

truth:                         # optional, evaluation only; no plugin may read it
  clocks:                      # local_time = true_time * (1 + skew_ppm*1e-6) + offset_s
    A: {offset_s: 0.137, skew_ppm: 21.0}
  trajectories: truth.csv
  magnetic_field_world: [12.1, 14.6, -44.0]   # µT, the undisturbed Earth field in world axes (optional)
)");
  for (const char* f : {"A/audio.wav", "A/imu.csv", "A/ble.csv", "A/sync.csv", "truth.csv"}) write_file(dir + "/" + f, "");
  const Scene s = load_scene(dir);
  EXPECT_EQ(s.name, "meeting-room-4");
  EXPECT_EQ(s.sample_rate_hz, 44100.0);
  EXPECT_EQ(s.speed_of_sound_mps, 343.2);
  EXPECT_FALSE(s.temperature_c);
  EXPECT_EQ(s.environment_yaml, "{room: [5.3, 6.0, 3.5]}");
  ASSERT_EQ(s.devices.size(), 1u);
  const auto& a = s.devices[0];
  EXPECT_EQ(a.line, 8);
  EXPECT_EQ(a.mics_m.size(), 2u);
  EXPECT_EQ(a.mics_m[1], (Vec3{0.0, 0.07, 0.0}));
  ASSERT_EQ(a.emits.size(), 1u);
  EXPECT_EQ(a.emits[0].type, "lfm");
  EXPECT_EQ(a.emits[0].f1_hz, 8000.0);
  EXPECT_EQ(a.emits[0].duration_s, 0.04);
  EXPECT_EQ(a.emits[0].fade_s, 0.005);
  EXPECT_EQ(a.emits[0].amplitude, 1.0);
  EXPECT_FALSE(a.emits[0].sync_delay_s);
  EXPECT_EQ(a.emits_at[0], (std::pair<int, int>{14, 9}));
  EXPECT_EQ(s.path(a.audio), dir + "/A/audio.wav");
  ASSERT_EQ(s.emitters.size(), 2u);
  EXPECT_EQ(s.emitters[0].emits[0].tones_hz, (std::vector<double>{18000, 18250, 18500}));
  EXPECT_EQ(s.emitters[1].emits[0].address, "C4:2C:03:3A:2C:A1");
  EXPECT_EQ(s.emitters[1].emits[0].tx_power_dbm, -59.0);
  EXPECT_FALSE(s.emitters[1].anchor_position_m);
  ASSERT_TRUE(s.truth);
  EXPECT_EQ(s.truth->clocks.at("A").skew_ppm, 21.0);
  EXPECT_NEAR(s.truth->clocks.at("A").true_from_local(s.truth->clocks.at("A").local_from_true(12.5)), 12.5, 1e-12);
  EXPECT_EQ(*s.truth->magnetic_field_world_ut, (Vec3{12.1, 14.6, -44.0}));
  require_known_signal_types(s);  // all known: no throw
}

TEST(SceneYaml, AbsentOptionalFieldsAndUnknownKeys) {
  TempDir tmp;
  write_file(tmp / "scene.yaml", R"(format: locus-scene/1
sample_rate: 16000
temperature_c: 20
vendor_extension: {anything: [1, 2]}
devices:
  - id: tab-1
    colour: blue
    imu: imu.csv
  - id: mic_2
    mics: [[0, 0, 0]]
    emits:
      - {type: gold, degree: 5, index: 2, carrier: 0, chip_samples: 1, future_field: 3}
)");
  write_file(tmp / "imu.csv", "");
  const Scene s = load_scene(tmp.str());
  EXPECT_EQ(s.name, "");
  EXPECT_DOUBLE_EQ(s.speed_of_sound_mps, 331.3 + 0.606 * 20);
  EXPECT_EQ(*s.temperature_c, 20.0);
  EXPECT_EQ(s.environment_yaml, "");
  EXPECT_TRUE(s.emitters.empty());
  EXPECT_FALSE(s.truth);
  EXPECT_TRUE(s.devices[0].mics_m.empty());
  EXPECT_FALSE(s.devices[0].speaker_m);
  EXPECT_EQ(s.devices[0].audio, "");
  EXPECT_EQ(s.devices[1].emits[0].index, 2);
  EXPECT_EQ(s.devices[1].emits[0].amplitude, 1.0);
  EXPECT_EQ(s.devices[1].emits[0].chips, "");
}

TEST(SceneYaml, UnknownSignalTypeIsKeptAndReportedOnRequest) {
  TempDir tmp;
  write_file(tmp / "scene.yaml", R"(format: locus-scene/1
sample_rate: 48000
speed_of_sound: 343
devices:
  - id: A
    emits:
      - {type: lfm, f0: 1000, f1: 2000, duration: 0.01}
      - {type: zadoff_chu, root: 25}
emitters:
  - id: E
    emits: [{type: ofdm}]
)");
  const Scene s = load_scene(tmp.str());
  ASSERT_EQ(s.devices[0].emits.size(), 2u);
  EXPECT_EQ(s.devices[0].emits[1].type, "zadoff_chu");
  EXPECT_FALSE(s.devices[0].emits[1].acoustic());
  const std::string f = tmp / "scene.yaml";
  EXPECT_EQ(scene_error([&] { require_known_signal_types(s); }),
            f + ":8:9: device 'A': emits[1]: unknown signal type 'zadoff_chu' (known: lfm, gold, multitone, ble)\n" +
                f + ":11:13: emitter 'E': emits[0]: unknown signal type 'ofdm' (known: lfm, gold, multitone, ble)");
  EXPECT_EQ(scene_error([&] { require_known_signal_types(s, {"E"}); }),
            f + ":11:13: emitter 'E': emits[0]: unknown signal type 'ofdm' (known: lfm, gold, multitone, ble)");
  EXPECT_TRUE(is_known_signal_type("multitone"));
  EXPECT_FALSE(is_known_signal_type("ofdm"));
}

TEST(SceneYaml, ValidateStreamsChecksChannelsAndRateAndWarnsOnTruncation) {
  TempDir tmp;
  Scene s;
  s.dir = tmp.str();
  s.sample_rate_hz = 48000;
  DeviceSpec a;
  a.id = "A";
  a.mics_m = {{0, 0, 0}, {0.1, 0, 0}};
  a.audio = "A/audio.wav";
  DeviceSpec b;
  b.id = "B";
  b.mics_m = {{0, 0, 0}};
  b.audio = "B/audio.wav";
  s.devices = {a, b};
  std::filesystem::create_directories(s.path("A"));
  std::filesystem::create_directories(s.path("B"));
  const float z[4] = {};
  {
    WavWriter w(s.path(a.audio), 2, 48000, WavSampleFormat::Int16);
    w.write(z, 2);
  }
  {
    WavWriter w(s.path(b.audio), 1, 48000);
    w.write(z, 4);
  }
  EXPECT_TRUE(validate_scene_streams(s).empty());

  {
    WavWriter w(s.path(a.audio), 3, 44100, WavSampleFormat::Int16);
    w.write(z, 1);
  }
  RawWav t;
  t.rate = 48000;
  t.data = std::string(6, '\0');
  t.declared_data = 100;
  write_file(s.path(b.audio), build_wav(t));
  const std::string pa = s.path(a.audio), pb = s.path(b.audio);
  EXPECT_EQ(scene_error([&] { validate_scene_streams(s); }),
            pa + ": byte 22: 3 channels, expected 2 (one per mic of device 'A' in scene.yaml)\n" + pa +
                ": byte 24: sample rate 44100 Hz, expected 48000 Hz (scene.yaml sample_rate)");
  s.devices.erase(s.devices.begin());
  const auto warnings = validate_scene_streams(s);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], pb + ": byte 40: truncated data chunk: header declares 100 bytes; 3 whole frames present");
}
