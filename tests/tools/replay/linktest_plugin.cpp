// `linktest`: a test-only localizer loaded from a .so by the replay integration test. It plays one of
// two roles, chosen from its params and HostContext::device, to prove that nodes of one replay talk
// over the shared link and that the shutdown phases deliver everything:
//   - on `publisher_device` it publishes every local audio detection ("<device> <frame>") on
//     linktest/detection, and at finish() the count on linktest/done;
//   - on every other device it pairs each remote detection with its own latest detection and publishes
//     an Estimate (target = the publisher, distance_m = (local - remote) / fs * c: a toy one-way range
//     that is right when both clocks start together), and at finish() a summary Estimate
//     (target "summary", position = [remote detections, local detections, done messages received]),
//     with `reference` = its device and the mic count of its geometry in std_m (checks HostContext);
//   - the publisher also reports its own geometry at finish() (target "geometry": speaker position,
//     confidence 1 when its emits hold the scene's lfm entry, mic count in std_m);
//   - every node publishes its device on linktest/ended from inputs_ended(), and the publisher reports
//     at finish() how many other nodes' such messages it had (target "ended", distance_m): the replay
//     calls every node's inputs_ended() before the first finish(), so A, which finishes first, has B's.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "locus/plugin.hpp"

namespace {

using namespace locus;

class LinkTest final : public Localizer {
 public:
  void configure(const Params& params, HostContext& ctx) override {
    device_ = std::string(ctx.device);
    publisher_ = params.get_string("publisher_device");
    c_ = params.get_float("speed_of_sound_mps");
    link_ = &ctx.link;
    geometry_ = ctx.geometry;
    mics_ = ctx.geometry != nullptr ? static_cast<int>(ctx.geometry->mic_count) : -1;
    if (device_ != publisher_) {
      link_->subscribe("linktest/#", [this](const LinkMessage& m) { on_link(m); });
    } else {
      link_->subscribe("linktest/ended", [this](const LinkMessage& m) { ended_ += m.payload != device_; });
    }
  }
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event& e, Publisher&) override {
    const auto& d = std::get<AudioDetection>(e);
    if (d.channel != 0) return;
    ++local_;
    locals_.push_back(d.frame / d.sample_rate_hz);
    if (device_ == publisher_) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "%s %.6f", device_.c_str(), d.frame / d.sample_rate_hz);
      link_->publish("linktest/detection", buf);
    }
  }
  void inputs_ended(Publisher&) override { link_->publish("linktest/ended", device_); }
  void finish(Publisher& out) override {
    if (device_ == publisher_) {
      Estimate ended;
      ended.plugin = "linktest";
      ended.reference = std::string_view(device_);
      ended.frame = "test";
      ended.target = "ended";
      ended.distance_m = ended_;
      out.publish(ended);
      link_->publish("linktest/done", std::to_string(local_));
      // What this node knows of its own geometry: the speaker position and its emits entries.
      Estimate g;
      g.plugin = "linktest";
      g.reference = std::string_view(device_);
      g.frame = "test";
      g.target = "geometry";
      g.dims = 3;
      if (geometry_ != nullptr && geometry_->has_speaker) g.position_m = geometry_->speaker_m;
      bool lfm_8k = false;
      if (geometry_ != nullptr)
        for (const SignalSpec& s : geometry_->emits) lfm_8k = lfm_8k || (s.type == "lfm" && s.f1_hz == 8000.0);
      g.confidence = lfm_8k ? 1.0f : 0.0f;
      g.std_m = mics_;
      out.publish(g);
      return;
    }
    for (double remote_s : pending_) pair(remote_s);
    for (const Estimate& e : estimates_) out.publish(e);
    Estimate s;
    s.plugin = "linktest";
    s.reference = std::string_view(device_);
    s.frame = "test";
    s.target = "summary";
    s.position_m = {static_cast<double>(remote_), static_cast<double>(local_), static_cast<double>(done_)};
    s.dims = 3;
    s.std_m = mics_;
    out.publish(s);
  }

 private:
  void on_link(const LinkMessage& m) {
    if (m.topic == "linktest/ended") return;
    if (m.topic == "linktest/done") {
      ++done_;
      return;
    }
    const auto space = m.payload.find(' ');
    if (space == std::string::npos) return;
    ++remote_;
    pending_.push_back(std::strtod(m.payload.c_str() + space + 1, nullptr));
  }
  void pair(double remote_s) {
    Estimate e;
    e.plugin = "linktest";
    e.reference = std::string_view(device_);
    e.frame = "test";
    e.target = std::string_view(publisher_);
    e.t_s = remote_s;
    e.distance_m = (nearest_local(remote_s) - remote_s) * c_;
    estimates_.push_back(e);
  }
  double nearest_local(double t) const {
    double best = 1e300;
    for (double l : locals_) best = std::abs(l - t) < std::abs(best - t) ? l : best;
    return best;
  }

  std::string device_, publisher_;
  double c_ = 343.0;
  Link* link_ = nullptr;
  const DeviceGeometry* geometry_ = nullptr;
  int mics_ = -1;
  int local_ = 0, remote_ = 0, done_ = 0, ended_ = 0;
  std::vector<double> pending_, locals_;  // paired at finish(): remote and local order is not fixed
  std::vector<Estimate> estimates_;
};

const ParamSchema& schema() {
  static const ParamSchema s = [] {
    ParamSchema out;
    ParamSpec p;
    p.key = "publisher_device";
    p.type = ParamType::String;
    p.default_value = std::string("A");
    p.doc = "Device whose instance publishes its detections; the others pair them with their own.";
    out.push_back(p);
    ParamSpec c;
    c.key = "speed_of_sound_mps";
    c.type = ParamType::Float;
    c.default_value = 343.0;
    c.min = 300.0;
    c.max = 400.0;
    c.unit = "m/s";
    c.doc = "Speed of sound for the toy range.";
    out.push_back(c);
    return out;
  }();
  return s;
}

const locus_plugin_descriptor kDescriptor{LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "linktest", "1",
                                          "test: nodes exchange detections over the link", 0,
                                          [] { return &schema(); }, nullptr,
                                          [] { return static_cast<Localizer*>(new LinkTest); }};

}  // namespace

LOCUS_PLUGIN_EXPORT(&kDescriptor)
