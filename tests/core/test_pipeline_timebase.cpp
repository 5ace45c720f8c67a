// The pipeline's time base (pipeline.hpp, "Time base"): on a device whose audio source is live, sensor
// events stamped on CLOCK_MONOTONIC (SensorSource::monotonic_time()) are moved onto the audio timeline
// (t_s - AudioSource::frame_zero_monotonic_s()) before they are merged with the audio, handed to the
// detectors and posted to the sink; events popped before the origin is known are held; replay devices
// and devices without audio keep their times. DeviceRunner is driven on the test thread with fakes,
// then once with the real synth source in pace=realtime (its own thread, the real steady clock).
#include <gtest/gtest.h>

#include <time.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "locus/pipeline.hpp"
#include "synth/synth_source.hpp"

namespace locus {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double monotonic_now_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// An audio source whose frames the test writes into the ring itself, with a settable origin.
class FakeAudio final : public AudioSource {
 public:
  explicit FakeAudio(bool live) : live_(live) {}
  void open(const Params&, HostContext&) override {}
  std::uint32_t channels() const override { return 1; }
  double sample_rate_hz() const override { return 1000.0; }
  bool live() const override { return live_; }
  void start(AudioRing&) override {}
  void stop() override {}
  bool finished() const noexcept override { return finished_.load(); }
  double frame_zero_monotonic_s() const noexcept override { return origin_s_.load(); }

  std::atomic<double> origin_s_{kNaN};
  std::atomic<bool> finished_{false};

 private:
  bool live_;
};

/// A sensor source whose events the test pushes into the queue itself.
class FakeImu final : public SensorSource {
 public:
  FakeImu(bool live, bool monotonic) : live_(live), monotonic_(monotonic) {}
  void open(const Params&, HostContext&) override {}
  SensorKind kind() const override { return SensorKind::Imu; }
  bool live() const override { return live_; }
  bool monotonic_time() const override { return monotonic_; }
  void start(SensorQueue&) override {}
  void stop() override {}
  bool finished() const noexcept override { return finished_.load(); }

  std::atomic<bool> finished_{false};

 private:
  bool live_;
  bool monotonic_;
};

/// What the detector saw, in order: audio blocks (their first frame) and IMU samples (their t_s).
struct Seen {
  char kind;     // 'A' or 'I'
  double value;  // first frame or t_s
};

class RecordingDetector final : public Detector {
 public:
  void configure(const StreamInfo&, const Params&, HostContext&) override {}
  void process_audio(const AudioBlock& b, EventSink&) noexcept override {
    seen.push_back({'A', static_cast<double>(b.first_frame)});
  }
  void process_imu(const ImuSample* s, std::size_t n, EventSink&) noexcept override {
    for (std::size_t i = 0; i < n; ++i) seen.push_back({'I', s[i].t_s});
  }
  std::vector<Seen> seen;
};

/// The sink: the raw sensor events' times as posted.
class TimesSink final : public EventSink {
 public:
  bool emit(const Event& e) noexcept override {
    const double t = sensor_event_time_s(e);
    if (!std::isnan(t)) times.push_back(t);
    return true;
  }
  std::vector<double> times;
};

ImuSample imu_at(double t_s) {
  ImuSample s;
  s.t_s = t_s;
  return s;
}

void write_frames(AudioRing& ring, std::size_t n) {
  std::vector<float> zeros(n, 0.0f);
  ASSERT_EQ(ring.write(zeros.data(), n), n);
}

/// One device: a 1-channel 1000 Hz ring read in 100-frame blocks, one IMU stream, one recording detector.
struct Device {
  Device(bool audio_live, bool imu_live, bool imu_monotonic, bool with_audio = true, std::size_t queue_capacity = 64)
      : audio(audio_live), imu(imu_live, imu_monotonic), ring(1, 4096), queue(queue_capacity), runner(1000.0, sink) {
    if (with_audio) {
      blocks = std::make_unique<AudioBlockRunner>(ring, 100, std::vector<Detector*>{&detector}, sink);
      runner.set_audio(*blocks, ring, audio, 100);
    }
    runner.add_sensor(queue, imu, {&detector});
  }
  /// Steps until nothing more can be delivered now.
  void run(bool stop_requested) {
    for (int i = 0; i < 10000 && runner.step(stop_requested); ++i) {
    }
  }
  FakeAudio audio;
  FakeImu imu;
  AudioRing ring;
  SensorQueue queue;
  RecordingDetector detector;
  TimesSink sink;
  std::unique_ptr<AudioBlockRunner> blocks;
  DeviceRunner runner;
};

void expect_seen(const std::vector<Seen>& got, const std::vector<Seen>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(got[i].kind, want[i].kind) << "item " << i;
    EXPECT_NEAR(got[i].value, want[i].value, 1e-9) << "item " << i;
  }
}

TEST(PipelineTimebase, LiveSensorEventsGoOntoTheAudioTimelineAndMergeInOrder) {
  Device d(/*audio_live=*/true, /*imu_live=*/true, /*imu_monotonic=*/true);
  const double origin = 5000.0;  // frame 0 captured at monotonic 5000 s
  d.audio.origin_s_ = origin;
  write_frames(d.ring, 300);
  for (const double t : {origin - 0.01, origin + 0.05, origin + 0.15, origin + 0.25})
    ASSERT_TRUE(d.queue.try_push(imu_at(t)));
  d.run(false);
  d.imu.finished_ = true;
  d.audio.finished_ = true;
  d.run(true);
  EXPECT_TRUE(d.runner.done());
  // Before block [F, F + 100) come exactly the events with t * fs < F (t on the audio timeline).
  expect_seen(d.detector.seen, {{'I', -0.01}, {'A', 0}, {'I', 0.05}, {'A', 100}, {'I', 0.15}, {'A', 200}, {'I', 0.25}});
  ASSERT_EQ(d.sink.times.size(), 4u);  // posted translated too
  EXPECT_NEAR(d.sink.times[0], -0.01, 1e-9);
  EXPECT_NEAR(d.sink.times[3], 0.25, 1e-9);
  EXPECT_EQ(d.runner.sensor_events_translated(), 4u);
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 0u);
}

TEST(PipelineTimebase, EventsBeforeTheOriginIsKnownAreHeldThenTranslated) {
  Device d(true, true, true);
  ASSERT_TRUE(d.queue.try_push(imu_at(700.05)));
  ASSERT_TRUE(d.queue.try_push(imu_at(700.12)));
  d.run(false);
  EXPECT_TRUE(d.detector.seen.empty()) << "delivered before the audio had an origin";
  EXPECT_TRUE(d.sink.times.empty());
  EXPECT_GT(d.runner.origin_waits(), 0u);

  d.audio.origin_s_ = 700.0;  // the audio starts: origin known, frames follow
  write_frames(d.ring, 200);
  d.run(false);
  expect_seen(d.detector.seen, {{'A', 0}, {'I', 0.05}, {'A', 100}, {'I', 0.12}});
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 0u);
  EXPECT_EQ(d.runner.sensor_events_translated(), 2u);
}

TEST(PipelineTimebase, AudioThatNeverStartsReleasesHeldEventsUntranslatedAndCountsThem) {
  Device d(true, true, true);
  ASSERT_TRUE(d.queue.try_push(imu_at(700.05)));
  d.run(false);
  EXPECT_TRUE(d.detector.seen.empty());
  d.run(true);  // inputs stopped without an origin
  expect_seen(d.detector.seen, {{'I', 700.05}});
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 1u);
  EXPECT_EQ(d.runner.sensor_events_translated(), 0u);
}

TEST(PipelineTimebase, AFullQueueReleasesTheOldestHeldEventRatherThanLosingNewOnes) {
  Device d(true, true, true, true, /*queue_capacity=*/4);
  ASSERT_EQ(d.queue.capacity(), 4u);
  double t = 100.0;
  while (d.queue.try_push(imu_at(t))) t += 0.01;  // full
  d.run(false);                                   // pops the head (held), queue 3 of 4: still held
  ASSERT_TRUE(d.queue.try_push(imu_at(t)));       // full again
  ASSERT_TRUE(d.runner.step(false));              // the oldest goes out on its own clock
  expect_seen(d.detector.seen, {{'I', 100.0}});
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 1u);
  EXPECT_FALSE(d.runner.step(false));  // the next one is held again (the queue has room)

  d.audio.origin_s_ = 100.0;
  write_frames(d.ring, 100);
  d.run(false);
  // The rest is translated: 0.01 .. 0.04 s lie in block [0, 100) at 1000 Hz, so they follow it.
  expect_seen(d.detector.seen, {{'I', 100.0}, {'A', 0}, {'I', 0.01}, {'I', 0.02}, {'I', 0.03}, {'I', 0.04}});
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 1u);
  EXPECT_EQ(d.runner.sensor_events_translated(), 4u);
}

TEST(PipelineTimebase, ReplayDeviceKeepsItsTimes) {
  // Non-live audio and a non-monotonic (scene) sensor: device-local time is already the audio's.
  Device d(/*audio_live=*/false, /*imu_live=*/false, /*imu_monotonic=*/false);
  d.audio.origin_s_ = 5000.0;  // ignored: replay
  write_frames(d.ring, 200);
  for (const double t : {0.05, 0.15}) ASSERT_TRUE(d.queue.try_push(imu_at(t)));
  d.imu.finished_ = true;
  d.audio.finished_ = true;
  d.run(false);
  EXPECT_TRUE(d.runner.done());
  expect_seen(d.detector.seen, {{'A', 0}, {'I', 0.05}, {'A', 100}, {'I', 0.15}});
  EXPECT_EQ(d.runner.sensor_events_translated(), 0u);
}

TEST(PipelineTimebase, NonLiveAudioDoesNotTranslateMonotonicSensors) {
  Device d(/*audio_live=*/false, true, true);
  d.audio.origin_s_ = 5000.0;
  write_frames(d.ring, 100);
  ASSERT_TRUE(d.queue.try_push(imu_at(5000.05)));
  d.imu.finished_ = true;
  d.audio.finished_ = true;
  d.run(true);
  ASSERT_EQ(d.sink.times.size(), 1u);
  EXPECT_NEAR(d.sink.times[0], 5000.05, 1e-9);
  EXPECT_EQ(d.runner.sensor_events_translated(), 0u);
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 0u);
}

TEST(PipelineTimebase, DeviceWithoutAudioKeepsMonotonicTime) {
  Device d(true, true, true, /*with_audio=*/false);
  ASSERT_TRUE(d.queue.try_push(imu_at(1234.5)));
  d.run(false);
  expect_seen(d.detector.seen, {{'I', 1234.5}});
  EXPECT_EQ(d.runner.sensor_events_translated(), 0u);
  EXPECT_EQ(d.runner.sensor_events_untranslated(), 0u);
}

// The real synth source in pace=realtime: its origin is the steady clock at its start, so an event
// stamped with CLOCK_MONOTONIC when the source had produced P frames lands at t >= P / fs (those
// frames were captured before the stamp) and not far after (a block of 256 frames plus scheduling).
TEST(PipelineTimebase, RealtimeSynthSourcePutsMonotonicStampsOnItsFrameClock) {
  hal::synth::SynthConfig cfg;
  cfg.channels = 1;
  cfg.duration_s = 1.5;
  cfg.pace = hal::synth::Pace::Realtime;
  hal::synth::SynthSource synth;
  synth.open(cfg);
  ASSERT_TRUE(synth.live());
  EXPECT_TRUE(std::isnan(synth.frame_zero_monotonic_s()));

  const double fs = synth.sample_rate_hz();
  FakeImu imu(true, true);
  AudioRing ring(1, 1 << 16);
  SensorQueue queue(256);
  RecordingDetector detector;
  TimesSink sink;
  AudioBlockRunner blocks(ring, 256, {&detector}, sink);
  DeviceRunner runner(fs, sink);
  runner.set_audio(blocks, ring, synth, 256);
  runner.add_sensor(queue, imu, {&detector});

  const double before_start = monotonic_now_s();
  synth.start(ring);
  std::vector<double> produced_s;  // frames produced / fs when each stamp was taken
  std::thread producer([&] {
    // Before the first frame the stream has no origin yet and a stamp may precede it (a loaded machine
    // starts the synth thread late): the stamps are taken once frames flow.
    const auto first_frame_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (synth.frames_produced() == 0 && std::chrono::steady_clock::now() < first_frame_deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    for (int i = 0; i < 20; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(i == 0 ? 0 : 50));
      const double p = static_cast<double>(synth.frames_produced()) / fs;
      const double t = monotonic_now_s();
      produced_s.push_back(p);
      ASSERT_TRUE(queue.try_push(imu_at(t)));
    }
    imu.finished_ = true;
  });
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!runner.done() && std::chrono::steady_clock::now() < deadline) {
    if (!runner.step(false)) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  producer.join();
  synth.stop();
  ASSERT_TRUE(runner.done()) << "timed out";

  const double origin = synth.frame_zero_monotonic_s();
  ASSERT_TRUE(std::isfinite(origin));
  EXPECT_GE(origin, before_start);
  EXPECT_EQ(runner.sensor_events_translated(), 20u);
  EXPECT_EQ(runner.sensor_events_untranslated(), 0u);
  std::vector<double> imu_t;
  double last_block_start_s = -1.0;
  for (const Seen& s : detector.seen) {
    if (s.kind == 'A') {
      last_block_start_s = s.value / fs;
      continue;
    }
    imu_t.push_back(s.value);
    // Merge order: a block delivered before the event was either produced before the stamp was taken
    // (so it starts before the event's time) or was readable with the event queued, and then the
    // merge puts it after the event unless it starts earlier. Untranslated stamps would fail this.
    EXPECT_LE(last_block_start_s, s.value + 2e-3) << "event at " << s.value;
  }
  ASSERT_EQ(imu_t.size(), produced_s.size());
  for (std::size_t i = 0; i < imu_t.size(); ++i) {
    EXPECT_GE(imu_t[i], produced_s[i] - 1e-3) << "stamp " << i << " precedes frames already produced";
    EXPECT_LE(imu_t[i], produced_s[i] + 2.0) << "stamp " << i << " far after the frames produced (load?)";
  }
}

}  // namespace
}  // namespace locus
