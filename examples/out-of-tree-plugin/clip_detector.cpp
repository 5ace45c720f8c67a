// clip_detector: an out-of-tree Locus detector plugin.
//
// Reports clipped runs: per channel, a run of at least `min_run_samples` consecutive samples with
// |x| >= `threshold` yields one AudioDetection, emitted as soon as the run is long enough. Its
// `frame` is the fractional frame where the signal crossed the threshold at the start of the run
// (linear interpolation between the last unclipped sample and the first clipped one), on the
// stream's own frame counter; `amplitude` is the largest |x| seen in the run up to that point.
//
// Everything is sized in configure(); process_audio() is real-time safe: no allocation, no lock,
// no logging, no syscall, no exception.
#include <locus/plugin.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using namespace locus;

ParamSchema make_clip_schema() {
  ParamSpec threshold;
  threshold.key = "threshold";
  threshold.type = ParamType::Float;
  threshold.default_value = 0.99;
  threshold.min = 0.001;
  threshold.max = 1.0;
  threshold.unit = "";
  threshold.doc = "Linear magnitude (full scale = 1.0) at or above which a sample counts as clipped.";

  ParamSpec min_run;
  min_run.key = "min_run_samples";
  min_run.type = ParamType::Int;
  min_run.default_value = std::int64_t{3};
  min_run.min = 1.0;
  min_run.max = 65536.0;
  min_run.unit = "samples";
  min_run.doc = "Consecutive clipped samples needed before a run is reported (once per run).";

  return {threshold, min_run};
}

/// Static storage owned by the plugin, as the descriptor's schema() requires.
const ParamSchema& clip_schema() {
  static const ParamSchema schema = make_clip_schema();
  return schema;
}

class ClipDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    threshold_ = params.get_float("threshold");
    const std::int64_t min_run = params.get_int("min_run_samples");
    if (!(threshold_ > 0.0) || min_run < 1) {
      throw std::runtime_error("clip_detector: threshold must be > 0 and min_run_samples >= 1");
    }
    if (info.channels == 0 || info.channels > 65536) {
      throw std::runtime_error("clip_detector: unsupported channel count " + std::to_string(info.channels));
    }
    min_run_ = static_cast<std::uint64_t>(min_run);
    device_ = info.device;
    detector_ = NameTag(ctx.instance);
    stream_ = info.stream;
    sample_rate_hz_ = info.sample_rate_hz;
    channels_.assign(info.channels, Channel{});
  }

  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    if (block.lost_before != 0) {
      // Frames are missing: a run cannot be continued across the gap.
      for (Channel& c : channels_) c = Channel{};
    }
    const std::size_t n = std::min<std::size_t>(block.channels, channels_.size());
    const float thr = static_cast<float>(threshold_);
    for (std::size_t ch = 0; ch < n; ++ch) {
      const float* x = block.channel_data[ch];
      if (x == nullptr) continue;
      Channel& c = channels_[ch];
      for (std::uint32_t i = 0; i < block.frames; ++i) {
        const float v = x[i];
        const float a = std::fabs(v);
        if (a >= thr) {
          if (c.run_length == 0) {
            double start = static_cast<double>(block.first_frame + i);
            if (c.have_prev) {
              // Where the line from the previous sample crosses the level on this sample's side.
              const double level = v >= 0.0f ? thr : -thr;
              const double denom = static_cast<double>(v) - static_cast<double>(c.prev);
              if (denom != 0.0) start = start - 1.0 + std::clamp((level - c.prev) / denom, 0.0, 1.0);
            }
            c.run_start = start;
            c.peak = 0.0f;
          }
          ++c.run_length;
          c.peak = std::max(c.peak, a);
          if (c.run_length == min_run_) emit(out, static_cast<std::uint16_t>(ch), c);
        } else {
          c.run_length = 0;
        }
        c.prev = v;
        c.have_prev = true;
      }
    }
  }

 private:
  struct Channel {
    std::uint64_t run_length = 0;  // consecutive clipped samples so far
    double run_start = 0.0;        // fractional frame of the current run's start
    float peak = 0.0f;             // largest |x| in the current run
    float prev = 0.0f;             // last sample seen (for the crossing interpolation)
    bool have_prev = false;
  };

  void emit(EventSink& out, std::uint16_t channel, const Channel& c) noexcept {
    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = channel;
    d.template_index = 0;
    d.frame = c.run_start;
    d.sample_rate_hz = sample_rate_hz_;
    d.snr_db = 0.0f;  // not meaningful for clipping
    d.confidence = 1.0f;
    d.amplitude = c.peak;
    out.emit(Event{d});  // a full queue drops it; the host counts drops
  }

  double threshold_ = 0.99;
  std::uint64_t min_run_ = 3;
  DeviceId device_;
  NameTag detector_;
  std::uint32_t stream_ = 0;
  double sample_rate_hz_ = 0.0;
  std::vector<Channel> channels_;
};

const locus_plugin_descriptor kClipDetector = {
    LOCUS_PLUGIN_ABI_VERSION,
    LOCUS_PLUGIN_DETECTOR,
    "clip_detector",
    "1.0.0",
    "Reports runs of clipped samples (|x| >= threshold) per channel",
    kInputAudio,
    []() -> const ParamSchema* { return &clip_schema(); },
    []() -> Detector* { return new ClipDetector(); },
    nullptr,
};

}  // namespace

LOCUS_PLUGIN_EXPORT(&kClipDetector)
