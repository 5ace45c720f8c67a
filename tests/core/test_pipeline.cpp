// The pipeline end to end with test components registered in a local registry: a finite source
// whose samples encode their frame number, a detector that checks every sample it sees and emits a
// detection every 1000 frames, and a localizer that talks over the link and publishes estimates.
#include "locus/pipeline.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

namespace locus {
namespace {

const ParamSchema kNoParams{};
const ParamSchema kSourceSchema{
    ParamSpec{"frames", ParamType::Int, ParamValue{std::int64_t{100000}}, 1.0, 1e9, "", "frames to produce", {}, {}, {}},
    ParamSpec{"channels", ParamType::Int, ParamValue{std::int64_t{2}}, 1.0, 8.0, "", "channels", {}, {}, {}},
};

// value(frame, channel) is exact in float for frames < 2^20.
float value(std::uint64_t frame, std::uint32_t c) { return static_cast<float>(frame % (1u << 20)) + 0.25f * c; }

class RampSource final : public AudioSource {
 public:
  void open(const Params& p, HostContext&) override {
    frames_ = static_cast<std::uint64_t>(p.get_int("frames"));
    channels_ = static_cast<std::uint32_t>(p.get_int("channels"));
  }
  std::uint32_t channels() const override { return channels_; }
  double sample_rate_hz() const override { return 44100.0; }
  bool live() const override { return false; }
  void start(AudioRing& ring) override {
    thread_ = std::thread([this, &ring] {
      std::vector<float> block(333 * channels_);
      std::uint64_t f = 0;
      while (f < frames_ && !stop_) {
        const std::size_t n = std::min<std::uint64_t>(333, frames_ - f);
        for (std::size_t i = 0; i < n; ++i)
          for (std::uint32_t c = 0; c < channels_; ++c) block[i * channels_ + c] = value(f + i, c);
        std::size_t done = 0;
        while (done < n && !stop_) {
          auto span = ring.write_acquire(n - done);
          if (span.frames() == 0) {
            std::this_thread::sleep_for(std::chrono::microseconds(100));
            continue;
          }
          std::size_t k = 0;
          for (auto seg : {span.first, span.second})
            for (std::size_t i = 0; i < seg.frames; ++i, ++k)
              for (std::uint32_t c = 0; c < channels_; ++c) seg.data[i * channels_ + c] = block[(done + k) * channels_ + c];
          ring.write_commit(span.frames());
          done += span.frames();
        }
        f += n;
      }
      finished_ = true;
    });
  }
  void stop() override {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  bool finished() const noexcept override { return finished_; }
  ~RampSource() override { stop(); }

 private:
  std::uint64_t frames_ = 0;
  std::uint32_t channels_ = 1;
  std::thread thread_;
  std::atomic<bool> stop_{false}, finished_{false};
};

std::atomic<int> g_bad_samples{0};

class CheckingDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params&, HostContext& ctx) override {
    device_ = info.device;
    name_ = ctx.instance;
    max_block_ = info.max_block_frames;
  }
  void process_audio(const AudioBlock& b, EventSink& out) noexcept override {
    if (b.frames > max_block_ || b.first_frame != next_) g_bad_samples.fetch_add(1);
    for (std::uint32_t i = 0; i < b.frames; ++i) {
      const std::uint64_t f = b.first_frame + i;
      for (std::uint32_t c = 0; c < b.channels; ++c)
        if (b.channel_data[c][i] != value(f, c)) g_bad_samples.fetch_add(1);
      if (f % 1000 == 0) {
        AudioDetection d;
        d.device = device_;
        d.detector = name_;
        d.frame = static_cast<double>(f) + 0.5;
        d.sample_rate_hz = 44100;
        out.emit(d);
      }
    }
    next_ = b.first_frame + b.frames;
  }
  void finish(EventSink& out) override {
    AudioDetection d;
    d.device = device_;
    d.detector = name_;
    d.frame = -1;  // marks "finish ran"
    out.emit(d);
  }

 private:
  DeviceId device_;
  NameTag name_;
  std::uint32_t max_block_ = 0;
  std::uint64_t next_ = 0;
};

class CountingLocalizer final : public Localizer {
 public:
  void configure(const Params&, HostContext& ctx) override {
    link_ = &ctx.link;
    link_->subscribe("test/count", [this](const LinkMessage& m) {
      link_messages_ += std::stoi(m.payload);
      dispatcher_checks_ += std::this_thread::get_id() == dispatcher_ ? 0 : 1;
    });
  }
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event& e, Publisher& out) override {
    dispatcher_ = std::this_thread::get_id();
    const auto& d = std::get<AudioDetection>(e);
    if (d.frame < 0) return;
    ++detections_;
    if (detections_ % 10 == 0) link_->publish("test/count", "10");
    Estimate est;
    est.plugin = "count";
    est.target = d.device;
    est.t_s = d.frame / d.sample_rate_hz;
    est.position_m = {static_cast<double>(detections_), 0, 0};
    out.publish(est);
  }
  void finish(Publisher& out) override {
    Estimate est;
    est.plugin = "count";
    est.target = "total";
    est.position_m = {static_cast<double>(detections_), static_cast<double>(link_messages_), 0};
    out.publish(est);
  }

 private:
  Link* link_ = nullptr;
  int detections_ = 0;
  int link_messages_ = 0;
  int dispatcher_checks_ = 0;
  std::thread::id dispatcher_;
};

const locus_plugin_descriptor kCheckingDescriptor{
    LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "checking", "1", "checks samples", kInputAudio,
    [] { return &kNoParams; }, []() -> Detector* { return new CheckingDetector; }, nullptr};
const locus_plugin_descriptor kCountingDescriptor{
    LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "counting", "1", "counts", 0,
    [] { return &kNoParams; }, nullptr, []() -> Localizer* { return new CountingLocalizer; }};

struct PipelineFixture : ::testing::Test {
  Registry registry;
  std::filesystem::path out = std::filesystem::temp_directory_path() / ("locus-pipeline-" + std::to_string(::getpid()));
  void SetUp() override {
    g_bad_samples = 0;
    registry.add_plugin(&kCheckingDescriptor);
    registry.add_plugin(&kCountingDescriptor);
    registry.add_source(SourceDescriptor{"ramp", "test ramp", kSourceSchema, [] { return std::make_unique<RampSource>(); }});
  }
  void TearDown() override { std::filesystem::remove(out); }

  Config config(std::int64_t frames, int devices) {
    Config c;
    c.file = "test";
    c.output.path = out.string();
    c.output.events = {EventType::Estimate};
    for (int i = 0; i < devices; ++i) {
      DeviceConfig d;
      d.id = std::string(1, static_cast<char>('A' + i));
      AudioConfig a;
      a.source = "ramp";
      a.params = Params::defaults(kSourceSchema);
      a.params.set("frames", frames);
      a.ring_frames = 4096;
      a.block_frames = 256;
      d.audio = a;
      d.detectors.push_back(ComponentConfig{"checking", "check_" + d.id, Params{}});
      c.devices.push_back(d);
    }
    c.localizers.push_back(ComponentConfig{"counting", "count", Params{}});
    return c;
  }

  std::vector<nlohmann::json> lines() {
    std::ifstream in(out);
    std::vector<nlohmann::json> v;
    std::string line;
    while (std::getline(in, line)) v.push_back(nlohmann::json::parse(line));
    return v;
  }
};

TEST_F(PipelineFixture, EveryFrameReachesTheDetectorsAndEveryEventTheSinks) {
  constexpr std::int64_t kFrames = 1'000'000;  // ~23 s of audio through a 4096-frame ring
  Pipeline p(config(kFrames, 2), registry);
  std::atomic<int> detections{0};
  p.subscribe(EventType::AudioDetection, [&](const Event&) { ++detections; });
  p.start();
  while (!p.finished()) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  p.stop();

  EXPECT_EQ(g_bad_samples.load(), 0);
  for (const DeviceStats& s : p.stats()) {
    EXPECT_EQ(s.frames_processed, static_cast<std::uint64_t>(kFrames)) << s.id;
    EXPECT_EQ(s.frames_lost, 0u);
    EXPECT_EQ(s.events_dropped, 0u);
  }
  const int per_device = kFrames / 1000;
  EXPECT_EQ(detections.load(), 2 * (per_device + 1));  // + the finish() marker
  const auto j = lines();
  ASSERT_EQ(j.size(), static_cast<std::size_t>(2 * per_device + 1));
  const auto& total = j.back();
  EXPECT_EQ(total["target"], "total");
  EXPECT_EQ(total["position_m"][0].get<double>(), 2 * per_device);
  EXPECT_EQ(total["position_m"][1].get<double>(), 2 * per_device);  // every link message arrived before finish
}

TEST_F(PipelineFixture, StopMidStreamFlushesWhatWasAccepted) {
  Pipeline p(config(1'000'000'000, 1), registry);  // far longer than the test
  p.start();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  p.stop();
  EXPECT_FALSE(p.stats()[0].frames_processed == 0);
  const auto j = lines();
  // Every detection delivered became an estimate line, plus the final total.
  ASSERT_FALSE(j.empty());
  EXPECT_EQ(j.back()["target"], "total");
  EXPECT_EQ(j.size(), static_cast<std::size_t>(j.back()["position_m"][0].get<double>()) + 1);
  EXPECT_EQ(g_bad_samples.load(), 0);
}

TEST_F(PipelineFixture, UnknownSourceIsAClearError) {
  Config c = config(1000, 1);
  c.devices[0].audio->source = "nope";
  try {
    Pipeline p(c, registry);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("device 'A'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locus
