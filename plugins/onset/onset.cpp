// The `onset` energy-onset detector; the algorithm and its bias are documented in onset.hpp.
#include "onset.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace locus::plugins::onset {

namespace {

class OnsetDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device;
    detector_ = NameTag(ctx.instance);
    stream_ = info.stream;
    rate_ = info.sample_rate_hz;
    if (!(rate_ > 0)) throw std::runtime_error("onset: sample rate must be > 0");
    if (info.channels == 0) throw std::runtime_error("onset: the stream has no channels");
    channels_ = info.channels;

    const double threshold_db = params.get_float("threshold_db");
    const double window_s = params.get_float("window_s");
    const double floor_tc_s = params.get_float("floor_time_constant_s");
    const double hold_off_s = params.get_float("hold_off_s");
    const double k = params.get_float("onset_k");
    const double gap_s = params.get_float("onset_gap_s");
    const double lookback_s = params.get_float("lookback_s");
    const double warmup_s = params.get_float("warmup_s");
    const double min_floor_dbfs = params.get_float("min_floor_dbfs");
    if (!(window_s > 0) || !(floor_tc_s > 0)) throw std::runtime_error("onset: window_s and floor_time_constant_s must be > 0");
    if (floor_tc_s <= window_s)
      throw std::runtime_error("onset: floor_time_constant_s (" + std::to_string(floor_tc_s) +
                               " s) must be longer than window_s (" + std::to_string(window_s) + " s)");

    threshold_db_ = threshold_db;
    threshold_ = std::pow(10.0, threshold_db / 10.0);
    alpha_ = 1.0 - std::exp(-1.0 / (window_s * rate_));
    beta_ = 1.0 - std::exp(-1.0 / (floor_tc_s * rate_));
    k_ = k;
    min_floor_ = std::pow(10.0, min_floor_dbfs / 10.0);
    hold_frames_ = static_cast<std::uint64_t>(std::llround(std::max(0.0, hold_off_s) * rate_));
    gap_frames_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(gap_s * rate_)));
    lookback_frames_ = std::max<std::uint64_t>(gap_frames_ + 2, static_cast<std::uint64_t>(std::llround(lookback_s * rate_)));
    warmup_frames_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(warmup_s * rate_)));
    hist_size_ = std::bit_ceil(static_cast<std::size_t>(lookback_frames_ + 1));
    hist_mask_ = hist_size_ - 1;

    chans_.assign(channels_, Channel{});
    hist_.assign(hist_size_ * channels_, 0.0f);
    dropped_ = 0;
  }

  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    const std::uint32_t nch = std::min(block.channels, channels_);
    if (block.lost_before > 0) {
      for (std::uint32_t c = 0; c < channels_; ++c) {
        Channel& ch = chans_[c];
        if (ch.pending) emit(c, out);
        const double floor = ch.floor;
        const std::uint64_t floor_n = ch.floor_n;
        ch = Channel{};
        ch.floor = floor;
        ch.floor_n = floor_n;
        ch.e = std::max(floor, min_floor_);
      }
    }
    for (std::uint32_t i = 0; i < block.frames; ++i) {
      const std::uint64_t frame = block.first_frame + i;
      for (std::uint32_t c = 0; c < nch; ++c) step(c, block.channel_data[c][i], frame, out);
    }
  }

  void finish(EventSink& out) override {
    for (std::uint32_t c = 0; c < channels_; ++c)
      if (chans_[c].pending) emit(c, out);
    if (dropped_ > 0 && log_)
      log_->warn("onset: " + std::to_string(dropped_) + " detections dropped (event queue full)");
  }

 private:
  struct Channel {
    double e = 0.0;             // short-term energy
    double floor = 0.0;         // noise power estimate
    std::uint64_t floor_n = 0;  // samples the floor has seen (warm-up)
    std::uint64_t seen = 0;     // contiguous samples since start/reset (history validity)
    std::uint64_t hold_until = 0;  // `seen` index until which the event holds off
    bool armed = true;
    bool pending = false;
    double onset_frame = 0.0;
    double peak_e = 0.0;
    float peak_abs = 0.0f;
    double floor_at_trigger = 0.0;
  };

  void step(std::uint32_t c, float x, std::uint64_t frame, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    float* hist = &hist_[static_cast<std::size_t>(c) * hist_size_];
    const double x2 = static_cast<double>(x) * static_cast<double>(x);
    ch.e += alpha_ * (x2 - ch.e);
    const std::uint64_t s = ch.seen;
    hist[s & hist_mask_] = x;
    const double floor = std::max(ch.floor, min_floor_);
    const double level = threshold_ * floor;

    if (ch.armed) {
      if (ch.floor_n >= warmup_frames_ && ch.e > level) trigger(ch, hist, s, frame, floor);
    } else {
      if (ch.pending) {
        ch.peak_e = std::max(ch.peak_e, ch.e);
        ch.peak_abs = std::max(ch.peak_abs, std::fabs(x));
        if (ch.e < level || s >= ch.hold_until) emit(c, out);
      }
      if (!ch.pending && s >= ch.hold_until && ch.e < level) ch.armed = true;
    }
    // The floor tracks only while no event is in progress.
    if (!ch.pending && s >= ch.hold_until) {
      const double b = std::max(beta_, 1.0 / static_cast<double>(ch.floor_n + 1));
      ch.floor += b * (x2 - ch.floor);
      ++ch.floor_n;
    }
    ch.seen = s + 1;
  }

  void trigger(Channel& ch, const float* hist, std::uint64_t s, std::uint64_t frame, double floor) noexcept {
    const double kthr = k_ * std::sqrt(floor);
    const std::uint64_t max_back = std::min<std::uint64_t>(s, lookback_frames_);  // history holds s+1 samples
    std::uint64_t earliest = 0;  // j of the earliest sample above kthr (valid when found)
    bool found = false;
    std::uint64_t below = 0;
    float peak = 0.0f;
    for (std::uint64_t j = 0; j <= max_back; ++j) {
      const float a = std::fabs(hist[(s - j) & hist_mask_]);
      if (a > kthr) {
        earliest = j;
        found = true;
        below = 0;
        peak = std::max(peak, a);
      } else if (++below >= gap_frames_ && found) {
        break;
      }
    }
    double onset = static_cast<double>(frame);
    if (found) {
      const double f1 = static_cast<double>(frame - earliest);
      const double a1 = std::fabs(hist[(s - earliest) & hist_mask_]);
      onset = f1;
      if (earliest < s && earliest < lookback_frames_) {  // the sample before it is in the history
        const double a0 = std::fabs(hist[(s - earliest - 1) & hist_mask_]);
        if (a1 > a0) onset = f1 - 1.0 + std::clamp((kthr - a0) / (a1 - a0), 0.0, 1.0);
      }
    }
    ch.armed = false;
    ch.pending = true;
    ch.onset_frame = onset;
    ch.peak_e = ch.e;
    ch.peak_abs = peak;
    ch.floor_at_trigger = floor;
    // Hold off from the onset on (in `seen` units: the onset lies `frame - onset` samples back).
    const auto back = static_cast<std::uint64_t>(std::max(0.0, std::floor(static_cast<double>(frame) - onset)));
    ch.hold_until = s - std::min(back, s) + hold_frames_;
  }

  void emit(std::uint32_t c, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    ch.pending = false;
    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = static_cast<std::uint16_t>(c);
    d.template_index = 0;
    d.frame = ch.onset_frame;
    d.sample_rate_hz = rate_;
    const double snr_db = 10.0 * std::log10(std::max(ch.peak_e, 1e-300) / ch.floor_at_trigger);
    d.snr_db = static_cast<float>(snr_db);
    d.confidence = static_cast<float>(std::clamp(1.0 - std::pow(10.0, -(snr_db - threshold_db_) / 10.0), 0.0, 1.0));
    d.amplitude = ch.peak_abs;
    if (!out.emit(Event{d})) ++dropped_;
  }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  std::uint32_t stream_ = 0;
  std::uint32_t channels_ = 0;
  double rate_ = 44100.0;
  double threshold_db_ = 12.0;
  double threshold_ = 1.0;
  double alpha_ = 0.0;
  double beta_ = 0.0;
  double k_ = 4.0;
  double min_floor_ = 0.0;
  std::uint64_t hold_frames_ = 0;
  std::uint64_t gap_frames_ = 1;
  std::uint64_t lookback_frames_ = 1;
  std::uint64_t warmup_frames_ = 1;
  std::size_t hist_size_ = 0;
  std::size_t hist_mask_ = 0;
  std::vector<Channel> chans_;
  std::vector<float> hist_;  // channels * hist_size_, a ring per channel indexed by `seen`
  std::uint64_t dropped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new OnsetDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = {
      float_param("threshold_db", 12.0, 1.0, 80.0, "dB", "Trigger when the short-term energy exceeds the noise floor by this."),
      float_param("window_s", 0.002, 1e-5, 1.0, "s", "Time constant of the one-pole short-term energy."),
      float_param("floor_time_constant_s", 1.0, 1e-3, 3600.0, "s",
            "Time constant of the noise-floor tracker (tracks only while no event is in progress)."),
      float_param("hold_off_s", 0.1, 0.0, 3600.0, "s", "After an onset, no new detection on that channel for this long."),
      float_param("onset_k", 4.0, 1.0, 1000.0, "",
            "Onset = first sample whose |x| exceeds onset_k noise RMS (linear interpolation between samples)."),
      float_param("onset_gap_s", 0.0002, 1e-6, 1.0, "s",
            "A run of samples this long below onset_k noise RMS ends the walk back to the onset."),
      float_param("lookback_s", 0.05, 1e-4, 10.0, "s", "How far back from the trigger the onset may lie."),
      float_param("warmup_s", 0.05, 0.0, 3600.0, "s", "Noise floor learnt for this long before the first trigger."),
      float_param("min_floor_dbfs", -120.0, -400.0, 0.0, "dB",
            "Lower bound of the noise floor (power, dBFS), so digital silence has a finite floor."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_DETECTOR,
      "onset",
      "0.1.0",
      "energy onset per channel: short-term energy over a tracked noise floor, sample-accurate onset",
      kInputAudio,
      &schema_fn,
      &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::onset
