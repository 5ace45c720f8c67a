// The steps that build a Pipeline (core/src/runtime/pipeline_steps.hpp), each on its own: the
// HostContext factory, the link choice, the geometry, the sample-rate check, a device's audio,
// sensors and detector routing, the served device, the localizers and the outputs.
#include "pipeline_steps.hpp"

#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "support/test_host.hpp"

namespace locus::pipeline_steps {
namespace {

const ParamSchema* no_params() {
  static const ParamSchema schema;
  return &schema;
}

/// A finished audio source at a configurable rate and channel count.
class FixedSource final : public AudioSource {
 public:
  FixedSource(double rate_hz, std::uint32_t channels) : rate_hz_(rate_hz), channels_(channels) {}
  void open(const Params&, HostContext& ctx) override {
    opened_instance = std::string(ctx.instance);
    opened_device = std::string(ctx.device);
    opened_geometry = ctx.geometry;
  }
  std::uint32_t channels() const override { return channels_; }
  double sample_rate_hz() const override { return rate_hz_; }
  bool live() const override { return false; }
  void start(AudioRing&) override {}
  void stop() override {}
  bool finished() const noexcept override { return true; }

  static inline std::string opened_instance, opened_device;
  static inline const DeviceGeometry* opened_geometry = nullptr;

 private:
  double rate_hz_;
  std::uint32_t channels_;
};

/// A sensor source of any kind that produces nothing.
class QuietSensor final : public SensorSource {
 public:
  explicit QuietSensor(SensorKind kind) : kind_(kind) {}
  SensorKind kind() const noexcept override { return kind_; }
  void open(const Params&, HostContext&) override {}
  bool live() const noexcept override { return false; }
  void start(SensorQueue&) override {}
  void stop() override {}
  bool finished() const noexcept override { return true; }

 private:
  SensorKind kind_;
};

/// Remembers what configure() got.
class SpyDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params&, HostContext& ctx) override {
    last_info = info;
    last_emitter = ctx.emitter;
    last_instance = std::string(ctx.instance);
  }
  static inline StreamInfo last_info;
  static inline Emitter* last_emitter = nullptr;
  static inline std::string last_instance;
};

Detector* make_spy() { return new SpyDetector; }

const locus_plugin_descriptor kAudioDetector{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "audio_spy", "1", "d",
                                             kInputAudio, &no_params, &make_spy, nullptr};
const locus_plugin_descriptor kImuDetector{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "imu_spy", "1", "d",
                                           kInputImu, &no_params, &make_spy, nullptr};
const locus_plugin_descriptor kBothDetector{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "both_spy", "1", "d",
                                            kInputAudio | kInputImu, &no_params, &make_spy, nullptr};
const locus_plugin_descriptor kLocalizer{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "null_loc", "1", "l", 0,
                                         &no_params, nullptr, &test::make_null_localizer};

struct Steps : ::testing::Test {
  Steps() {
    registry.add_source(SourceDescriptor{"at44k", "", {}, [] { return std::make_unique<FixedSource>(44100.0, 3); }});
    registry.add_source(SourceDescriptor{"at48k", "", {}, [] { return std::make_unique<FixedSource>(48000.0, 1); }});
    registry.add_sensor_source(SensorSourceDescriptor{
        "imu_q", "", SensorKind::Imu, {}, [] { return std::make_unique<QuietSensor>(SensorKind::Imu); }});
    registry.add_sensor_source(SensorSourceDescriptor{
        "sync_q", "", SensorKind::Sync, {}, [] { return std::make_unique<QuietSensor>(SensorKind::Sync); }});
    registry.add_plugin(&kAudioDetector);
    registry.add_plugin(&kImuDetector);
    registry.add_plugin(&kBothDetector);
    registry.add_plugin(&kLocalizer);
  }

  static DeviceConfig device(const std::string& id, const std::string& source) {
    DeviceConfig dc;
    dc.id = id;
    if (!source.empty()) {
      AudioConfig ac;
      ac.source = source;
      ac.ring_frames = 1024;
      ac.block_frames = 128;
      dc.audio = ac;
    }
    return dc;
  }
  static SensorConfig sensor(const std::string& source) {
    SensorConfig sc;
    sc.source = source;
    sc.queue_capacity = 64;
    return sc;
  }

  Registry registry;
  test::TestHost test_host;
  HostServices host{test_host.clock, test_host.fft, test_host.link};
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST_F(Steps, HostContextCarriesEveryServiceAndTheInstance) {
  DeviceGeometry g;
  test::RecordingLogger log;
  HostContext ctx = host.context(log, "onset", "A", &g);
  EXPECT_EQ(&ctx.log, &log);
  EXPECT_EQ(&ctx.clock, &test_host.clock);
  EXPECT_EQ(&ctx.fft, &test_host.fft);
  EXPECT_EQ(&ctx.link, &test_host.link);
  EXPECT_EQ(ctx.instance, "onset");
  EXPECT_EQ(ctx.device, "A");
  EXPECT_EQ(ctx.geometry, &g);
  EXPECT_EQ(ctx.emitter, nullptr);
}

TEST_F(Steps, LinkIsTheSharedOneThenTheConfiguredTypeThenInProcess) {
  Config config;
  test::LoopbackLink shared;
  LinkChoice c = choose_link(config, registry, &shared);
  EXPECT_EQ(c.link, &shared);
  EXPECT_EQ(c.owned, nullptr);

  c = choose_link(config, registry, nullptr);
  ASSERT_NE(c.owned, nullptr);
  EXPECT_EQ(c.link, c.owned.get());
  EXPECT_EQ(c.inprocess, c.owned.get());

  config.link = LinkConfig{"carrier_pigeon", {}};
  EXPECT_EQ(error_of([&] { choose_link(config, registry, nullptr); }), "link: unknown type 'carrier_pigeon'");
  registry.add_link(LinkDescriptor{"broken", "", {}, [](const Params&, Logger&) -> std::unique_ptr<Link> {
                                     throw std::runtime_error("no broker");
                                   }});
  config.link = LinkConfig{"broken", {}};
  EXPECT_EQ(error_of([&] { choose_link(config, registry, nullptr); }), "link 'broken': no broker");
}

TEST_F(Steps, GeometryFromConfigKeepsAtMostMaxMicsAndTheOptionalParts) {
  GeometryConfig g;
  for (std::uint32_t i = 0; i < DeviceGeometry::kMaxMics + 3; ++i) g.mics_m.push_back({double(i), 0.0, 1.0});
  g.anchor_m = std::array<double, 3>{1.0, 2.0, 3.0};
  const GeometrySpec spec = geometry_from_config(g);
  EXPECT_EQ(spec.geometry.mic_count, DeviceGeometry::kMaxMics);
  EXPECT_EQ(spec.geometry.mics_m[5][0], 5.0);
  EXPECT_FALSE(spec.geometry.has_speaker);
  EXPECT_TRUE(spec.geometry.has_anchor);
  EXPECT_EQ(spec.geometry.anchor_m[2], 3.0);
}

TEST_F(Steps, ConfigGeometryFillsWhatTheEmbedderDidNotGiveAndPointsAtItsSignals) {
  Config config;
  DeviceConfig a = device("A", ""), b = device("B", ""), t = device(std::string(kTemplateDeviceId), "");
  a.geometry = GeometryConfig{{{0.0, 0.0, 0.0}}, std::nullopt, std::nullopt};
  b.geometry = GeometryConfig{{{1.0, 0.0, 0.0}, {2.0, 0.0, 0.0}}, std::nullopt, std::nullopt};
  t.geometry = b.geometry;
  config.devices = {a, b, t};
  std::map<std::string, GeometrySpec> geometry;
  GeometrySpec given;
  given.geometry.mic_count = 7;
  SignalSpec lfm;
  lfm.type = "lfm";
  given.emits = {lfm};
  geometry.emplace("A", given);
  add_config_geometry(config, geometry);
  ASSERT_EQ(geometry.size(), 2u);  // the template gets none
  EXPECT_EQ(geometry.at("A").geometry.mic_count, 7u);  // the embedder's wins
  EXPECT_EQ(geometry.at("B").geometry.mic_count, 2u);
  for (const auto& [id, spec] : geometry) {
    EXPECT_EQ(spec.geometry.emits.data(), spec.emits.data()) << id;
    EXPECT_EQ(spec.geometry.emits.size(), spec.emits.size()) << id;
    EXPECT_EQ(spec.geometry.scene_emits.data(), spec.scene_emits.data()) << id;
  }
  EXPECT_EQ(find_geometry(geometry, "B"), &geometry.at("B").geometry);
  EXPECT_EQ(find_geometry(geometry, "C"), nullptr);
}

TEST_F(Steps, NodeRateCheckNamesBothRates) {
  EXPECT_NO_THROW(require_node_rate("x", 48000.0, 48000.0 + 1e-9));
  EXPECT_EQ(error_of([] { require_node_rate("device 'A': audio source 'y'", 48000.0, 44100.0); }),
            "device 'A': audio source 'y' runs at 48000.000000 Hz but the node is configured for 44100.000000 Hz "
            "(sample_rate_hz)");
}

TEST_F(Steps, AudioOpensTheSourceWithTheDeviceContextAndSizesTheRing) {
  const DeviceConfig dc = device("A", "at44k");
  Device dev;
  dev.id = dc.id;
  DeviceGeometry g;
  dev.geometry = &g;
  StreamInfo info = initial_stream_info(dc, 44100.0);
  EXPECT_EQ(info.channels, 0u);
  EXPECT_EQ(info.max_block_frames, 128u);
  open_audio(dev, *dc.audio, registry, host, 44100.0, info);
  ASSERT_NE(dev.source, nullptr);
  ASSERT_NE(dev.ring, nullptr);
  EXPECT_EQ(dev.ring->channels(), 3u);
  EXPECT_EQ(info.channels, 3u);
  EXPECT_EQ(FixedSource::opened_instance, "at44k");
  EXPECT_EQ(FixedSource::opened_device, "A");
  EXPECT_EQ(FixedSource::opened_geometry, &g);
  EXPECT_EQ(initial_stream_info(device("B", ""), 44100.0).max_block_frames, 256u);
}

TEST_F(Steps, AudioAtAnotherRateOrUnknownIsRefusedNamingTheDevice) {
  const DeviceConfig dc = device("A", "at48k");
  Device dev;
  dev.id = dc.id;
  StreamInfo info = initial_stream_info(dc, 44100.0);
  const std::string e = error_of([&] { open_audio(dev, *dc.audio, registry, host, 44100.0, info); });
  EXPECT_EQ(e.rfind("device 'A': audio source 'at48k' runs at 48000", 0), 0u) << e;
  Device other;
  other.id = "B";
  const DeviceConfig unknown = device("B", "nope");
  EXPECT_EQ(error_of([&] { open_audio(other, *unknown.audio, registry, host, 44100.0, info); }),
            "device 'B': audio source 'nope': unknown audio source 'nope'");
}

TEST_F(Steps, PlaybackWithAnUnknownSinkIsRefused) {
  Device dev;
  dev.id = "A";
  PlaybackConfig pc;
  pc.sink = "horn";
  EXPECT_EQ(error_of([&] { open_playback(dev, pc, registry, host, 44100.0); }),
            "device 'A': playback sink 'horn': unknown playback sink");
  EXPECT_EQ(dev.emitter, nullptr);
}

TEST_F(Steps, SensorsOpenInKindOrderAndSumTheirQueues) {
  DeviceConfig dc = device("A", "");
  dc.sync = sensor("sync_q");
  dc.imu = sensor("imu_q");
  Device dev;
  dev.id = dc.id;
  const std::size_t capacity = open_sensors(dev, dc, registry, host);
  ASSERT_EQ(dev.sensors.size(), 2u);
  EXPECT_EQ(dev.sensors[0].kind, SensorKind::Imu);
  EXPECT_EQ(dev.sensors[1].kind, SensorKind::Sync);
  EXPECT_EQ(capacity, dev.sensors[0].queue->capacity() + dev.sensors[1].queue->capacity());
  EXPECT_EQ(available_inputs(dev), kInputImu);  // sync feeds no detector

  DeviceConfig wrong = device("B", "");
  wrong.ble = sensor("imu_q");
  Device dev_b;
  dev_b.id = "B";
  EXPECT_EQ(error_of([&] { open_sensors(dev_b, wrong, registry, host); }),
            "device 'B': ble source 'imu_q': produces imu events");
}

TEST_F(Steps, DetectorsAreRoutedToTheStreamsTheyConsume) {
  DeviceConfig dc = device("A", "at44k");
  dc.imu = sensor("imu_q");
  dc.detectors = {ComponentConfig{"audio_spy", "a1", {}}, ComponentConfig{"imu_spy", "i1", {}},
                  ComponentConfig{"both_spy", "b1", {}}};
  Device dev;
  dev.id = dc.id;
  StreamInfo info = initial_stream_info(dc, 44100.0);
  open_audio(dev, *dc.audio, registry, host, 44100.0, info);
  open_sensors(dev, dc, registry, host);
  EXPECT_EQ(available_inputs(dev), kInputAudio | kInputImu);
  const DetectorRoutes routes = create_detectors(dev, dc, registry, host, info);
  ASSERT_EQ(dev.detectors.size(), 3u);
  EXPECT_EQ(routes.audio, (std::vector<Detector*>{dev.detectors[0].get(), dev.detectors[2].get()}));
  EXPECT_EQ(routes.imu, (std::vector<Detector*>{dev.detectors[1].get(), dev.detectors[2].get()}));
  EXPECT_TRUE(routes.ble.empty());
  EXPECT_EQ(SpyDetector::last_instance, "b1");
  EXPECT_EQ(SpyDetector::last_info.channels, 3u);
  EXPECT_EQ(SpyDetector::last_emitter, nullptr);  // no playback section
}

TEST_F(Steps, ADetectorWithoutItsStreamIsRefused) {
  DeviceConfig dc = device("A", "at44k");
  dc.detectors = {ComponentConfig{"imu_spy", "steps", {}}};
  Device dev;
  dev.id = dc.id;
  StreamInfo info = initial_stream_info(dc, 44100.0);
  open_audio(dev, *dc.audio, registry, host, 44100.0, info);
  EXPECT_EQ(error_of([&] { create_detectors(dev, dc, registry, host, info); }),
            "device 'A': detector 'steps' consumes  imu but the device has no such stream");
}

TEST_F(Steps, BuildDeviceWiresRunnersOnlyForADeviceWithStreams) {
  EventBus bus;
  const std::map<std::string, GeometrySpec> geometry;
  DeviceConfig dc = device("A", "at44k");
  dc.detectors = {ComponentConfig{"audio_spy", "a1", {}}};
  const auto dev = build_device(dc, registry, host, geometry, 44100.0, bus);
  ASSERT_NE(dev->device_runner, nullptr);
  ASSERT_NE(dev->runner, nullptr);
  ASSERT_NE(dev->queue, nullptr);
  EXPECT_GE(dev->queue->capacity(), 4096u);

  const auto quiet = build_device(device("B", ""), registry, host, geometry, 44100.0, bus);
  EXPECT_EQ(quiet->device_runner, nullptr);
  EXPECT_EQ(quiet->queue, nullptr);
  DeviceConfig lonely = device("C", "");
  lonely.detectors = {ComponentConfig{"audio_spy", "a1", {}}};
  EXPECT_EQ(error_of([&] { build_device(lonely, registry, host, geometry, 44100.0, bus); }),
            "device 'C' has detectors but no stream (audio, imu, ble or sync)");
}

TEST_F(Steps, LocalizersServeTheGivenDeviceOrTheOnlyOne) {
  Config config;
  config.devices = {device(std::string(kTemplateDeviceId), ""), device("A", "")};
  EXPECT_EQ(served_device(config, ""), "A");
  EXPECT_EQ(served_device(config, "Z"), "Z");
  config.devices.push_back(device("B", ""));
  EXPECT_EQ(served_device(config, ""), "");
}

TEST_F(Steps, LocalizerOpensOrNamesItself) {
  auto inst = open_localizer(ComponentConfig{"null_loc", "tri", {}}, registry, host, "A/tri", "A", nullptr, nullptr);
  EXPECT_EQ(inst->name, "tri");
  ASSERT_NE(inst->localizer, nullptr);
  EXPECT_EQ(error_of([&] {
              open_localizer(ComponentConfig{"audio_spy", "tri", {}}, registry, host, "tri", "", nullptr, nullptr);
            }),
            "localizer 'tri': plugin 'audio_spy' is a detector, not a localizer");
}

TEST_F(Steps, UnknownOutputIsRefusedWithoutALogger) {
  std::vector<std::unique_ptr<SpdLogger>> logs;
  EventOutputConfig oc;
  oc.type = "telegraph";
  EXPECT_EQ(error_of([&] { open_output(oc, registry, logs); }), "output: unknown type 'telegraph'");
  EXPECT_TRUE(logs.empty());
}

}  // namespace
}  // namespace locus::pipeline_steps
