// The `ble_rss` plugin (see ble_rss.hpp).
#include "ble_rss.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "locus/dsp/iir.hpp"
#include "motion_common/motion_common.hpp"

namespace locus::plugins::ble_rss {

namespace {

class BleRssDetector final : public Detector {
 public:
  void configure(const StreamInfo&, const Params& p, HostContext& ctx) override {
    log_ = &ctx.log;
    grid_dt_ = 1.0 / p.get_float("grid_rate_hz");
    const double cutoff = p.get_float("lowpass_hz");
    if (cutoff >= 0.5 / grid_dt_)
      throw std::runtime_error("ble_rss: lowpass_hz (" + std::to_string(cutoff) + ") must be below half of grid_rate_hz (" +
                               std::to_string(0.5 / grid_dt_) + ")");
    const auto sos = dsp::butter_lowpass(static_cast<int>(p.get_int("lowpass_order")), cutoff, 1.0 / grid_dt_);
    timeout_s_ = p.get_float("tag_timeout_s");
    restart_gap_s_ = p.get_float("restart_gap_s");
    alpha_ = p.get_float("akf_alpha");
    alpha_r_ = p.get_float("akf_alpha_r");
    r0_ = p.get_float("measurement_var_db2");
    r_min_ = p.get_float("r_min_db2");
    q_min_ = p.get_float("q_min_db2");
    tags_.assign(static_cast<std::size_t>(p.get_int("max_tags")), Tag{});
    for (Tag& t : tags_) t.bf = dsp::SosFilter(sos);
    dropped_tags_ = dropped_events_ = 0;
  }

  void process_ble(const BleAdvertisement* adverts, std::size_t count, EventSink& out) noexcept override {
    for (std::size_t i = 0; i < count; ++i) {
      const BleAdvertisement& a = adverts[i];
      if (!std::isfinite(a.rssi_dbm) || !std::isfinite(a.t_s)) {
        ++rejected_;
        continue;
      }
      Tag* tag = find_or_claim(a);
      if (!tag) {
        ++dropped_tags_;
        continue;
      }
      BleAdvertisement f = a;
      f.rssi_dbm = static_cast<float>(filter(*tag, a.t_s, a.rssi_dbm));
      if (!out.emit(Event{f})) ++dropped_events_;
    }
  }

  void finish(EventSink&) override {
    if (!log_) return;
    if (dropped_tags_ > 0)
      log_->warn("ble_rss: " + std::to_string(dropped_tags_) + " adverts dropped: more than max_tags (" +
                 std::to_string(tags_.size()) + ") tags active at once");
    if (dropped_events_ > 0) log_->warn("ble_rss: " + std::to_string(dropped_events_) + " events dropped (queue full)");
    if (rejected_ > 0) log_->warn("ble_rss: " + std::to_string(rejected_) + " adverts with non-finite RSS or time ignored");
  }

 private:
  struct Tag {
    bool used = false;
    DeviceId device;
    std::array<std::uint8_t, 6> address{};
    dsp::SosFilter bf;
    double last_t = 0.0, last_rssi = 0.0, next_grid_t = 0.0, bf_out = 0.0, bf_prev = 0.0;
    double x = 0.0, p = 0.0, q = 0.0, r = 0.0;
  };

  Tag* find_or_claim(const BleAdvertisement& a) noexcept {
    Tag* oldest = nullptr;
    for (Tag& t : tags_) {
      if (t.used && t.address == a.address && t.device == a.device) return &t;
      if (!t.used) {
        if (!oldest || oldest->used) oldest = &t;
      } else if (a.t_s - t.last_t > timeout_s_ && (!oldest || (oldest->used && t.last_t < oldest->last_t))) {
        oldest = &t;
      }
    }
    if (!oldest) return nullptr;
    oldest->used = true;
    oldest->address = a.address;
    oldest->device = a.device;
    oldest->last_t = -1e300;  // forces a restart in filter()
    return oldest;
  }

  double filter(Tag& t, double time, double rssi) noexcept {
    const double gap = time - t.last_t;
    if (!(gap >= 0.0) || gap > restart_gap_s_) {
      t.bf.set_steady_state(rssi);
      t.bf_out = t.bf_prev = rssi;
      t.next_grid_t = time + grid_dt_;
      t.x = rssi;
      t.r = r0_;
      t.p = r0_;
      t.q = q_min_;
    } else {
      for (; t.next_grid_t <= time; t.next_grid_t += grid_dt_) {
        const double v = gap > 0 ? t.last_rssi + (rssi - t.last_rssi) * (t.next_grid_t - t.last_t) / gap : rssi;
        t.bf_out = t.bf.process_double(v);
      }
      const double u = t.bf_out - t.bf_prev;
      t.bf_prev = t.bf_out;
      const double xp = t.x + u;
      const double pp = t.p + t.q;
      const double nu = rssi - xp;
      const double k = pp / (pp + t.r);
      t.x = xp + k * nu;
      t.p = (1.0 - k) * pp;
      t.q = (1.0 - alpha_) * t.q + alpha_ * std::max(k * nu * k * nu, q_min_);
      t.r = (1.0 - alpha_r_) * t.r + alpha_r_ * std::max(nu * nu - pp, r_min_);
    }
    t.last_t = time;
    t.last_rssi = rssi;
    return t.x;
  }

  Logger* log_ = nullptr;
  std::vector<Tag> tags_;
  double grid_dt_ = 0.1, timeout_s_ = 10.0, restart_gap_s_ = 3.0;
  double alpha_ = 0.1, alpha_r_ = 0.02, r0_ = 16.0, r_min_ = 1.0, q_min_ = 0.01;
  std::uint64_t dropped_tags_ = 0, dropped_events_ = 0, rejected_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new BleRssDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = [] {
    using motion_common::append_ahrs_params;
    ParamSchema s;
    s.push_back(int_param("max_tags", std::int64_t{64}, 1, 100000, "", "Tags filtered at once (preallocated)."));
    s.push_back(float_param("grid_rate_hz", 10.0, 0.5, 200.0, "Hz", "Regular grid the RSS is resampled onto (LocBLE adverts: 10 Hz)."));
    s.push_back(float_param("lowpass_hz", 0.5, 0.01, 100.0, "Hz", "Butterworth low-pass cutoff on the grid."));
    s.push_back(int_param("lowpass_order", std::int64_t{6}, 1, 12, "", "Butterworth order (LocBLE: 6)."));
    s.push_back(float_param("tag_timeout_s", 10.0, 0.1, 86400.0, "s", "A tag silent this long frees its slot for another."));
    s.push_back(float_param("restart_gap_s", 3.0, 0.01, 86400.0, "s", "A tag silent this long restarts its filters."));
    s.push_back(float_param("akf_alpha", 0.1, 0.0, 1.0, "", "AKF adaptation rate of the process noise Q."));
    s.push_back(float_param("akf_alpha_r", 0.02, 0.0, 1.0, "", "AKF adaptation rate of the measurement noise R."));
    s.push_back(float_param("measurement_var_db2", 16.0, 0.01, 1000.0, "dB^2", "Initial RSS measurement variance R."));
    s.push_back(float_param("r_min_db2", 1.0, 0.0001, 1000.0, "dB^2", "Lower bound of R."));
    s.push_back(float_param("q_min_db2", 0.01, 0.0, 1000.0, "dB^2", "Lower bound of Q."));
    return s;
  }();
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "ble_rss", "0.1.0",
      "per-tag BLE RSS smoothing: 6th-order Butterworth + adaptive Kalman (LocBLE)", kInputBle, &schema_fn, &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::ble_rss
