// Registry::load_library / load_directory against the fixture libraries of tests/plugin_fixtures
// (built into <build>/test-plugins/<case>/), and the example out-of-tree clip_detector built in-tree.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "locus/registry.hpp"

namespace locus {
namespace {

namespace fs = std::filesystem;

const std::string kPluginDir = std::string(LOCUS_BINARY_DIR) + "/test-plugins";
const std::string kGood = kPluginDir + "/good/libfixture_good.so";
const std::string kWrongAbi = kPluginDir + "/wrong_abi/libfixture_wrong_abi.so";
const std::string kNoEntry = kPluginDir + "/no_entry/libfixture_no_entry.so";
const std::string kDuplicate = kPluginDir + "/duplicate/libfixture_duplicate.so";
const std::string kBadDescriptor = kPluginDir + "/bad_descriptor/libfixture_bad_descriptor.so";
const std::string kNotElf = kPluginDir + "/not_elf/libnot_elf.so";
const std::string kClip = kPluginDir + "/clip/libclip_detector.so";

struct NullLogger : Logger {
  void log(LogLevel, std::string_view) override {}
};
struct ZeroClock : Clock {
  double now_s() const noexcept override { return 0.0; }
};
struct NoFft : FftPlanner {
  std::unique_ptr<RealFft> plan_real(std::size_t) override { throw std::invalid_argument("no FFT in this test"); }
};
struct NoLink : Link {
  void publish(std::string_view, std::string_view) override {}
  std::uint64_t subscribe(std::string_view, LinkHandler) override { return 1; }
  void unsubscribe(std::uint64_t) override {}
};
struct TestHost {
  NullLogger log;
  ZeroClock clock;
  NoFft fft;
  NoLink link;
  HostContext ctx{log, clock, fft, link, "inst", "dev0"};
};

struct CollectSink : EventSink {
  CollectSink() { events.reserve(64); }
  bool emit(const Event& e) noexcept override {
    events.push_back(e);
    return true;
  }
  std::vector<AudioDetection> detections() const {
    std::vector<AudioDetection> out;
    for (const Event& e : events) {
      if (const auto* d = std::get_if<AudioDetection>(&e)) out.push_back(*d);
    }
    return out;
  }
  std::vector<Event> events;
};

struct CollectPublisher : Publisher {
  void publish(const Event& e) override { events.push_back(e); }
  std::vector<Event> events;
};

/// Planar block over `data` (one vector per channel, all the same length).
struct Block {
  explicit Block(std::vector<std::vector<float>> d, std::uint64_t first_frame, std::uint64_t lost = 0)
      : data(std::move(d)) {
    for (auto& ch : data) pointers.push_back(ch.data());
    block.channel_data = pointers.data();
    block.channels = static_cast<std::uint32_t>(data.size());
    block.frames = static_cast<std::uint32_t>(data.empty() ? 0 : data[0].size());
    block.first_frame = first_frame;
    block.lost_before = lost;
  }
  std::vector<std::vector<float>> data;
  std::vector<const float*> pointers;
  AudioBlock block;
};

std::string load_error(Registry& registry, const std::string& path) {
  try {
    registry.load_library(path);
  } catch (const PluginLoadError& e) {
    return e.what();
  }
  ADD_FAILURE() << "loading " << path << " did not throw PluginLoadError";
  return {};
}

const Registry::PluginEntry* entry_of(const Registry& registry, std::string_view name) {
  for (const auto& e : registry.plugins()) {
    if (e.descriptor->name == name) return &e;
  }
  return nullptr;
}

TEST(PluginLoader, FixturesWereBuilt) {
  for (const auto& p : {kGood, kWrongAbi, kNoEntry, kDuplicate, kBadDescriptor, kNotElf, kClip}) {
    EXPECT_TRUE(fs::exists(p)) << p;
  }
}

TEST(PluginLoader, GoodLibraryAddsDetectorAndLocalizer) {
  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::vector<std::string> names = registry.load_library(kGood);
  EXPECT_EQ(names, (std::vector<std::string>{"fixture_level", "fixture_count"}));
  ASSERT_EQ(registry.plugins().size(), before + 2);

  const locus_plugin_descriptor* level = registry.find_plugin("fixture_level");
  ASSERT_NE(level, nullptr);
  EXPECT_EQ(level->kind, LOCUS_PLUGIN_DETECTOR);
  EXPECT_EQ(level->abi_version, LOCUS_PLUGIN_ABI_VERSION);
  EXPECT_EQ(entry_of(registry, "fixture_level")->origin, kGood);
  const locus_plugin_descriptor* count = registry.find_plugin("fixture_count");
  ASSERT_NE(count, nullptr);
  EXPECT_EQ(count->kind, LOCUS_PLUGIN_LOCALIZER);
  EXPECT_EQ(entry_of(registry, "fixture_count")->origin, kGood);
}

TEST(PluginLoader, GoodDetectorRunsOnABlock) {
  Registry registry;
  registry.load_library(kGood);
  TestHost host;
  CollectSink sink;
  std::unique_ptr<Detector> detector = registry.create_detector("fixture_level");
  ASSERT_NE(detector, nullptr);

  StreamInfo info;
  info.device = "dev0";
  info.channels = 1;
  info.sample_rate_hz = 48000.0;
  Params params;
  params.set("threshold", 0.5);
  detector->configure(info, params, host.ctx);

  Block b({{0.0f, 0.1f, 0.2f, 0.8f, 0.9f, 0.1f, -0.7f, 0.0f}}, 100);
  detector->process_audio(b.block, sink);
  const auto d = sink.detections();
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].frame, 103.0);
  EXPECT_EQ(d[1].frame, 106.0);
  EXPECT_EQ(d[0].device, std::string_view("dev0"));
  EXPECT_EQ(d[0].detector, std::string_view("inst"));
  EXPECT_EQ(d[0].sample_rate_hz, 48000.0);
  EXPECT_FLOAT_EQ(d[1].amplitude, 0.7f);

  std::unique_ptr<Localizer> localizer = registry.create_localizer("fixture_count");
  ASSERT_NE(localizer, nullptr);
  localizer->configure(Params{}, host.ctx);
  EXPECT_EQ(localizer->subscriptions(), std::vector<EventType>{EventType::AudioDetection});
  CollectPublisher pub;
  localizer->on_event(Event{d[0]}, pub);
  ASSERT_EQ(pub.events.size(), 1u);
  ASSERT_TRUE(std::holds_alternative<Estimate>(pub.events[0]));
  EXPECT_FLOAT_EQ(std::get<Estimate>(pub.events[0]).confidence, 0.5f);
  // Instances (whose code lives in the library) are destroyed before the registry closes it.
}

TEST(PluginLoader, WrongAbiIsRefusedWithBothVersions) {
  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kWrongAbi);
  EXPECT_NE(msg.find(kWrongAbi), std::string::npos) << msg;
  EXPECT_NE(msg.find("built for Locus plugin ABI 999"), std::string::npos) << msg;
  EXPECT_NE(msg.find("this host speaks ABI " + std::to_string(LOCUS_PLUGIN_ABI_VERSION)), std::string::npos) << msg;
  EXPECT_NE(msg.find("rebuild the plugin"), std::string::npos) << msg;
  EXPECT_NE(msg.find("find_package(Locus)"), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
  EXPECT_EQ(registry.find_plugin("fixture_from_the_future"), nullptr);
}

TEST(PluginLoader, MissingEntryPointIsRefused) {
  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kNoEntry);
  EXPECT_NE(msg.find(kNoEntry), std::string::npos) << msg;
  EXPECT_NE(msg.find("no entry point 'locus_plugin_enum'"), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
}

TEST(PluginLoader, DuplicateWithAnotherLibraryAddsNothing) {
  Registry registry;
  registry.load_library(kGood);
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kDuplicate);
  EXPECT_NE(msg.find(kDuplicate), std::string::npos) << msg;
  EXPECT_NE(msg.find("'fixture_level' is already registered"), std::string::npos) << msg;
  EXPECT_NE(msg.find("loaded from " + kGood), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
  // The library's other (valid, new) descriptor was not added either.
  EXPECT_EQ(registry.find_plugin("fixture_dup_unique"), nullptr);
  EXPECT_EQ(entry_of(registry, "fixture_level")->origin, kGood);
}

TEST(PluginLoader, DuplicateOfABuiltInIsRefused) {
  static const ParamSchema kNoParams;
  static const locus_plugin_descriptor kBuiltin = {
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "fixture_level", "1", "a built-in stand-in", kInputAudio,
      []() -> const ParamSchema* { return &kNoParams; }, []() -> Detector* { return nullptr; }, nullptr,
  };
  Registry registry;
  registry.add_plugin(&kBuiltin);
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kGood);
  EXPECT_NE(msg.find(kGood), std::string::npos) << msg;
  EXPECT_NE(msg.find("'fixture_level' is already registered (built-in)"), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
  EXPECT_EQ(registry.find_plugin("fixture_count"), nullptr);
  EXPECT_EQ(registry.find_plugin("fixture_level"), &kBuiltin);
}

TEST(PluginLoader, SameLibraryTwiceIsRefusedTheSecondTime) {
  Registry registry;
  registry.load_library(kGood);
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kGood);
  EXPECT_NE(msg.find("already registered"), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
  // The first load is untouched (the refused dlopen only dropped its own reference).
  TestHost host;
  CollectSink sink;
  auto detector = registry.create_detector("fixture_level");
  StreamInfo info;
  Params params;
  params.set("threshold", 0.5);
  detector->configure(info, params, host.ctx);
  Block b({{0.0f, 1.0f}}, 0);
  detector->process_audio(b.block, sink);
  EXPECT_EQ(sink.detections().size(), 1u);
}

TEST(PluginLoader, NullNameIsRefusedAndNothingIsAdded) {
  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::string msg = load_error(registry, kBadDescriptor);
  EXPECT_NE(msg.find(kBadDescriptor), std::string::npos) << msg;
  EXPECT_NE(msg.find("descriptor #1 has a null name"), std::string::npos) << msg;
  EXPECT_EQ(registry.plugins().size(), before);
  EXPECT_EQ(registry.find_plugin("fixture_bad_first_ok"), nullptr);
}

TEST(PluginLoader, NotASharedObjectIsRefused) {
  Registry registry;
  const std::string msg = load_error(registry, kNotElf);
  EXPECT_NE(msg.find(kNotElf), std::string::npos) << msg;
  EXPECT_NE(msg.find("cannot be loaded as a shared object"), std::string::npos) << msg;
}

TEST(PluginLoader, MissingFileIsRefused) {
  Registry registry;
  const std::string path = kPluginDir + "/does-not-exist/libnothing.so";
  const std::string msg = load_error(registry, path);
  EXPECT_EQ(msg, "plugin library " + path + ": no such file");
  const std::string dir_msg = load_error(registry, kPluginDir + "/good");
  EXPECT_NE(dir_msg.find("is a directory"), std::string::npos) << dir_msg;
}

class PluginDirectory : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "locus-plugin-dir-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path dir_;
};

TEST_F(PluginDirectory, LoadsEveryLibrarySortedAndCollectsFailures) {
  fs::copy_file(kNotElf, dir_ / "c_not_elf.so");
  fs::copy_file(kGood, dir_ / "a_good.so");
  fs::copy_file(kWrongAbi, dir_ / "b_wrong_abi.so");
  fs::copy_file(kDuplicate, dir_ / "d_duplicate.so");
  fs::copy_file(kNoEntry, dir_ / "e_no_entry.so.disabled");  // not *.so: ignored
  fs::create_directory(dir_ / "f_dir.so");                    // a directory: ignored
  {
    std::FILE* f = std::fopen((dir_ / "README.txt").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fclose(f);
  }

  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::vector<std::string> failures = registry.load_directory(dir_.string());
  ASSERT_EQ(failures.size(), 3u) << ::testing::PrintToString(failures);
  EXPECT_NE(failures[0].find((dir_ / "b_wrong_abi.so").string()), std::string::npos) << failures[0];
  EXPECT_NE(failures[0].find("ABI 999"), std::string::npos) << failures[0];
  EXPECT_NE(failures[1].find((dir_ / "c_not_elf.so").string()), std::string::npos) << failures[1];
  EXPECT_NE(failures[2].find((dir_ / "d_duplicate.so").string()), std::string::npos) << failures[2];
  EXPECT_NE(failures[2].find("already registered"), std::string::npos) << failures[2];

  EXPECT_EQ(registry.plugins().size(), before + 2);
  ASSERT_NE(entry_of(registry, "fixture_level"), nullptr);
  EXPECT_EQ(entry_of(registry, "fixture_level")->origin, (dir_ / "a_good.so").string());
  EXPECT_EQ(registry.find_plugin("fixture_dup_unique"), nullptr);
  EXPECT_EQ(registry.find_plugin("fixture_no_entry"), nullptr);
}

TEST_F(PluginDirectory, EmptyDirectoryIsFine) {
  Registry registry;
  EXPECT_TRUE(registry.load_directory(dir_.string()).empty());
}

TEST_F(PluginDirectory, WorldWritableDirectoryIsRefusedWithTheFix) {
  fs::copy_file(kGood, dir_ / "a_good.so");
  fs::permissions(dir_, fs::perms::others_write, fs::perm_options::add);
  Registry registry;
  const std::size_t before = registry.plugins().size();
  const std::vector<std::string> failures = registry.load_directory(dir_.string());
  ASSERT_EQ(failures.size(), 1u) << ::testing::PrintToString(failures);
  EXPECT_NE(failures[0].find("plugin directory " + dir_.string() + ": is world-writable"), std::string::npos)
      << failures[0];
  EXPECT_NE(failures[0].find("chmod o-w " + dir_.string()), std::string::npos) << failures[0];
  EXPECT_EQ(registry.plugins().size(), before);
  // Named directly, the library is refused for its directory too.
  const std::string msg = load_error(registry, (dir_ / "a_good.so").string());
  EXPECT_NE(msg.find("its directory " + dir_.string() + " is world-writable"), std::string::npos) << msg;
  EXPECT_EQ(registry.find_plugin("fixture_level"), nullptr);
}

TEST_F(PluginDirectory, WorldWritableLibraryIsRefused) {
  fs::copy_file(kGood, dir_ / "a_good.so");
  fs::copy_file(kGood, dir_ / "b_writable.so");
  fs::permissions(dir_ / "b_writable.so", fs::perms::others_write, fs::perm_options::add);
  Registry registry;
  const std::string msg = load_error(registry, (dir_ / "b_writable.so").string());
  EXPECT_NE(msg.find("is world-writable (mode 0"), std::string::npos) << msg;
  EXPECT_EQ(registry.find_plugin("fixture_level"), nullptr);
  // In a directory scan the writable one is a failure; the other still loads.
  const std::vector<std::string> failures = registry.load_directory(dir_.string());
  ASSERT_EQ(failures.size(), 1u) << ::testing::PrintToString(failures);
  EXPECT_NE(failures[0].find((dir_ / "b_writable.so").string()), std::string::npos) << failures[0];
  EXPECT_NE(registry.find_plugin("fixture_level"), nullptr);
}

TEST(PluginLoader, MissingDirectoryIsOneFailure) {
  Registry registry;
  const std::string dir = kPluginDir + "/no-such-directory";
  const std::vector<std::string> failures = registry.load_directory(dir);
  ASSERT_EQ(failures.size(), 1u);
  EXPECT_NE(failures[0].find(dir), std::string::npos) << failures[0];
  EXPECT_NE(failures[0].find("no such directory"), std::string::npos) << failures[0];
}

// ------------------------------------------------------------ examples/out-of-tree-plugin (clip_detector)

class ClipDetectorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    registry_.load_library(kClip);
    detector_ = registry_.create_detector("clip_detector");
    ASSERT_NE(detector_, nullptr);
  }
  void configure(double threshold, std::int64_t min_run, std::uint32_t channels) {
    StreamInfo info;
    info.device = "dev0";
    info.stream = 2;
    info.channels = channels;
    info.sample_rate_hz = 48000.0;
    Params params;
    params.set("threshold", threshold);
    params.set("min_run_samples", min_run);
    detector_->configure(info, params, host_.ctx);
  }
  Registry registry_;  // declared first: outlives the detector whose code it holds
  TestHost host_;
  CollectSink sink_;
  std::unique_ptr<Detector> detector_;
};

TEST_F(ClipDetectorTest, DeclaresItsSchema) {
  const locus_plugin_descriptor* d = registry_.find_plugin("clip_detector");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->kind, LOCUS_PLUGIN_DETECTOR);
  EXPECT_EQ(d->inputs, kInputAudio);
  const ParamSchema& schema = *d->schema();
  ASSERT_EQ(schema.size(), 2u);
  EXPECT_EQ(schema[0].key, "threshold");
  EXPECT_EQ(schema[0].type, ParamType::Float);
  EXPECT_EQ(std::get<double>(schema[0].default_value), 0.99);
  EXPECT_EQ(schema[0].min, 0.001);
  EXPECT_EQ(schema[0].max, 1.0);
  EXPECT_FALSE(schema[0].doc.empty());
  EXPECT_EQ(schema[1].key, "min_run_samples");
  EXPECT_EQ(schema[1].type, ParamType::Int);
  EXPECT_EQ(std::get<std::int64_t>(schema[1].default_value), 3);
  EXPECT_EQ(schema[1].min, 1.0);
  EXPECT_EQ(schema[1].unit, "samples");
  EXPECT_FALSE(schema[1].doc.empty());
}

TEST_F(ClipDetectorTest, ReportsRunsAcrossBlocksWithFractionalStart) {
  configure(0.9, 3, 2);
  Block b1({{0.0f, 0.1f, 0.5f, 0.7f}, {0.0f, 0.0f, 0.0f, 0.0f}}, 1000);
  Block b2({{1.0f, 1.0f, 1.0f, 0.2f}, {0.0f, -0.6f, -1.0f, -1.0f}}, 1004);
  Block b3({{0.0f, 0.95f, 0.95f, 0.0f}, {-1.0f, -1.0f, 0.0f, 0.0f}}, 1008);
  detector_->process_audio(b1.block, sink_);
  EXPECT_TRUE(sink_.events.empty());
  detector_->process_audio(b2.block, sink_);
  ASSERT_EQ(sink_.detections().size(), 1u);  // channel 0; channel 1's run is only 2 long so far
  detector_->process_audio(b3.block, sink_);
  const auto d = sink_.detections();
  ASSERT_EQ(d.size(), 2u);  // channel 0's 2-sample run in b3 is too short

  EXPECT_EQ(d[0].channel, 0);
  EXPECT_NEAR(d[0].frame, 1003.0 + (0.9 - 0.7) / (1.0 - 0.7), 1e-5);
  EXPECT_FLOAT_EQ(d[0].amplitude, 1.0f);
  EXPECT_EQ(d[0].device, std::string_view("dev0"));
  EXPECT_EQ(d[0].detector, std::string_view("inst"));
  EXPECT_EQ(d[0].stream, 2u);
  EXPECT_EQ(d[0].sample_rate_hz, 48000.0);
  EXPECT_FLOAT_EQ(d[0].confidence, 1.0f);

  EXPECT_EQ(d[1].channel, 1);
  EXPECT_NEAR(d[1].frame, 1005.75, 1e-5);  // -0.6 -> -1.0 crosses -0.9 three quarters of the way
  EXPECT_FLOAT_EQ(d[1].amplitude, 1.0f);
}

TEST_F(ClipDetectorTest, ReportsALongRunOnce) {
  configure(0.5, 2, 1);
  Block b({{0.0f, 0.6f, 0.7f, 0.8f, 0.9f, 0.6f, 0.0f, 0.5f, 0.5f}}, 0);
  detector_->process_audio(b.block, sink_);
  const auto d = sink_.detections();
  ASSERT_EQ(d.size(), 2u);
  EXPECT_NEAR(d[0].frame, 1.0 - 1.0 / 6.0, 1e-5);  // 0 -> 0.6 crosses 0.5 at 5/6
  EXPECT_FLOAT_EQ(d[0].amplitude, 0.7f);           // the peak when the run qualified
  EXPECT_NEAR(d[1].frame, 7.0, 1e-9);              // exactly at threshold: starts on the sample
}

TEST_F(ClipDetectorTest, LostFramesBreakARun) {
  configure(0.9, 3, 1);
  Block b1({{0.0f, 1.0f, 1.0f}}, 0);
  Block b2({{1.0f, 1.0f, 0.0f}}, 10, /*lost=*/7);
  detector_->process_audio(b1.block, sink_);
  detector_->process_audio(b2.block, sink_);
  EXPECT_TRUE(sink_.events.empty());
  Block b3({{1.0f, 1.0f, 1.0f}}, 20, /*lost=*/7);
  detector_->process_audio(b3.block, sink_);
  const auto d = sink_.detections();
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].frame, 20.0);  // no previous sample after a gap: the run starts on its first sample
}

}  // namespace
}  // namespace locus
