// Test-only localizers for the end-to-end tests of a live node (tests/integration/live): loaded from a
// .so through `plugin_dirs:` by real `locusd` processes, so they exercise what a third-party plugin
// gets from the host of a live node: the link of the `link:` section, the publisher that feeds
// `output:` and `outputs:`, and the emitter of a device's `playback:` section.
//
//   e2e_link   role `publish`: every audio detection (channel 0) of the node becomes one link message
//              on `topic`: "<device> <frame> <sample_rate_hz>" (the frame printed exactly, %.17g).
//              role `receive`: subscribes to `topic`; every message received becomes one Estimate
//              (target = the sender's device, t_s = sender frame / rate, reference = this node's
//              device, frame "e2e"), published with the next local event this localizer gets (a
//              localizer can only publish from on_event() or finish(): the ABI gives it a Publisher
//              nowhere else), the rest at finish(). Malformed messages are counted and logged.
//   e2e_beep   schedules one emission through HostContext::emitter in configure(): `signal` (a
//              scene-format signal object) at playback frame `start_frame`; refuses to start (throws)
//              without an emitter or when schedule() fails, so a wiring bug cannot pass silently. At
//              finish() it logs the emitter's playback frame and late emissions, and publishes one
//              Estimate (target "beep", t_s = start_frame / rate, distance_m = (first own detection at
//              or after start_frame - start_frame) / rate * speed_of_sound_mps: the device's range to
//              itself through the loop; NaN when it never heard itself).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "locus/plugin.hpp"

namespace {

using namespace locus;

// ------------------------------------------------------------------ e2e_link

class E2eLink final : public Localizer {
 public:
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    link_ = &ctx.link;
    topic_ = params.get_string("topic");
    publisher_ = params.get_string("role") == "publish";
    if (!publisher_) link_->subscribe(topic_, [this](const LinkMessage& m) { on_link(m); });
  }
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event& e, Publisher& out) override {
    const auto& d = std::get<AudioDetection>(e);
    if (d.channel != 0) return;
    if (publisher_) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "%s %.17g %.17g", d.device.str().c_str(), d.frame, d.sample_rate_hz);
      link_->publish(topic_, buf);
      ++sent_;
      return;
    }
    local_device_ = d.device.str();
    publish_pending(out);
  }
  void finish(Publisher& out) override {
    if (publisher_) {
      log_->info("published " + std::to_string(sent_) + " detections on " + topic_);
      return;
    }
    publish_pending(out);
    log_->info("received " + std::to_string(received_) + " messages, published " + std::to_string(published_) +
               " estimates, " + std::to_string(malformed_) + " malformed");
    if (malformed_ > 0) log_->warn("first malformed message: '" + first_malformed_ + "'");
  }

 private:
  struct Remote {
    std::string device;
    double frame;
    double rate;
  };
  void on_link(const LinkMessage& m) {
    char device[64];
    double frame = 0.0, rate = 0.0;
    int used = 0;
    if (std::sscanf(m.payload.c_str(), "%63s %lf %lf%n", device, &frame, &rate, &used) != 3 ||
        static_cast<std::size_t>(used) != m.payload.size() || !(rate > 0.0)) {
      if (malformed_++ == 0) first_malformed_ = m.payload;
      return;
    }
    ++received_;
    pending_.push_back(Remote{device, frame, rate});
  }
  void publish_pending(Publisher& out) {
    for (const Remote& r : pending_) {
      Estimate e;
      e.plugin = "e2e_link";
      e.reference = std::string_view(local_device_);
      e.frame = "e2e";
      e.target = std::string_view(r.device);
      e.t_s = r.frame / r.rate;
      e.position_m = {r.frame, 0.0, 0.0};
      e.dims = 2;
      e.distance_m = r.frame / r.rate;
      e.confidence = 1.0f;
      out.publish(e);
      ++published_;
    }
    pending_.clear();
  }

  Logger* log_ = nullptr;
  Link* link_ = nullptr;
  std::string topic_;
  bool publisher_ = false;
  std::string local_device_;
  std::vector<Remote> pending_;
  std::uint64_t sent_ = 0, received_ = 0, published_ = 0, malformed_ = 0;
  std::string first_malformed_;
};

const ParamSchema& link_schema() {
  static const ParamSchema s = {
      enum_param("role", std::string("publish"), {"publish", "receive"},
                 "publish: send every local detection over the link; receive: turn received ones into estimates."),
      string_param("topic", std::string("e2e/detection"), "Link topic (MQTT link: <topic_prefix>/link/<topic>)."),
  };
  return s;
}

// ------------------------------------------------------------------ e2e_beep

class E2eBeep final : public Localizer {
 public:
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    emitter_ = ctx.emitter;
    start_frame_ = static_cast<std::uint64_t>(params.get_int("start_frame"));
    c_ = params.get_float("speed_of_sound_mps");
    if (emitter_ == nullptr) {
      throw std::runtime_error("e2e_beep: no emitter (HostContext::emitter is null): the node needs exactly one "
                               "device and that device a playback: section");
    }
    // The signal as the config gives it (YAML or JSON); a SignalError names the field.
    const SignalSpec signal = parse_signal(params.get_string("signal"), "e2e_beep: param 'signal'");
    std::string err;
    if (!emitter_->schedule(signal, start_frame_, params.get_float("gain"), &err)) {
      throw std::runtime_error("e2e_beep: schedule at frame " + std::to_string(start_frame_) + " refused: " + err);
    }
    log_->info("emission scheduled at playback frame " + std::to_string(start_frame_) + " (playback frame now " +
               std::to_string(emitter_->playback_frame()) + ")");
  }
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event& e, Publisher&) override {
    const auto& d = std::get<AudioDetection>(e);
    if (d.channel != 0 || heard_ || d.frame < static_cast<double>(start_frame_)) return;
    heard_ = true;
    heard_frame_ = d.frame;
  }
  void finish(Publisher& out) override {
    const double fs = emitter_->sample_rate_hz();
    log_->info("playback frame " + std::to_string(emitter_->playback_frame()) + ", late emissions " +
               std::to_string(emitter_->late_emissions()) +
               (heard_ ? ", heard at capture frame " + std::to_string(heard_frame_) : ", never heard"));
    Estimate e;
    e.plugin = "e2e_beep";
    e.frame = "e2e";
    e.target = "beep";
    e.t_s = static_cast<double>(start_frame_) / fs;
    e.distance_m = heard_ ? (heard_frame_ - static_cast<double>(start_frame_)) / fs * c_ : kNaN;
    e.confidence = heard_ ? 1.0f : 0.0f;
    out.publish(e);
  }

 private:
  Logger* log_ = nullptr;
  Emitter* emitter_ = nullptr;
  std::uint64_t start_frame_ = 0;
  double c_ = 343.0;
  bool heard_ = false;
  double heard_frame_ = 0.0;
};

const ParamSchema& beep_schema() {
  static const ParamSchema s = {
      string_param("signal",
                   std::string(R"({"type":"lfm","f0":2000,"f1":8000,"duration":0.04,"fade":0.005,"amplitude":0.5})"),
                   "Scene-format signal object to play (docs/scene-format.md)."),
      int_param("start_frame", std::int64_t{66150}, 0, 1e12, "", "Playback frame at which the emission starts."),
      float_param("gain", 1.0, 0.0, 1.0, "", "Gain of the emission (0..1)."),
      float_param("speed_of_sound_mps", 343.0, 300.0, 400.0, "m/s", "For the self-range in the final estimate."),
  };
  return s;
}

const locus_plugin_descriptor kLink{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "e2e_link", "1",
                                    "test: detections over the link between boards, back as estimates", 0,
                                    [] { return &link_schema(); }, nullptr,
                                    [] { return static_cast<Localizer*>(new E2eLink); }};
const locus_plugin_descriptor kBeep{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "e2e_beep", "1",
                                    "test: one emission through the device's emitter", 0,
                                    [] { return &beep_schema(); }, nullptr,
                                    [] { return static_cast<Localizer*>(new E2eBeep); }};

}  // namespace

LOCUS_PLUGIN_EXPORT(&kLink, &kBeep)
