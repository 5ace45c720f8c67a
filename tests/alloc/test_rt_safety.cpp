// Proves that the real-time path never allocates, frees or takes a mutex after warm-up: the audio
// callback path (AudioRing write, including the overrun path), the detector thread's block step
// (AudioBlockRunner::step with every registered detector) and the event hand-over (RtEventQueue).
//
// The hooks count calls made by the current thread while a RtSection is open.
#include <gtest/gtest.h>
#include <dlfcn.h>
#include <pthread.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <cstdlib>
#include <new>
#include <span>
#include <string>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/dsp/emission_canceller.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/event_bus.hpp"
#include "locus/fftw_planner.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"
#include "support/test_host.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus {
namespace {

TEST(RtSafety, HooksSeeAllocationsAndLocks) {
  // The proof is only worth something if the hooks fire: check that they do.
  RtSection rt;
  std::vector<int>* v = new std::vector<int>(100);
  delete v;
  pthread_mutex_t m = PTHREAD_MUTEX_INITIALIZER;
  pthread_mutex_lock(&m);
  pthread_mutex_unlock(&m);
  EXPECT_GE(rt.allocs(), 2);
  EXPECT_GE(rt.frees(), 2);
  EXPECT_EQ(rt.locks(), 1);
}

TEST(RtSafety, AudioCallbackPathDoesNotAllocateOrLock) {
  AudioRing ring(2, 4096, 8);
  std::vector<float> period(2 * 256, 0.25f), out(2 * 4096);
  RtSection rt;
  for (int i = 0; i < 2000; ++i) {
    ring.write(period.data(), 256);  // overruns (ring full) on most iterations: the loss path too
    if (i % 40 == 0) ring.read(out.data(), 4096);
  }
  rt.end();
  EXPECT_GT(ring.overruns(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

TEST(RtSafety, EventHandOverDoesNotAllocateOrLock) {
  RtEventQueue queue("rt", 64);
  AudioDetection d;
  d.device = "A";
  Event out;
  RtSection rt;
  for (int i = 0; i < 1000; ++i) {
    d.frame = i;
    queue.emit(d);  // fills up, then counts drops
    if (i % 3 == 0) queue.pop(out);
  }
  rt.end();
  EXPECT_GT(queue.dropped(), 0u);
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
}

// Every registered audio detector, with its default parameters, through the detector thread's
// block step on a stream of noise with periodic tone bursts (so detectors actually fire).
TEST(RtSafety, EveryDetectorProcessDoesNotAllocateOrLock) {
  Registry registry;
  register_builtins(registry);
  for (const char* dir : {LOCUS_TEST_PLUGIN_DIR "/clip", LOCUS_TEST_PLUGIN_DIR "/good"}) {
    const auto failures = registry.load_directory(dir);
    ASSERT_TRUE(failures.empty()) << failures.front();
  }
  test::TestHost host;
  FftwPlanner fftw({}, /*measure=*/false);
  int checked = 0;
  for (const auto& entry : registry.plugins()) {
    const locus_plugin_descriptor* d = entry.descriptor;
    if (d->kind != LOCUS_PLUGIN_DETECTOR || !(d->inputs & kInputAudio)) continue;
    const Params params = Params::defaults(*d->schema());
    bool has_required = false;
    for (const ParamSpec& p : *d->schema()) has_required |= p.required();
    ASSERT_FALSE(has_required) << d->name << ": give it test parameters here";

    SCOPED_TRACE(d->name);
    constexpr std::uint32_t kChannels = 2, kBlock = 256;
    StreamInfo info;
    info.device = "A";
    info.channels = kChannels;
    info.sample_rate_hz = 44100.0;
    info.max_block_frames = kBlock;
    auto detector = registry.create_detector(d->name);
    // The real FFTW planner (as the host uses): the naive test planner is O(n^2) and would make this
    // test take minutes with 8192-point correlators.
    HostContext ctx{host.log, host.clock, fftw, host.link, d->name, "A"};
    detector->configure(info, params, ctx);

    AudioRing ring(kChannels, 1 << 16);
    RtEventQueue queue("A", 1 << 14);
    AudioBlockRunner runner(ring, kBlock, {detector.get()}, queue);
    std::vector<float> block(kChannels * kBlock);
    std::uint64_t frame = 0;
    std::uint32_t seed = 12345;
    auto fill = [&] {
      for (std::uint32_t i = 0; i < kBlock; ++i, ++frame) {
        seed = seed * 1664525u + 1013904223u;
        const float noise = 1e-3f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
        const bool burst = (frame % 22050) < 2000;
        const float tone = burst ? 0.5f * std::sin(2.0f * 3.14159265f * 3000.0f * static_cast<float>(frame) / 44100.0f) : 0.0f;
        for (std::uint32_t c = 0; c < kChannels; ++c) block[i * kChannels + c] = tone + noise;
      }
    };
    // Warm-up (first blocks may touch lazily initialised state), then the measured section.
    for (int i = 0; i < 50; ++i) {
      fill();
      ring.write(block.data(), kBlock);
      runner.step(false);
    }
    const std::uint64_t delivered_before = queue.dropped();
    (void)delivered_before;
    RtSection rt;
    for (int i = 0; i < 2000; ++i) {
      fill();
      ring.write(block.data(), kBlock);
      runner.step(false);
      if (i == 1000) ring.write_lost(100);  // a gap: detectors reset their state
    }
    const long allocs = rt.allocs(), frees = rt.frees(), locks = rt.locks();
    EXPECT_EQ(allocs, 0) << d->name << " allocated in process_audio";
    EXPECT_EQ(frees, 0) << d->name << " freed in process_audio";
    EXPECT_EQ(locks, 0) << d->name << " locked a mutex in process_audio";
    EXPECT_EQ(runner.frames_lost(), 100u);
    ++checked;
  }
  EXPECT_GE(checked, 3) << "expected onset, clip_detector and fixture_level at least";
}

// The sensor delivery path: DeviceRunner merging audio blocks with IMU / BLE / sync queues by local
// time, handing IMU and BLE events to every registered detector that consumes them and posting the raw
// events to the bus queue.
namespace {
class RtAudioSource final : public AudioSource {
 public:
  void open(const Params&, HostContext&) override {}
  std::uint32_t channels() const override { return 1; }
  double sample_rate_hz() const override { return 44100.0; }
  bool live() const override { return false; }
  void start(AudioRing&) override {}
  void stop() override {}
  bool finished() const noexcept override { return false; }
};
class RtSensorSource final : public SensorSource {
 public:
  RtSensorSource(SensorKind kind, bool live) : kind_(kind), live_(live) {}
  void open(const Params&, HostContext&) override {}
  SensorKind kind() const override { return kind_; }
  bool live() const override { return live_; }
  void start(SensorQueue&) override {}
  void stop() override {}
  bool finished() const noexcept override { return false; }

 private:
  SensorKind kind_;
  bool live_;
};
}  // namespace

TEST(RtSafety, SensorDeliveryDoesNotAllocateOrLock) {
  Registry registry;
  register_builtins(registry);
  test::TestHost host;
  constexpr std::uint32_t kBlock = 256;
  constexpr double kFs = 44100.0;
  StreamInfo info;
  info.device = "A";
  info.channels = 1;
  info.sample_rate_hz = kFs;
  info.max_block_frames = kBlock;
  std::vector<std::unique_ptr<Detector>> detectors;
  std::vector<Detector*> audio_dets, imu_dets, ble_dets;
  std::vector<std::string> names;
  for (const auto& entry : registry.plugins()) {
    const locus_plugin_descriptor* d = entry.descriptor;
    if (d->kind != LOCUS_PLUGIN_DETECTOR || !(d->inputs & (kInputImu | kInputBle))) continue;
    bool has_required = false;
    for (const ParamSpec& p : *d->schema()) has_required |= p.required();
    ASSERT_FALSE(has_required) << d->name << ": give it test parameters here";
    auto det = registry.create_detector(d->name);
    HostContext ctx = host.context(d->name, "A");
    det->configure(info, Params::defaults(*d->schema()), ctx);
    if (d->inputs & kInputAudio) audio_dets.push_back(det.get());
    if (d->inputs & kInputImu) imu_dets.push_back(det.get());
    if (d->inputs & kInputBle) ble_dets.push_back(det.get());
    names.emplace_back(d->name);
    detectors.push_back(std::move(det));
  }
  {  // `attitude` once more with the hard-iron calibration on (off by default): its solve runs in process_imu
    const locus_plugin_descriptor* d = registry.find_plugin("attitude");
    ASSERT_NE(d, nullptr);
    auto det = registry.create_detector("attitude");
    HostContext ctx = host.context("attitude_calibrating", "A");
    Params params = Params::defaults(*d->schema());
    params.set("mag_calibration", true);
    det->configure(info, params, ctx);
    imu_dets.push_back(det.get());
    names.emplace_back("attitude(mag_calibration)");
    detectors.push_back(std::move(det));
  }
  AudioRing ring(1, 1 << 16);
  RtEventQueue queue("A", 1 << 12);
  AudioBlockRunner block_runner(ring, kBlock, audio_dets, queue);
  RtAudioSource audio_source;
  RtSensorSource imu_source(SensorKind::Imu, false), ble_source(SensorKind::Ble, true),
      sync_source(SensorKind::Sync, true);
  SensorQueue imu_q(1024), ble_q(256), sync_q(64);
  DeviceRunner runner(kFs, queue, &queue);
  runner.set_audio(block_runner, ring, audio_source, kBlock);
  runner.add_sensor(imu_q, imu_source, imu_dets);
  runner.add_sensor(ble_q, ble_source, ble_dets);
  runner.add_sensor(sync_q, sync_source, {});

  std::vector<float> block(kBlock);
  std::uint64_t frame = 0;
  int n = 0;
  Event out;
  auto iterate = [&] {
    for (std::uint32_t i = 0; i < kBlock; ++i, ++frame) {
      block[i] = 0.3f * std::sin(2.0f * 3.14159265f * 1000.0f * static_cast<float>(frame) / 44100.0f);
    }
    ring.write(block.data(), kBlock);
    const double t = static_cast<double>(frame - kBlock + 100) / kFs;
    ImuSample imu;
    imu.device = "A";
    imu.t_s = t;
    imu.accel_mps2 = {0.0f, static_cast<float>(9.81 + std::sin(6.0 * t)), 0.5f * static_cast<float>(std::cos(11.0 * t))};
    // turning at about 1 rad/s, the field with it in the body frame: every 0.5 s interval of the
    // hard-iron calibrator counts as a turn and runs its solve
    imu.gyro_radps = {0.01f, 0.02f, static_cast<float>(1.0 + 0.3 * std::sin(2.0 * t))};
    imu.has_mag = true;
    imu.mag_ut = {static_cast<float>(20.0 * std::cos(t)), static_cast<float>(-20.0 * std::sin(t)), -44.0f};
    imu_q.try_push(imu);
    if (n % 4 == 0) {
      BleAdvertisement a;
      a.device = "A";
      a.t_s = t + 0.001;
      a.address = {0xC4, 0x2C, 0x03, 0x3A, 0x2C, 0xA1};
      a.rssi_dbm = static_cast<float>(-60 - n % 9);
      ble_q.try_push(a);
    }
    if (n % 16 == 0) {
      RadioSync r;
      r.device = "A";
      r.t_s = t + 0.002;
      r.source = "B1";
      sync_q.try_push(r);
    }
    ++n;
    while (runner.step(false)) {
    }
    while (queue.pop(out)) {
    }
  };
  for (int i = 0; i < 200; ++i) iterate();  // warm-up
  const std::uint64_t delivered0 = runner.sensor_events_delivered();
  RtSection rt;
  for (int i = 0; i < 4000; ++i) iterate();
  const long allocs = rt.allocs(), frees = rt.frees(), locks = rt.locks();
  std::string who;
  for (const auto& name : names) who += name + " ";
  EXPECT_EQ(allocs, 0) << "sensor delivery allocated (detectors: " << who << ")";
  EXPECT_EQ(frees, 0) << "sensor delivery freed (detectors: " << who << ")";
  EXPECT_EQ(locks, 0) << "sensor delivery locked a mutex (detectors: " << who << ")";
  EXPECT_GE(runner.sensor_events_delivered() - delivered0, 4000u + 1000u + 250u - 2u);
  EXPECT_GE(block_runner.frames_processed(), 4000u * kBlock);
}

// The time base on the same path: a live audio source with a frame-0 origin and live monotonic-time
// sensors, whose events the runner holds until the origin is known, then moves onto the audio timeline.
namespace {
class RtLiveAudioSource final : public AudioSource {
 public:
  void open(const Params&, HostContext&) override {}
  std::uint32_t channels() const override { return 1; }
  double sample_rate_hz() const override { return 44100.0; }
  bool live() const override { return true; }
  void start(AudioRing&) override {}
  void stop() override {}
  bool finished() const noexcept override { return false; }
  double frame_zero_monotonic_s() const noexcept override { return origin_s.load(std::memory_order_acquire); }
  std::atomic<double> origin_s{std::numeric_limits<double>::quiet_NaN()};
};
class RtMonotonicSensor final : public SensorSource {
 public:
  explicit RtMonotonicSensor(SensorKind kind) : kind_(kind) {}
  void open(const Params&, HostContext&) override {}
  SensorKind kind() const override { return kind_; }
  bool live() const override { return true; }
  bool monotonic_time() const override { return true; }
  void start(SensorQueue&) override {}
  void stop() override {}
  bool finished() const noexcept override { return false; }

 private:
  SensorKind kind_;
};
}  // namespace

TEST(RtSafety, LiveSensorTimeBaseDoesNotAllocateOrLock) {
  constexpr std::uint32_t kBlock = 256;
  constexpr double kFs = 44100.0;
  constexpr double kOrigin = 81234.5;  // CLOCK_MONOTONIC of audio frame 0
  AudioRing ring(1, 1 << 16);
  RtEventQueue queue("A", 1 << 12);
  AudioBlockRunner block_runner(ring, kBlock, {}, queue);
  RtLiveAudioSource audio_source;
  RtMonotonicSensor imu_source(SensorKind::Imu), ble_source(SensorKind::Ble);
  SensorQueue imu_q(1024), ble_q(256);
  DeviceRunner runner(kFs, queue, &queue);
  runner.set_audio(block_runner, ring, audio_source, kBlock);
  runner.add_sensor(imu_q, imu_source, {});
  runner.add_sensor(ble_q, ble_source, {});
  std::vector<float> block(kBlock, 0.1f);
  std::uint64_t frame = 0;
  Event out;
  double min_t = 1e300, max_t = -1e300;
  auto iterate = [&] {
    ring.write(block.data(), kBlock);
    frame += kBlock;
    const double t = kOrigin + static_cast<double>(frame - kBlock + 100) / kFs;
    ImuSample imu;
    imu.t_s = t;
    imu_q.try_push(imu);
    BleAdvertisement a;
    a.t_s = t + 0.001;
    ble_q.try_push(a);
    while (runner.step(false)) {
    }
    while (queue.pop(out)) {
      const double ts = sensor_event_time_s(out);
      if (!std::isnan(ts)) {
        min_t = std::min(min_t, ts);
        max_t = std::max(max_t, ts);
      }
    }
  };
  RtSection rt;
  for (int i = 0; i < 5; ++i) iterate();  // no origin yet: sensor events are held
  const std::uint64_t held_delivered = runner.sensor_events_delivered();
  audio_source.origin_s.store(kOrigin, std::memory_order_release);
  for (int i = 0; i < 4000; ++i) iterate();
  EXPECT_EQ(rt.allocs(), 0) << "time-base translation allocated";
  EXPECT_EQ(rt.frees(), 0) << "time-base translation freed";
  EXPECT_EQ(rt.locks(), 0) << "time-base translation locked a mutex";
  EXPECT_EQ(held_delivered, 0u);
  EXPECT_GT(runner.origin_waits(), 0u);
  EXPECT_GE(runner.sensor_events_translated(), 2u * 4000u);
  EXPECT_EQ(runner.sensor_events_untranslated(), 0u);
  EXPECT_GE(min_t, 0.0);  // on the audio timeline, not CLOCK_MONOTONIC
  EXPECT_LT(max_t, 4010.0 * kBlock / kFs);
}

}  // namespace

// The chirp detector's multipath branch (dsp::MultipathFit) runs only when a reflection distorts the
// correlation peak, which the generic noise-and-tone stream above does not produce: AMIL beeps with a
// reflection 12-30 samples after the direct path (the case that made the fit necessary).
// live: overlapped windows and a short settle (hop_s, settle_s), as ./run hil amil runs it.
static void chirp_multipath_rt(bool live) {
  Registry registry;
  register_builtins(registry);
  test::TestHost host;
  FftwPlanner fftw({}, /*measure=*/false);
  const locus_plugin_descriptor* d = registry.find_plugin("chirp");
  ASSERT_NE(d, nullptr);
  Params params = Params::defaults(*d->schema());
  params.set("f0_hz", 18000.0);
  params.set("f1_hz", 22000.0);
  params.set("duration_s", 0.05);
  params.set("fade_s", 0.005);
  if (live) {
    params.set("hop_s", 0.01);
    params.set("settle_s", 0.003);
  }
  constexpr std::uint32_t kBlock = 256;
  constexpr double kFs = 44100.0;
  StreamInfo info;
  info.device = "A";
  info.channels = 1;
  info.sample_rate_hz = kFs;
  info.max_block_frames = kBlock;
  auto detector = registry.create_detector("chirp");
  HostContext ctx{host.log, host.clock, fftw, host.link, "chirp", "A"};
  detector->configure(info, params, ctx);

  dsp::SignalSpec beep;
  beep.type = "lfm";
  beep.f0_hz = 18000;
  beep.f1_hz = 22000;
  beep.duration_s = 0.05;
  beep.fade_s = 0.005;
  const dsp::SignalEvaluator eval(beep, kFs);
  // 12 beeps 0.5 s apart, each with a reflection (gain 0.5..0.9, sign alternating) 12..30 samples later.
  constexpr std::size_t kBeeps = 12, kPeriod = 22050;
  std::vector<float> audio(kBeeps * kPeriod + 4096);
  std::uint32_t seed = 777;
  for (std::size_t n = 0; n < audio.size(); ++n) {
    seed = seed * 1664525u + 1013904223u;
    audio[n] = 1e-3f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
  }
  for (std::size_t b = 0; b < kBeeps; ++b) {
    const double start = 2000.0 + static_cast<double>(b * kPeriod) + 0.37 * static_cast<double>(b % 3);
    const double echo_delay = 12.0 + 1.5 * static_cast<double>(b);
    const double echo_gain = (b % 2 ? -1.0 : 1.0) * (0.5 + 0.035 * static_cast<double>(b));
    for (std::size_t n = 0; n < 2400; ++n) {
      const double k = std::floor(start) + static_cast<double>(n);
      audio[static_cast<std::size_t>(k)] += static_cast<float>(
          0.3 * (eval.value((k - start) / kFs) + echo_gain * eval.value((k - start - echo_delay) / kFs)));
    }
  }
  test::CollectingSink sink(1 << 12);
  const float* chan[1];
  AudioBlock block;
  block.channel_data = chan;
  block.channels = 1;
  // Warm-up on the first beep, then the measured section over the rest.
  std::size_t pos = 0;
  auto step = [&] {
    chan[0] = audio.data() + pos;
    block.frames = kBlock;
    block.first_frame = pos;
    detector->process_audio(block, sink);
    pos += kBlock;
  };
  while (pos + kBlock <= kPeriod) step();
  RtSection rt;
  while (pos + kBlock <= audio.size()) step();
  const long allocs = rt.allocs(), frees = rt.frees(), locks = rt.locks();
  EXPECT_EQ(allocs, 0);
  EXPECT_EQ(frees, 0);
  EXPECT_EQ(locks, 0);
  EXPECT_GE(sink.events.size(), kBeeps - 1) << "the beeps must be detected for the test to mean anything";
}

TEST(RtSafety, ChirpMultipathFitDoesNotAllocateOrLock) { chirp_multipath_rt(false); }
TEST(RtSafety, ChirpWithOverlappedWindowsDoesNotAllocateOrLock) { chirp_multipath_rt(true); }

// A Montage device: its own Gold code (through the own-emission canceller) overlapped by three other
// users' codes 50 dB weaker and Doppler-shifted (walking, ±1.2 m/s), codes from the scene
// (goldcode `from_scene`, `cancel_own`, Doppler search and the two-path first-arrival model on):
// process_audio never allocates or locks.
// gate: with the round gate (round_window_s) as config/montage-detect.yaml sets it.
void goldcode_canceller_doppler_rt(bool gate) {
  Registry registry;
  register_builtins(registry);
  test::TestHost host;
  FftwPlanner fftw({}, /*measure=*/false);
  const locus_plugin_descriptor* d = registry.find_plugin("goldcode");
  ASSERT_NE(d, nullptr);
  Params params = Params::defaults(*d->schema());
  params.set("from_scene", true);
  if (gate) params.set("round_window_s", std::vector<double>{0.16, 0.22});
  constexpr std::uint32_t kBlock = 256;
  constexpr double kFs = 44100.0;
  StreamInfo info;
  info.device = "A";
  info.channels = 1;
  info.sample_rate_hz = kFs;
  info.max_block_frames = kBlock;
  std::vector<SignalSpec> specs(4);
  std::vector<SceneSignal> scene;
  for (int u = 0; u < 4; ++u) {
    specs[static_cast<std::size_t>(u)].type = "gold";
    specs[static_cast<std::size_t>(u)].degree = 7;
    specs[static_cast<std::size_t>(u)].index = 2 + u;
    specs[static_cast<std::size_t>(u)].carrier_hz = 19000.0;
    specs[static_cast<std::size_t>(u)].chip_samples = 40;
    scene.push_back(SceneSignal{std::string(1, static_cast<char>('A' + u)), specs[static_cast<std::size_t>(u)], false, {}});
  }
  DeviceGeometry geometry;
  geometry.mic_count = 1;
  geometry.has_speaker = true;
  geometry.emits = std::span<const SignalSpec>(specs.data(), 1);
  geometry.scene_emits = scene;
  auto detector = registry.create_detector("goldcode");
  HostContext ctx{host.log, host.clock, fftw, host.link, "goldcode", "A", &geometry};
  detector->configure(info, params, ctx);

  constexpr std::size_t kRounds = 6, kPeriod = 44100;
  std::vector<float> audio(kRounds * kPeriod + 8192, 0.0f);
  std::uint32_t seed = 7;
  for (float& v : audio) {
    seed = seed * 1664525u + 1013904223u;
    v = 1e-5f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
  }
  const double speed[4] = {0.0, -1.2, 0.4, 1.2};
  for (std::size_t r = 0; r < kRounds; ++r)
    for (int u = 0; u < 4; ++u) {
      const std::vector<std::uint8_t> chips = dsp::gold_chips(specs[static_cast<std::size_t>(u)]);
      const double start = 4000.0 + static_cast<double>(r * kPeriod) + 97.3 * u;
      const double alpha = 1.0 + speed[u] / 343.0, a = u == 0 ? 0.3 : 0.3 * std::pow(10.0, -50.0 / 20.0);
      for (std::size_t n = static_cast<std::size_t>(start) + 1; n < audio.size(); ++n) {
        const double t = alpha * (static_cast<double>(n) - start);
        const auto k = static_cast<std::size_t>(t / 40.0);
        if (k >= chips.size()) break;
        audio[n] += static_cast<float>(a * (chips[k] ? -1.0 : 1.0) * std::cos(2.0 * M_PI * 19000.0 * t / kFs));
      }
    }
  test::CollectingSink sink(1 << 12);
  const float* chan[1];
  AudioBlock block;
  block.channel_data = chan;
  block.channels = 1;
  std::size_t pos = 0;
  auto step = [&] {
    chan[0] = audio.data() + pos;
    block.frames = kBlock;
    block.first_frame = pos;
    detector->process_audio(block, sink);
    pos += kBlock;
  };
  while (pos + kBlock <= kPeriod) step();
  long allocs = 0, frees = 0, locks = 0;
  {
    RtSection rt;
    while (pos + kBlock <= audio.size()) step();
    allocs = rt.allocs();
    frees = rt.frees();
    locks = rt.locks();
  }
  EXPECT_EQ(allocs, 0);
  EXPECT_EQ(frees, 0);
  EXPECT_EQ(locks, 0);
  std::size_t own = 0, others = 0;
  for (const Event& e : sink.events)
    if (const auto* a = std::get_if<AudioDetection>(&e)) (a->template_index == 0 ? own : others) += 1;
  EXPECT_GE(own, kRounds - 2) << "the own code must be cancelled (and reported) for the test to mean anything";
  EXPECT_GE(others, 3 * (kRounds - 3)) << "the other users must be found for the test to mean anything";
}

TEST(RtSafety, GoldcodeCancellerDopplerSearchDoesNotAllocateOrLock) { goldcode_canceller_doppler_rt(false); }
TEST(RtSafety, GoldcodeRoundGateDoesNotAllocateOrLock) { goldcode_canceller_doppler_rt(true); }

// A working TUM device: its own up-chirp (loud, through the own-emission canceller) overlapped by the
// other device's down-chirp 40 dB weaker, 2 channels, templates from the scene (chirp `cancel_own`),
// and dsp::EmissionCanceller on its own: process() and flush() never allocate or lock.
TEST(RtSafety, ChirpOwnEmissionCancellerDoesNotAllocateOrLock) {
  Registry registry;
  register_builtins(registry);
  test::TestHost host;
  FftwPlanner fftw({}, /*measure=*/false);
  const locus_plugin_descriptor* d = registry.find_plugin("chirp");
  ASSERT_NE(d, nullptr);
  Params params = Params::defaults(*d->schema());
  params.set("from_scene", true);
  constexpr std::uint32_t kBlock = 256;
  constexpr double kFs = 44100.0;
  StreamInfo info;
  info.device = "A";
  info.channels = 2;
  info.sample_rate_hz = kFs;
  info.max_block_frames = kBlock;
  DeviceGeometry geometry;
  geometry.mic_count = 2;
  geometry.has_speaker = true;
  const test::TumChirpSignals tum = test::tum_chirp_signals("A", "D");
  geometry.emits = tum.own;
  geometry.scene_emits = tum.scene;
  auto detector = registry.create_detector("chirp");
  HostContext ctx{host.log, host.clock, fftw, host.link, "chirp", "A", &geometry};
  detector->configure(info, params, ctx);

  dsp::SignalSpec up;
  up.type = "lfm";
  up.f0_hz = 2000;
  up.f1_hz = 8000;
  up.duration_s = 0.04;
  up.fade_s = 0.005;
  dsp::SignalSpec down = up;
  down.f0_hz = 8000;
  down.f1_hz = 2000;
  const dsp::SignalEvaluator eu(up, kFs), ed(down, kFs);
  constexpr std::size_t kRounds = 10, kPeriod = 14700;
  std::vector<float> audio[2];
  for (auto& a : audio) a.assign(kRounds * kPeriod + 4096, 0.0f);
  std::uint32_t seed = 99;
  for (std::size_t n = 0; n < audio[0].size(); ++n)
    for (auto& a : audio) {
      seed = seed * 1664525u + 1013904223u;
      a[n] = 1e-5f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
    }
  for (std::size_t r = 0; r < kRounds; ++r)
    for (std::size_t ch = 0; ch < 2; ++ch) {
      const double own = 3000.0 + static_cast<double>(r * kPeriod) + 0.3 * static_cast<double>(ch);
      const double other = own + 60.0 * static_cast<double>(r) + 11.7;  // 0..12 ms after the own tone
      for (std::size_t n = 0; n < 2400; ++n) {
        const double k = std::floor(own) + static_cast<double>(n);
        audio[ch][static_cast<std::size_t>(k)] += static_cast<float>(0.5 * eu.value((k - own) / kFs) +
                                                                     0.005 * ed.value((k - other) / kFs));
      }
    }
  test::CollectingSink sink(1 << 12);
  const float* chan[2];
  AudioBlock block;
  block.channel_data = chan;
  block.channels = 2;
  std::size_t pos = 0;
  auto step = [&] {
    chan[0] = audio[0].data() + pos;
    chan[1] = audio[1].data() + pos;
    block.frames = kBlock;
    block.first_frame = pos;
    detector->process_audio(block, sink);
    pos += kBlock;
  };
  while (pos + kBlock <= kPeriod) step();
  long allocs = 0, frees = 0, locks = 0;
  {
    RtSection rt;
    while (pos + kBlock <= audio[0].size()) step();
    allocs = rt.allocs();
    frees = rt.frees();
    locks = rt.locks();
  }
  EXPECT_EQ(allocs, 0);
  EXPECT_EQ(frees, 0);
  EXPECT_EQ(locks, 0);
  std::size_t other_found = 0;
  for (const Event& e : sink.events)
    if (const auto* a = std::get_if<AudioDetection>(&e); a && a->template_index == 1) ++other_found;
  EXPECT_GE(other_found, 2 * (kRounds - 2)) << "the overlapped tones must be found for the test to mean anything";

  // The canceller alone, including flush() at the end of the stream.
  dsp::EmissionCanceller canceller;
  dsp::EmissionCanceller::Options o;
  o.channels = 1;
  canceller.configure(dsp::render_signal(up, kFs), fftw, o);
  std::size_t cancelled_before = 0;
  {
    RtSection rt;
    std::size_t p = 0;
    while (p < audio[0].size()) {
      p += canceller.push(0, audio[0].data() + p, std::min<std::size_t>(kBlock, audio[0].size() - p));
      if (canceller.full(0)) {
        canceller.process(0);
        canceller.advance(0);
      }
    }
    canceller.flush(0);
    canceller.reset(0);
    cancelled_before = canceller.cancelled(0);
    EXPECT_EQ(rt.allocs(), 0);
    EXPECT_EQ(rt.frees(), 0);
    EXPECT_EQ(rt.locks(), 0);
  }
  EXPECT_EQ(cancelled_before, kRounds);
}

}  // namespace locus

namespace locus {

// The multitone detector's beep analysis (leading edge, onset fit, multipath onset fit with the Doppler
// estimate, decay features) runs inside
// process_audio when a beep's audio is complete: feed SpyLoc-like beeps (three identities, one every
// 0.3 s) so that path runs in the measured section, several beeps queued at once.
TEST(RtSafety, MultitoneBeepAnalysisDoesNotAllocateOrLock) {
  Registry registry;
  register_builtins(registry);
  test::TestHost host;
  FftwPlanner fftw({}, /*measure=*/false);
  const locus_plugin_descriptor* d = registry.find_plugin("multitone");
  ASSERT_NE(d, nullptr);
  constexpr std::uint32_t kBlock = 256;
  StreamInfo info;
  info.device = "W";
  info.channels = 1;
  info.sample_rate_hz = 44100.0;
  info.max_block_frames = kBlock;
  auto detector = registry.create_detector("multitone");
  HostContext ctx{host.log, host.clock, fftw, host.link, "multitone", "W"};
  detector->configure(info, Params::defaults(*d->schema()), ctx);
  // 6 s of beeps rendered before the measured section.
  std::vector<float> x(static_cast<std::size_t>(6.0 * 44100.0), 0.0f);
  const std::uint32_t masks[3] = {0b1100010001u, 0b1111010010u, 0b1010111100u};
  int beeps = 0;
  for (double t = 0.2; t < 5.7; t += 0.3, ++beeps) {
    dsp::SignalSpec s;
    s.type = "multitone";
    for (int k = 0; k < 10; ++k)
      if (masks[beeps % 3] & (1u << k)) s.tones_hz.push_back(18000.0 + 250.0 * k);
    s.duration_s = 0.05;
    s.fade_s = 0.005;
    s.amplitude = 0.3;
    dsp::SignalEvaluator ev(s, 44100.0);
    const auto n0 = static_cast<std::size_t>(t * 44100.0);
    // Direct path and a floor-like image 45 samples later: the multipath onset fit adds paths.
    for (std::size_t n = n0; n < n0 + 2400 && n < x.size(); ++n)
      x[n] += static_cast<float>(ev.value((n - t * 44100.0) / 44100.0) + 0.7 * ev.value((n - t * 44100.0 - 45.0) / 44100.0));
  }
  std::uint32_t seed = 7;
  for (float& v : x) {
    seed = seed * 1664525u + 1013904223u;
    v += 1e-4f * (static_cast<float>(seed >> 8) / 16777216.0f - 0.5f);
  }
  AudioRing ring(1, 1 << 16);
  RtEventQueue queue("W", 1 << 14);
  AudioBlockRunner runner(ring, kBlock, {detector.get()}, queue);
  std::size_t pos = 0;
  for (int i = 0; i < 20; ++i, pos += kBlock) {  // warm-up
    ring.write(x.data() + pos, kBlock);
    runner.step(false);
  }
  RtSection rt;
  for (; pos + kBlock <= x.size(); pos += kBlock) {
    ring.write(x.data() + pos, kBlock);
    runner.step(false);
  }
  EXPECT_EQ(rt.allocs(), 0) << "multitone allocated in process_audio";
  EXPECT_EQ(rt.frees(), 0) << "multitone freed in process_audio";
  EXPECT_EQ(rt.locks(), 0) << "multitone locked a mutex in process_audio";
  EXPECT_GE(queue.size_approx() + queue.dropped(), 2u * 15u) << "the beeps were not analysed (no events)";
}

}  // namespace locus
