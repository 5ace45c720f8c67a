// locus_load_plugin <path.so> [detector]: a minimal host for the out-of-tree packaging test.
//
// Loads one plugin library into a Registry, creates its detector (the named one, or the first
// detector it registered), configures it with its schema defaults on a 2-channel 48 kHz stream,
// feeds one synthetic block holding a clipped run on channel 1, and prints what it registered and
// every event, one per line:
//   plugin <name> <kind> <version>
//   event audio_detection channel=<c> frame=<f> amplitude=<a>
// Exit status: 0 on success, 1 on usage error, 2 if the library was refused, 4 on any other failure.
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <variant>
#include <vector>

#include "locus/registry.hpp"

namespace {

using namespace locus;

struct StderrLogger : Logger {
  void log(LogLevel, std::string_view m) override { std::fprintf(stderr, "plugin: %.*s\n", int(m.size()), m.data()); }
};
struct ZeroClock : Clock {
  double now_s() const noexcept override { return 0.0; }
};
struct NoFft : FftPlanner {
  std::unique_ptr<RealFft> plan_real(std::size_t) override {
    throw std::runtime_error("locus_load_plugin provides no FFT planner");
  }
};
struct NoLink : Link {
  void publish(std::string_view, std::string_view) override {}
  std::uint64_t subscribe(std::string_view, LinkHandler) override { return 1; }
  void unsubscribe(std::uint64_t) override {}
};
struct Collect : EventSink {
  bool emit(const Event& e) noexcept override {
    if (events.size() == events.capacity()) return false;
    events.push_back(e);
    return true;
  }
  std::vector<Event> events;
};

/// Schema defaults, built here so the driver does not depend on anything but the schema itself.
Params defaults_of(const ParamSchema& schema) {
  Params p;
  for (const ParamSpec& spec : schema) {
    if (!spec.required()) p.set(spec.key, spec.default_value);
  }
  return p;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || argc > 3) {
    std::fprintf(stderr, "usage: %s <plugin.so> [detector]\n", argv[0]);
    return 1;
  }
  Registry registry;
  std::vector<std::string> names;
  try {
    names = registry.load_library(argv[1]);
  } catch (const PluginLoadError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
  try {
    std::string detector_name = argc == 3 ? argv[2] : "";
    for (const std::string& n : names) {
      const locus_plugin_descriptor* d = registry.find_plugin(n);
      const bool is_detector = d->kind == LOCUS_PLUGIN_DETECTOR;
      std::printf("plugin %s %s %s\n", d->name, is_detector ? "detector" : "localizer", d->version);
      if (detector_name.empty() && is_detector) detector_name = n;
    }
    if (detector_name.empty()) throw std::runtime_error("the library registers no detector");
    const locus_plugin_descriptor* d = registry.find_plugin(detector_name);
    if (d == nullptr) throw std::runtime_error("no plugin named " + detector_name);

    StderrLogger log;
    ZeroClock clock;
    NoFft fft;
    NoLink link;
    HostContext ctx{log, clock, fft, link, detector_name, "synthetic"};
    Collect sink;
    sink.events.reserve(256);
    {
      std::unique_ptr<Detector> detector = registry.create_detector(detector_name);
      StreamInfo info;
      info.device = "synthetic";
      info.channels = 2;
      info.sample_rate_hz = 48000.0;
      info.max_block_frames = 256;
      detector->configure(info, defaults_of(*d->schema()), ctx);

      // Channel 0: quiet sine-ish ramp; channel 1: the same with a 20-sample run pinned at -1.0
      // starting at frame 100 (the sample before is -0.5, so the crossing of -0.99 is fractional).
      std::vector<float> ch0(256), ch1(256);
      for (std::size_t i = 0; i < ch0.size(); ++i) ch0[i] = ch1[i] = 0.25f * float(int(i % 8) - 4) / 4.0f;
      ch1[99] = -0.5f;
      for (std::size_t i = 100; i < 120; ++i) ch1[i] = -1.0f;
      const float* channels[2] = {ch0.data(), ch1.data()};
      AudioBlock block;
      block.channel_data = channels;
      block.channels = 2;
      block.frames = 256;
      block.first_frame = 0;
      detector->process_audio(block, sink);
      detector->finish(sink);
    }
    for (const Event& e : sink.events) {
      if (const auto* a = std::get_if<AudioDetection>(&e)) {
        std::printf("event audio_detection channel=%u frame=%.4f amplitude=%.3f\n", unsigned(a->channel), a->frame,
                    double(a->amplitude));
      } else {
        std::printf("event %s\n", std::string(event_type_name(type_of(e))).c_str());
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "locus_load_plugin: %s\n", e.what());
    return 4;
  }
  return 0;
}
