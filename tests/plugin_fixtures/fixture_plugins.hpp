// Tiny but real plugins shared by the loader fixtures (each fixture .so compiles its own copy; they
// are built with hidden visibility, so nothing but locus_plugin_enum is exported).
#pragma once

#include <locus/plugin.hpp>

#include <cmath>
#include <cstdint>
#include <vector>

namespace fixture {

using namespace locus;

/// "level": emits an AudioDetection (template 0) at each sample where |x| rises to >= threshold.
inline const ParamSchema& level_schema() {
  static const ParamSchema schema = [] {
    ParamSpec threshold;
    threshold.key = "threshold";
    threshold.type = ParamType::Float;
    threshold.default_value = 0.5;
    threshold.min = 0.0;
    threshold.max = 1.0;
    threshold.doc = "Linear magnitude that triggers a detection on a rising edge.";
    return ParamSchema{threshold};
  }();
  return schema;
}

class LevelDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    threshold_ = static_cast<float>(params.get_float("threshold"));
    device_ = info.device;
    name_ = NameTag(ctx.instance);
    rate_ = info.sample_rate_hz;
    above_.assign(info.channels, false);
  }
  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    const std::uint32_t n = block.channels < above_.size() ? block.channels : static_cast<std::uint32_t>(above_.size());
    for (std::uint32_t ch = 0; ch < n; ++ch) {
      for (std::uint32_t i = 0; i < block.frames; ++i) {
        const bool above = std::fabs(block.channel_data[ch][i]) >= threshold_;
        if (above && !above_[ch]) {
          AudioDetection d;
          d.device = device_;
          d.detector = name_;
          d.channel = static_cast<std::uint16_t>(ch);
          d.frame = static_cast<double>(block.first_frame + i);
          d.sample_rate_hz = rate_;
          d.amplitude = std::fabs(block.channel_data[ch][i]);
          d.confidence = 1.0f;
          out.emit(Event{d});
        }
        above_[ch] = above;
      }
    }
  }

 private:
  float threshold_ = 0.5f;
  DeviceId device_;
  NameTag name_;
  double rate_ = 0.0;
  std::vector<bool> above_;
};

inline const ParamSchema& empty_schema() {
  static const ParamSchema schema;
  return schema;
}

/// "count": publishes an Estimate whose confidence is 1 - 1/(n+1) after the n-th detection.
class CountLocalizer final : public Localizer {
 public:
  void configure(const Params&, HostContext& ctx) override { name_ = NameTag(ctx.instance); }
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event& event, Publisher& out) override {
    if (!std::holds_alternative<AudioDetection>(event)) return;
    ++count_;
    Estimate e;
    e.plugin = name_;
    e.target = std::get<AudioDetection>(event).device;
    e.t_s = std::get<AudioDetection>(event).frame / std::get<AudioDetection>(event).sample_rate_hz;
    e.confidence = 1.0f - 1.0f / static_cast<float>(count_ + 1);
    out.publish(Event{e});
  }

 private:
  NameTag name_;
  std::uint64_t count_ = 0;
};

/// A valid detector descriptor with the given name (abi_version overridable for the ABI fixture).
inline constexpr locus_plugin_descriptor detector_descriptor(const char* name,
                                                             std::uint32_t abi = LOCUS_PLUGIN_ABI_VERSION) {
  return locus_plugin_descriptor{
      abi,
      LOCUS_PLUGIN_DETECTOR,
      name,
      "0.0.1",
      "Test fixture: rising-edge level detector",
      kInputAudio,
      []() -> const ParamSchema* { return &level_schema(); },
      []() -> Detector* { return new LevelDetector(); },
      nullptr,
  };
}

inline constexpr locus_plugin_descriptor localizer_descriptor(const char* name) {
  return locus_plugin_descriptor{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_LOCALIZER,
      name,
      "0.0.1",
      "Test fixture: counts detections",
      0,
      []() -> const ParamSchema* { return &empty_schema(); },
      nullptr,
      []() -> Localizer* { return new CountLocalizer(); },
  };
}

}  // namespace fixture
