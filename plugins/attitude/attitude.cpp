// The `attitude` plugin (see attitude.hpp).
#include "attitude.hpp"

#include <string>

#include "locus/dsp/ahrs.hpp"
#include "motion_common/motion_common.hpp"

namespace locus::plugins::attitude {

namespace {

class AttitudeDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device.empty() ? DeviceId(ctx.device) : info.device;
    detector_ = NameTag(ctx.instance);
    tracker_.configure(params);
    const double rate = params.get_float("output_rate_hz");
    period_s_ = rate > 0 ? 1.0 / rate : 0.0;
    next_emit_s_ = 0.0;
    dropped_ = 0;
  }

  void process_imu(const ImuSample* samples, std::size_t count, EventSink& out) noexcept override {
    for (std::size_t i = 0; i < count; ++i) {
      if (!tracker_.update(samples[i])) continue;
      const double t = samples[i].t_s;
      if (tracker_.restarted()) next_emit_s_ = t;
      if (period_s_ > 0 && t < next_emit_s_) continue;
      if (period_s_ > 0) {
        next_emit_s_ += period_s_;
        if (next_emit_s_ <= t) next_emit_s_ = t + period_s_;  // fell behind (gap): restart the grid
      }
      Attitude a;
      a.device = device_;
      a.detector = detector_;
      a.t_s = t;
      const Eigen::Quaterniond& q = tracker_.q();
      a.q_wxyz = {static_cast<float>(q.w()), static_cast<float>(q.x()), static_cast<float>(q.y()),
                  static_cast<float>(q.z())};
      a.heading_rad = static_cast<float>(dsp::heading_of(q));
      if (!out.emit(Event{a})) ++dropped_;
    }
  }

  void finish(EventSink&) override {
    if (log_ && dropped_ > 0) log_->warn("attitude: " + std::to_string(dropped_) + " events dropped (queue full)");
    if (log_ && tracker_.rejected() > 0)
      log_->warn("attitude: " + std::to_string(tracker_.rejected()) + " IMU samples with non-finite values ignored");
  }

 private:
  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  motion_common::AttitudeTracker tracker_;
  double period_s_ = 0.1;
  double next_emit_s_ = 0.0;
  std::uint64_t dropped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new AttitudeDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = [] {
    ParamSchema s;
    motion_common::append_ahrs_params(s, 0.5);
    s.push_back(float_param("output_rate_hz", 10.0, 0.0, 1000.0, "Hz",
                                    "Attitude events per second (0 = one per IMU sample)."));
    return s;
  }();
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "attitude", "0.1.0",
      "device attitude from the IMU (Madgwick or Mahony; magnetometer when present)", kInputImu, &schema_fn, &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::attitude
