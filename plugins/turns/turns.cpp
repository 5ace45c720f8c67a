// The `turns` plugin (see turns.hpp).
#include "turns.hpp"

#include <cmath>
#include <string>

#include "locus/dsp/ahrs.hpp"
#include "motion_common/motion_common.hpp"

namespace locus::plugins::turns {

namespace {

class TurnsDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& p, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device.empty() ? DeviceId(ctx.device) : info.device;
    detector_ = NameTag(ctx.instance);
    tracker_.configure(p);
    smoothing_s_ = p.get_float("smoothing_s");
    start_rate_ = p.get_float("start_rate_radps");
    end_rate_ = p.get_float("end_rate_radps");
    if (end_rate_ >= start_rate_)
      throw std::runtime_error("turns: end_rate_radps (" + std::to_string(end_rate_) +
                               ") must be below start_rate_radps (" + std::to_string(start_rate_) + ")");
    hold_s_ = p.get_float("hold_s");
    min_turn_ = p.get_float("min_turn_rad");
    max_turn_s_ = p.get_float("max_turn_s");
    dropped_ = 0;
    turning_ = false;
  }

  void process_imu(const ImuSample* samples, std::size_t count, EventSink& out) noexcept override {
    for (std::size_t i = 0; i < count; ++i) {
      const ImuSample& s = samples[i];
      if (!tracker_.update(s)) continue;
      const Eigen::Vector3d g(s.gyro_radps[0], s.gyro_radps[1], s.gyro_radps[2]);
      const double wz = (tracker_.q() * g).z();
      const double t = s.t_s;
      if (tracker_.restarted()) {
        smoothed_ = wz;
        turning_ = false;
        acc_ = 0.0;
        calm_t_ = t;
        continue;
      }
      const double dt = tracker_.dt_s();
      smoothed_ += (1.0 - std::exp(-dt / smoothing_s_)) * (wz - smoothed_);
      acc_ += wz * dt;
      const double mag = std::abs(smoothed_);
      if (!turning_) {
        if (mag < end_rate_) {
          acc_ = 0.0;
          calm_t_ = t;
        } else if (mag > start_rate_) {
          turning_ = true;
          quiet_ = false;
          start_t_ = calm_t_;
        }
        continue;
      }
      if (mag < end_rate_) {
        if (!quiet_) {
          quiet_ = true;
          quiet_t_ = t;
          acc_end_ = acc_;
          q_end_ = tracker_.q();
        }
        if (t - quiet_t_ >= hold_s_) {
          if (std::abs(acc_end_) >= min_turn_ && quiet_t_ - start_t_ <= max_turn_s_) emit(out);
          turning_ = false;
          acc_ = 0.0;
          calm_t_ = t;
        }
      } else {
        quiet_ = false;
        if (t - start_t_ > max_turn_s_ * 2.0) {  // spinning or shaking, not a turn: start over
          turning_ = false;
          acc_ = 0.0;
          calm_t_ = t;
        }
      }
    }
  }

  void finish(EventSink& out) override {
    if (turning_ && quiet_ && std::abs(acc_end_) >= min_turn_ && quiet_t_ - start_t_ <= max_turn_s_) emit(out);
    turning_ = false;
    if (log_ && dropped_ > 0) log_->warn("turns: " + std::to_string(dropped_) + " events dropped (queue full)");
  }

 private:
  void emit(EventSink& out) noexcept {
    Attitude a;
    a.device = device_;
    a.detector = detector_;
    a.t_s = quiet_t_;
    a.q_wxyz = {static_cast<float>(std::cos(0.5 * acc_end_)), 0.0f, 0.0f, static_cast<float>(std::sin(0.5 * acc_end_))};
    a.heading_rad = static_cast<float>(dsp::heading_of(q_end_));
    if (!out.emit(Event{a})) ++dropped_;
  }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  motion_common::AttitudeTracker tracker_;
  double smoothing_s_ = 0.3, start_rate_ = 0.5, end_rate_ = 0.15, hold_s_ = 0.2, min_turn_ = 0.5, max_turn_s_ = 5.0;
  double smoothed_ = 0.0, acc_ = 0.0, acc_end_ = 0.0;
  double calm_t_ = 0.0, start_t_ = 0.0, quiet_t_ = 0.0;
  bool turning_ = false, quiet_ = false;
  Eigen::Quaterniond q_end_ = Eigen::Quaterniond::Identity();
  std::uint64_t dropped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new TurnsDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = [] {
    using motion_common::append_ahrs_params;
    ParamSchema s;
    s.push_back(float_param("smoothing_s", 0.3, 0.0001, 10.0, "s", "Time constant of the yaw-rate low-pass (step sway)."));
    s.push_back(float_param("start_rate_radps", 0.5, 0.01, 20.0, "rad/s", "A turn starts above this smoothed yaw rate."));
    s.push_back(float_param("end_rate_radps", 0.15, 0.001, 20.0, "rad/s", "A turn ends below this smoothed yaw rate."));
    s.push_back(float_param("hold_s", 0.2, 0.0, 10.0, "s", "The yaw rate must stay below the end rate this long."));
    s.push_back(float_param("min_turn_rad", 0.5, 0.0, 10.0, "rad", "Smallest reported turn (0.5 rad = 29 deg)."));
    s.push_back(float_param("max_turn_s", 5.0, 0.1, 60.0, "s", "Longest turn; longer rotations are not reported."));
    append_ahrs_params(s, 0.5);
    return s;
  }();
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "turns", "0.1.0",
      "walking turns from the world-frame yaw rate (LocBLE gyro bump), as Attitude events", kInputImu, &schema_fn,
      &create, nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::turns
