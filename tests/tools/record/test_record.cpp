// `locus record` (tools/record): the Recorder writes what its sources produced into a scene directory
// that load_scene + validate_scene_streams accept, sample for sample:
//   - the synth source (float32 bit-exact, int16 quantised exactly as WavWriter documents);
//   - the scene replay sources (audio keeps the scene's int16 encoding; imu/ble/sync rows equal);
//   - a live source that loses frames: zeros in the WAV at the lost frames, the frame index equal to
//     the stream frame counter, the gaps listed in <device>/gaps.csv (also a loss at the very end);
//   - --duration cuts every audio stream at exactly round(duration · rate) frames;
//   - a source error mid-stream: reported, and what came before is written;
//   - the OUT directory rules (no silent overwrite, never remove a non-scene directory);
//   - run_record (the CLI entry) exit statuses.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include "locus/config.hpp"
#include "locus/registry.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"
#include "record/record.hpp"
#include "synth/synth_source.hpp"

namespace fs = std::filesystem;
using namespace locus;
using locus::app::Recorder;
using locus::app::RecorderSettings;

namespace {

class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    dir_ = fs::temp_directory_path() /
           ("locus_record_test_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& rel = "") const { return rel.empty() ? dir_.string() : (dir_ / rel).string(); }

 private:
  fs::path dir_;
};

/// Value of (frame, channel) of the scripted source: distinct, never zero, exact in float.
float scripted_value(std::uint64_t frame, std::uint32_t ch) {
  return static_cast<float>(static_cast<double>((frame % 50000) + 1) / 65536.0) * (ch == 0 ? 1.0f : -1.0f);
}

/// A live audio source that plays a known ramp and declares frames lost where told (as a sound card
/// xrun or a ring overrun does): `losses` = [frame0, count0, frame1, count1, ...]. With `fail_at_frame`
/// > 0 it stops there with an error (a device that went away).
class ScriptedSource final : public AudioSource {
 public:
  ~ScriptedSource() override { stop(); }
  void open(const Params& p, HostContext&) override {
    total_ = static_cast<std::uint64_t>(p.get_int("total_frames"));
    channels_ = static_cast<std::uint32_t>(p.get_int("channels"));
    fail_at_ = static_cast<std::uint64_t>(p.get_int("fail_at_frame"));
    origin_s_ = p.get_float("frame_zero_monotonic_s");
    const auto& l = p.get_floats("losses");
    if (l.size() % 2 != 0) throw std::runtime_error("losses: expected frame,count pairs");
    for (std::size_t i = 0; i < l.size(); i += 2) losses_.push_back({std::uint64_t(l[i]), std::uint64_t(l[i + 1])});
  }
  std::uint32_t channels() const override { return channels_; }
  double sample_rate_hz() const override { return 44100.0; }
  bool live() const override { return true; }
  void start(AudioRing& ring) override {
    thread_ = std::thread([this, &ring] { run(ring); });
  }
  void stop() override {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override {
    std::lock_guard lock(mutex_);
    return error_;
  }
  double frame_zero_monotonic_s() const noexcept override {
    return origin_s_ < 0 || !started_.load() ? kNaN : origin_s_;
  }

 private:
  void run(AudioRing& ring) {
    started_.store(true);
    std::vector<float> block;
    std::uint64_t f = 0;
    std::size_t next_loss = 0;
    while (f < total_ && !stop_.load()) {
      if (fail_at_ != 0 && f >= fail_at_) {
        std::lock_guard lock(mutex_);
        error_ = "device unplugged at frame " + std::to_string(f);
        break;
      }
      if (next_loss < losses_.size() && losses_[next_loss].first == f) {
        ring.write_lost(losses_[next_loss].second);
        f += losses_[next_loss].second;
        ++next_loss;
        continue;
      }
      std::uint64_t n = std::min<std::uint64_t>(300, total_ - f);
      if (next_loss < losses_.size()) n = std::min(n, losses_[next_loss].first - f);
      if (fail_at_ != 0) n = std::min(n, fail_at_ - f);
      block.resize(n * channels_);
      for (std::uint64_t i = 0; i < n; ++i)
        for (std::uint32_t c = 0; c < channels_; ++c) block[i * channels_ + c] = scripted_value(f + i, c);
      // Hardware pacing is not needed for the test; wait for room instead of overrunning by accident.
      while (ring.capacity_frames() - ring.readable_frames() < n && !stop_.load())
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      ring.write(block.data(), n);
      f += n;
    }
    // A loss at the very end of the stream is still pending when the stream ends.
    if (next_loss < losses_.size() && losses_[next_loss].first == f) {
      ring.write_lost(losses_[next_loss].second);
    }
    finished_.store(true, std::memory_order_release);
  }

  std::uint64_t total_ = 0, fail_at_ = 0;
  double origin_s_ = -1.0;
  std::atomic<bool> started_{false};
  std::uint32_t channels_ = 1;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> losses_;
  std::thread thread_;
  std::atomic<bool> stop_{false}, finished_{false};
  mutable std::mutex mutex_;
  std::string error_;
};

void add_scripted(Registry& r) {
  r.add_source(SourceDescriptor{
      "scripted",
      "test: a live ramp with declared losses",
      {int_param("total_frames", std::int64_t{10000}, 1, 1e9, "", "frames"),
       int_param("channels", std::int64_t{1}, 1, 8, "", "channels"),
       int_param("fail_at_frame", std::int64_t{0}, 0, 1e9, "", "0 = never"),
       float_param("frame_zero_monotonic_s", -1.0, -1.0, 1e9, "s", "< 0 = unknown"),
       float_list_param("losses", std::vector<double>{}, 0, 1e9, "", "frame,count pairs")},
      [] { return std::unique_ptr<AudioSource>(std::make_unique<ScriptedSource>()); }});
}

/// A live IMU stamping CLOCK_MONOTONIC-like times: `count` samples at t0_s + i * 0.01.
class MonotonicImu final : public SensorSource {
 public:
  ~MonotonicImu() override { stop(); }
  void open(const Params& p, HostContext&) override {
    t0_ = p.get_float("t0_s");
    count_ = static_cast<int>(p.get_int("count"));
  }
  SensorKind kind() const override { return SensorKind::Imu; }
  bool live() const override { return true; }
  bool monotonic_time() const override { return true; }
  void start(SensorQueue& q) override {
    thread_ = std::thread([this, &q] {
      for (int i = 0; i < count_ && !stop_.load(); ++i) {
        ImuSample s;
        s.t_s = t0_ + i * 0.01;
        s.accel_mps2 = {0.0f, 9.81f, float(i)};
        while (!q.try_push(Event{s}) && !stop_.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      finished_.store(true, std::memory_order_release);
    });
  }
  void stop() override {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }

 private:
  double t0_ = 0.0;
  int count_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false}, finished_{false};
};

void add_monotonic_imu(Registry& r) {
  r.add_sensor_source(SensorSourceDescriptor{
      "mono_imu", "test: IMU on CLOCK_MONOTONIC", SensorKind::Imu,
      {float_param("t0_s", 1000.0, 0.0, 1e9, "s", "first time"), int_param("count", std::int64_t{20}, 1, 1e6, "", "n")},
      [] { return std::unique_ptr<SensorSource>(std::make_unique<MonotonicImu>()); }});
}

Config config_from(const std::string& yaml, Registry& r) { return load_config_string(yaml, "test.yaml", r); }

/// Runs a recorder until it completes (or `timeout_s`), then stops it.
void record(Recorder& rec, double timeout_s = 60.0) {
  rec.start();
  const auto t0 = std::chrono::steady_clock::now();
  while (!rec.complete() && rec.error().empty()) {
    ASSERT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), timeout_s)
        << "the recording did not complete";
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  rec.stop(rec.completion_reason());
}

std::vector<float> read_all(const std::string& path, scene::WavInfo* info = nullptr) {
  scene::WavReader r(path);
  if (info) *info = r.info();
  std::vector<float> out(r.info().frames * r.info().channels);
  std::size_t got = 0;
  while (got < r.info().frames) {
    const std::size_t n = r.read(out.data() + got * r.info().channels, r.info().frames - got);
    if (n == 0) break;
    got += n;
  }
  EXPECT_EQ(got, r.info().frames);
  return out;
}

std::vector<std::pair<std::uint64_t, std::uint64_t>> read_gaps(const std::string& path) {
  scene::CsvReader csv(path);
  const auto f = csv.require_column("frame");
  const auto n = csv.require_column("frames");
  std::vector<std::pair<std::uint64_t, std::uint64_t>> out;
  while (csv.next_row()) out.push_back({std::uint64_t(csv.integer(f, 0, 1LL << 62)), std::uint64_t(csv.integer(n, 1, 1LL << 62))});
  return out;
}

}  // namespace

TEST(Record, SynthFloat32IsBitExactAndTheSceneLoads) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  const Config cfg = config_from(R"(
devices:
  - id: A
    audio:
      source: synth
      params: {channels: 2, duration_s: 1.5, period_s: 0.5, channel_delays_s: [0, 0.0003], noise_dbfs: -50, seed: 7}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("out");
  Recorder rec(cfg, reg, s);
  record(rec);
  EXPECT_EQ(rec.error(), "");
  EXPECT_EQ(rec.completion_reason(), "end of streams");

  const scene::Scene sc = scene::load_scene(s.out_dir);
  EXPECT_NO_THROW(scene::validate_scene_streams(sc));
  EXPECT_EQ(sc.name, "out");
  EXPECT_EQ(sc.sample_rate_hz, 44100.0);
  ASSERT_EQ(sc.devices.size(), 1u);
  const scene::DeviceSpec& d = sc.devices[0];
  EXPECT_EQ(d.id, "A");
  ASSERT_EQ(d.mics_m.size(), 2u);  // one per channel, at the body origin (the config has no geometry)
  EXPECT_EQ(d.audio, "A/audio.wav");
  EXPECT_TRUE(d.imu.empty());

  scene::WavInfo info;
  const std::vector<float> got = read_all(sc.path(d.audio), &info);
  EXPECT_EQ(info.sample_format, scene::WavSampleFormat::Float32);  // synth delivers float
  hal::synth::SynthConfig sc_cfg = hal::synth::SynthConfig::from_params(cfg.devices[0].audio->params);
  hal::synth::SynthGenerator gen(sc_cfg);
  ASSERT_EQ(info.frames, sc_cfg.total_frames());
  std::vector<float> want(info.frames * 2);
  gen.render(0, info.frames, want.data());
  EXPECT_EQ(got, want);  // bit-exact
  EXPECT_TRUE(read_gaps(s.out_dir + "/A/gaps.csv").empty());
  EXPECT_TRUE(fs::exists(s.out_dir + "/recording.yaml"));

  const auto devs = rec.devices();
  ASSERT_EQ(devs.size(), 1u);
  EXPECT_EQ(devs[0].frames, info.frames);
  EXPECT_EQ(devs[0].lost_frames, 0u);
  EXPECT_EQ(devs[0].audio_source, "synth");
}

TEST(Record, GeometryFromTheConfigGoesToSceneYaml) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  const Config cfg = config_from(R"(
devices:
  - id: G
    audio: {source: synth, params: {channels: 2, duration_s: 0.1}}
    geometry: {mics_m: [0, -0.07, 0, 0, 0.07, 0.01], speaker_m: [0.02, -0.07, 0], anchor_m: [1, 2, 1.2]}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("geo");
  {
    Recorder rec(cfg, reg, s);
    record(rec);
  }
  const scene::Scene sc = scene::load_scene(s.out_dir);
  ASSERT_EQ(sc.devices.size(), 1u);
  const scene::DeviceSpec& d = sc.devices[0];
  ASSERT_EQ(d.mics_m.size(), 2u);
  EXPECT_EQ(d.mics_m[0], (scene::Vec3{0, -0.07, 0}));
  EXPECT_EQ(d.mics_m[1], (scene::Vec3{0, 0.07, 0.01}));
  ASSERT_TRUE(d.speaker_m);
  EXPECT_EQ(*d.speaker_m, (scene::Vec3{0.02, -0.07, 0}));
  ASSERT_TRUE(d.anchor_position_m);
  EXPECT_EQ(*d.anchor_position_m, (scene::Vec3{1, 2, 1.2}));

  // Three mics for two channels: refused, naming the device and both counts.
  const Config bad = config_from(R"(
devices:
  - id: G
    audio: {source: synth, params: {channels: 2, duration_s: 0.1}}
    geometry: {mics_m: [0, 0, 0, 1, 0, 0, 2, 0, 0]}
)", reg);
  s.out_dir = tmp.path("geo2");
  try {
    Recorder rec(bad, reg, s);
    FAIL() << "expected a refusal";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("device 'G': geometry.mics_m places 3 microphones"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("delivers 2 channels"), std::string::npos) << e.what();
  }
}

TEST(Record, MonotonicSensorTimesGoOnTheAudioTimeline) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  add_scripted(reg);
  add_monotonic_imu(reg);
  for (const bool origin_known : {true, false}) {
    const Config cfg = config_from(std::string(R"(
devices:
  - id: M
    audio: {source: scripted, params: {channels: 1, total_frames: 44100, frame_zero_monotonic_s: )") +
                                       (origin_known ? "999.75" : "-1") + R"(}}
    imu: {source: mono_imu, params: {t0_s: 1000.0, count: 20}}
)", reg);
    RecorderSettings s;
    s.out_dir = tmp.path(origin_known ? "aligned" : "unaligned");
    Recorder rec(cfg, reg, s);
    record(rec);
    EXPECT_EQ(rec.error(), "");
    const scene::Scene sc = scene::load_scene(s.out_dir);
    scene::ImuCsvReader r(sc.path(sc.devices[0].imu), DeviceId("M"));
    ImuSample x;
    int n = 0;
    while (r.next(x)) {
      const double want = origin_known ? 0.25 + n * 0.01 : 1000.0 + n * 0.01;
      EXPECT_NEAR(x.t_s, want, 1e-9) << "row " << n;
      ++n;
    }
    EXPECT_EQ(n, 20);
    EXPECT_EQ(rec.devices()[0].time_base[0], origin_known ? "audio" : "monotonic");
  }
}

TEST(Record, Int16IsQuantisedExactlyAsTheWavWriterDocuments) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  const Config cfg = config_from(R"(
devices:
  - id: mic
    audio: {source: synth, params: {channels: 1, duration_s: 0.5, first_emission_s: 0.1, amplitude: 0.9}}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("int16");
  s.sample_format = scene::WavSampleFormat::Int16;
  s.name = "quantised";
  Recorder rec(cfg, reg, s);
  record(rec);
  EXPECT_EQ(rec.error(), "");
  const scene::Scene sc = scene::load_scene(s.out_dir);
  EXPECT_EQ(sc.name, "quantised");
  scene::WavInfo info;
  const std::vector<float> got = read_all(sc.path("mic/audio.wav"), &info);
  EXPECT_EQ(info.sample_format, scene::WavSampleFormat::Int16);
  hal::synth::SynthGenerator gen(hal::synth::SynthConfig::from_params(cfg.devices[0].audio->params));
  std::vector<float> want(info.frames);
  gen.render(0, info.frames, want.data());
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const double q = std::clamp(std::round(double(want[i]) * 32768.0), -32768.0, 32767.0) / 32768.0;
    ASSERT_EQ(got[i], static_cast<float>(q)) << "frame " << i;
  }
}

TEST(Record, SceneReplaySourcesRoundTrip) {
  TempDir tmp;
  // A source scene: int16 audio (2 ch), imu, ble, sync.
  scene::Scene src;
  src.dir = tmp.path("src");
  src.name = "source";
  scene::DeviceSpec dev;
  dev.id = "P";
  dev.mics_m = {scene::Vec3{0, -0.07, 0}, scene::Vec3{0, 0.07, 0}};
  dev.audio = "P/audio.wav";
  dev.imu = "P/imu.csv";
  dev.ble = "P/ble.csv";
  dev.sync = "P/sync.csv";
  src.devices.push_back(dev);
  fs::create_directories(src.dir + "/P");
  const std::size_t frames = 30000;
  std::vector<float> audio(frames * 2);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> dist(-32768, 32767);
  for (float& v : audio) v = static_cast<float>(dist(rng)) / 32768.0f;
  {
    scene::WavWriter w(src.path(dev.audio), 2, 44100.0, scene::WavSampleFormat::Int16);
    w.write(audio.data(), frames);
    w.close();
    scene::ImuCsvWriter imu(src.path(dev.imu), true);
    for (int i = 0; i < 50; ++i) {
      ImuSample s;
      s.t_s = i * 0.01;
      s.accel_mps2 = {0.1f * i, 9.81f, -0.5f};
      s.gyro_radps = {0.01f, 0.02f * i, 0.0f};
      s.has_mag = (i % 2) == 0;
      s.mag_ut = {20.0f, -5.0f, 40.0f};
      imu.write(s);
    }
    imu.close();
    scene::BleCsvWriter ble(src.path(dev.ble));
    for (int i = 0; i < 7; ++i) {
      BleAdvertisement a;
      a.t_s = 0.05 * i;
      a.address = {0xC4, 0x2C, 0x03, 0x3A, 0x2C, std::uint8_t(i)};
      a.rssi_dbm = -60.0f - i;
      a.has_tx_power = i % 2;
      a.tx_power_dbm = -59.0f;
      a.channel = std::uint8_t(37 + i % 3);
      ble.write(a);
    }
    ble.close();
    scene::SyncCsvWriter sync(src.path(dev.sync));
    for (int i = 0; i < 3; ++i) {
      RadioSync r;
      r.t_s = 0.1 * i + 0.001;
      r.source = NameTag("B1");
      sync.write(r);
    }
    sync.close();
  }
  scene::write_scene_yaml(src);

  Registry reg;
  register_builtins(reg);
  const std::string p = "{scene: '" + src.dir + "', device: P}";
  const Config cfg = config_from("devices:\n  - id: P\n    audio: {source: scene_audio, params: " + p +
                                     "}\n    imu: {source: scene_imu, params: " + p +
                                     "}\n    ble: {source: scene_ble, params: " + p +
                                     "}\n    sync: {source: scene_sync, params: " + p + "}\n",
                                 reg);
  RecorderSettings s;
  s.out_dir = tmp.path("copy");
  Recorder rec(cfg, reg, s);
  record(rec);
  EXPECT_EQ(rec.error(), "");

  const scene::Scene sc = scene::load_scene(s.out_dir);
  EXPECT_NO_THROW(scene::validate_scene_streams(sc));
  ASSERT_EQ(sc.devices.size(), 1u);
  const scene::DeviceSpec& d = sc.devices[0];
  scene::WavInfo info;
  EXPECT_EQ(read_all(sc.path(d.audio), &info), audio);
  EXPECT_EQ(info.sample_format, scene::WavSampleFormat::Int16);  // as the source delivers

  const auto compare_imu = [&](const std::string& a, const std::string& b) {
    scene::ImuCsvReader ra(a, DeviceId("P")), rb(b, DeviceId("P"));
    ImuSample x, y;
    int n = 0;
    while (ra.next(x)) {
      ASSERT_TRUE(rb.next(y));
      EXPECT_EQ(x.t_s, y.t_s);
      EXPECT_EQ(x.accel_mps2, y.accel_mps2);
      EXPECT_EQ(x.gyro_radps, y.gyro_radps);
      EXPECT_EQ(x.has_mag, y.has_mag);
      if (x.has_mag) {
        EXPECT_EQ(x.mag_ut, y.mag_ut);
      }
      ++n;
    }
    EXPECT_FALSE(rb.next(y));
    EXPECT_EQ(n, 50);
  };
  compare_imu(src.path(dev.imu), sc.path(d.imu));
  {
    scene::BleCsvReader ra(src.path(dev.ble), DeviceId("P")), rb(sc.path(d.ble), DeviceId("P"));
    BleAdvertisement x, y;
    int n = 0;
    while (ra.next(x)) {
      ASSERT_TRUE(rb.next(y));
      EXPECT_EQ(x.t_s, y.t_s);
      EXPECT_EQ(x.address, y.address);
      EXPECT_EQ(x.rssi_dbm, y.rssi_dbm);
      EXPECT_EQ(x.has_tx_power, y.has_tx_power);
      EXPECT_EQ(x.channel, y.channel);
      ++n;
    }
    EXPECT_FALSE(rb.next(y));
    EXPECT_EQ(n, 7);
  }
  {
    scene::SyncCsvReader ra(src.path(dev.sync), DeviceId("P")), rb(sc.path(d.sync), DeviceId("P"));
    RadioSync x, y;
    int n = 0;
    while (ra.next(x)) {
      ASSERT_TRUE(rb.next(y));
      EXPECT_EQ(x.t_s, y.t_s);
      EXPECT_EQ(x.source.view(), y.source.view());
      ++n;
    }
    EXPECT_FALSE(rb.next(y));
    EXPECT_EQ(n, 3);
  }
  const auto devs = rec.devices();
  EXPECT_EQ(devs[0].events[0], 50u);
  EXPECT_EQ(devs[0].events[1], 7u);
  EXPECT_EQ(devs[0].events[2], 3u);
}

TEST(Record, LostFramesBecomeZerosAndAreListed) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  add_scripted(reg);
  // 2 channels, 40000 frames; losses at 1000 (+250), 20000 (+4096), 39990 (+10, the end of the stream,
  // reported only after the last frame was written).
  const Config cfg = config_from(R"(
devices:
  - id: L
    audio: {source: scripted, params: {channels: 2, total_frames: 39990, losses: [1000, 250, 20000, 4096, 39990, 10]}}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("lossy");
  Recorder rec(cfg, reg, s);
  record(rec);
  EXPECT_EQ(rec.error(), "");

  const scene::Scene sc = scene::load_scene(s.out_dir);
  EXPECT_NO_THROW(scene::validate_scene_streams(sc));
  scene::WavInfo info;
  const std::vector<float> got = read_all(sc.path("L/audio.wav"), &info);
  ASSERT_EQ(info.frames, 40000u);  // the stream frame counter, losses included
  const auto lost = [](std::uint64_t f) {
    return (f >= 1000 && f < 1250) || (f >= 20000 && f < 24096) || f >= 39990;
  };
  for (std::uint64_t f = 0; f < info.frames; ++f) {
    for (std::uint32_t c = 0; c < 2; ++c) {
      const float want = lost(f) ? 0.0f : scripted_value(f, c);
      ASSERT_EQ(got[f * 2 + c], want) << "frame " << f << " channel " << c;
    }
  }
  const auto gaps = read_gaps(sc.path("L/gaps.csv"));
  const std::vector<std::pair<std::uint64_t, std::uint64_t>> want{{1000, 250}, {20000, 4096}, {39990, 10}};
  EXPECT_EQ(gaps, want);
  const auto devs = rec.devices();
  EXPECT_EQ(devs[0].lost_frames, 250u + 4096u + 10u);
  EXPECT_EQ(devs[0].gaps.size(), 3u);
  EXPECT_EQ(devs[0].frames, 40000u);
}

TEST(Record, DurationCutsAtExactlyTheRequestedFrames) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  add_scripted(reg);
  const Config cfg = config_from(R"(
devices:
  - id: A
    audio: {source: synth, params: {channels: 1, duration_s: 100}}
  - id: B
    audio: {source: scripted, params: {channels: 1, total_frames: 100000000, losses: [5000, 100, 22000, 500]}}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("dur");
  s.duration_s = 0.5;  // 22050 frames: B's second loss straddles the end
  Recorder rec(cfg, reg, s);
  record(rec);
  EXPECT_EQ(rec.error(), "");
  const scene::Scene sc = scene::load_scene(s.out_dir);
  EXPECT_EQ(scene::read_wav_info(sc.path("A/audio.wav")).frames, 22050u);
  const std::vector<float> b = read_all(sc.path("B/audio.wav"));
  ASSERT_EQ(b.size(), 22050u);
  EXPECT_EQ(b[4999], scripted_value(4999, 0));
  EXPECT_EQ(b[5000], 0.0f);
  EXPECT_EQ(b[5100], scripted_value(5100, 0));
  EXPECT_EQ(b[22049], 0.0f);
  const std::vector<std::pair<std::uint64_t, std::uint64_t>> want{{5000, 100}, {22000, 50}};
  EXPECT_EQ(read_gaps(sc.path("B/gaps.csv")), want);
}

TEST(Record, SourceErrorIsReportedAndEverythingBeforeIsWritten) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  add_scripted(reg);
  const Config cfg = config_from(R"(
devices:
  - id: U
    audio: {source: scripted, params: {channels: 1, total_frames: 1000000000, fail_at_frame: 12345}}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("err");
  Recorder rec(cfg, reg, s);
  rec.start();
  const auto t0 = std::chrono::steady_clock::now();
  while (rec.error().empty()) {
    ASSERT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 30.0);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_NE(rec.error().find("device 'U': audio source 'scripted': device unplugged at frame 12345"), std::string::npos)
      << rec.error();
  rec.stop("error");
  const scene::Scene sc = scene::load_scene(s.out_dir);
  const std::vector<float> got = read_all(sc.path("U/audio.wav"));
  ASSERT_EQ(got.size(), 12345u);
  for (std::uint64_t f = 0; f < got.size(); ++f) ASSERT_EQ(got[f], scripted_value(f, 0));
  std::ifstream y(s.out_dir + "/recording.yaml");
  const std::string text((std::istreambuf_iterator<char>(y)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("device unplugged"), std::string::npos);
  EXPECT_NE(text.find("stopped_by: error"), std::string::npos);
}

TEST(Record, SceneYamlExistsWhileRecording) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  const Config cfg = config_from(R"(
devices:
  - id: A
    audio: {source: synth, params: {channels: 1, duration_s: 600, pace: realtime}}
)", reg);
  RecorderSettings s;
  s.out_dir = tmp.path("live");
  Recorder rec(cfg, reg, s);
  rec.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  // A recorder killed now leaves a scene that loads (the WAV header is finalised at the end).
  EXPECT_NO_THROW(scene::load_scene(s.out_dir));
  EXPECT_FALSE(rec.complete());
  rec.stop("SIGINT");
  const scene::Scene sc = scene::load_scene(s.out_dir);
  const auto frames = scene::read_wav_info(sc.path("A/audio.wav")).frames;
  EXPECT_GT(frames, 0u);
  EXPECT_EQ(rec.devices()[0].frames, frames);
  std::cout << "[ info ] 0.3 s realtime synth: " << frames << " frames, " << rec.devices()[0].lost_frames
            << " lost, " << rec.devices()[0].ring_overruns << " overruns\n";
}

TEST(Record, OutDirectoryRules) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  const Config cfg = config_from(R"(
devices:
  - id: A
    audio: {source: synth, params: {channels: 1, duration_s: 0.1}}
)", reg);
  // A non-empty directory that is not a scene: refused, even with overwrite, and left alone.
  fs::create_directories(tmp.path("home"));
  std::ofstream(tmp.path("home/precious.txt")) << "keep me";
  RecorderSettings s;
  s.out_dir = tmp.path("home");
  try {
    Recorder rec(cfg, reg, s);
    FAIL() << "expected a refusal";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not empty"), std::string::npos) << e.what();
  }
  s.overwrite = true;
  try {
    Recorder rec(cfg, reg, s);
    FAIL() << "expected a refusal";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("not a scene"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(fs::exists(tmp.path("home/precious.txt")));

  // A previous recording: refused without overwrite, replaced with it.
  s = RecorderSettings{};
  s.out_dir = tmp.path("scene");
  {
    Recorder rec(cfg, reg, s);
    record(rec);
  }
  std::ofstream(tmp.path("scene/stale.txt")) << "old";
  EXPECT_THROW(Recorder(cfg, reg, s), std::runtime_error);
  s.overwrite = true;
  {
    Recorder rec(cfg, reg, s);
    record(rec);
  }
  EXPECT_FALSE(fs::exists(tmp.path("scene/stale.txt")));
  EXPECT_NO_THROW(scene::load_scene(tmp.path("scene")));

  // A file where the directory should be.
  std::ofstream(tmp.path("file")) << "x";
  s.out_dir = tmp.path("file");
  EXPECT_THROW(Recorder(cfg, reg, s), std::runtime_error);
}

TEST(Record, SetupErrorsNameTheDevice) {
  TempDir tmp;
  Registry reg;
  register_builtins(reg);
  RecorderSettings s;
  s.out_dir = tmp.path("x");
  // The source's rate must be the node's (as locusd requires).
  const Config matching = config_from(R"(
sample_rate_hz: 48000
devices:
  - id: A
    audio: {source: synth, params: {sample_rate_hz: 48000}}
)", reg);
  EXPECT_NO_THROW(Recorder(matching, reg, s));
  const Config wrong = config_from(R"(
devices:
  - id: A
    audio: {source: synth, params: {sample_rate_hz: 48000}}
)", reg);
  s.out_dir = tmp.path("y");
  try {
    Recorder rec(wrong, reg, s);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("device 'A'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sample_rate_hz"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(tmp.path("y")));  // nothing touched the disk
  const Config none = config_from("devices:\n  - id: A\nlocalizers: []\n", reg);
  EXPECT_THROW(Recorder(none, reg, s), std::runtime_error);
}

TEST(Record, NativeSampleFormatFromParams) {
  using app::native_sample_format;
  Params p;
  EXPECT_EQ(native_sample_format("jack", p), scene::WavSampleFormat::Float32);
  p.set("format", std::string("S16_LE"));
  EXPECT_EQ(native_sample_format("alsa", p), scene::WavSampleFormat::Int16);
  p.set("format", std::string("FLOAT_LE"));
  EXPECT_EQ(native_sample_format("alsa", p), scene::WavSampleFormat::Float32);
  p.set("format", std::string("S32_LE"));
  EXPECT_EQ(native_sample_format("alsa", p), scene::WavSampleFormat::Int32);
  Params q;
  q.set("sample_format", std::string("int24"));
  EXPECT_EQ(native_sample_format("x", q), scene::WavSampleFormat::Int24);
}

TEST(Record, RunRecordExitStatuses) {
  TempDir tmp;
  {
    std::ofstream(tmp.path("ok.yaml")) << "log_level: warn\ndevices:\n  - id: A\n    audio: {source: synth, params: {duration_s: 0.2}}\n";
    std::ofstream(tmp.path("bad.yaml")) << "devices:\n  - id: A\n    audio: {source: nope}\n";
  }
  app::RecordOptions o;
  o.config_path = tmp.path("ok.yaml");
  o.out_dir = tmp.path("out");
  EXPECT_EQ(app::run_record(o), 0);
  EXPECT_EQ(scene::read_wav_info(tmp.path("out/A/audio.wav")).frames, 8820u);
  EXPECT_EQ(app::run_record(o), 2);  // OUT exists
  o.overwrite = true;
  o.duration_s = 0.1;
  EXPECT_EQ(app::run_record(o), 0);
  EXPECT_EQ(scene::read_wav_info(tmp.path("out/A/audio.wav")).frames, 4410u);
  o.config_path = tmp.path("bad.yaml");
  o.out_dir = tmp.path("out2");
  EXPECT_EQ(app::run_record(o), 2);
  EXPECT_FALSE(fs::exists(tmp.path("out2")));
}
