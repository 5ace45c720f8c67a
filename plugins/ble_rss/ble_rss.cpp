// The `ble_rss` plugin (see ble_rss.hpp).
#include "ble_rss.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "locus/dsp/rss_anf.hpp"
#include "motion_common/motion_common.hpp"

namespace locus::plugins::ble_rss {

namespace {

class BleRssDetector final : public Detector {
 public:
  void configure(const StreamInfo&, const Params& p, HostContext& ctx) override {
    log_ = &ctx.log;
    dsp::RssAnfOptions o;
    o.grid_rate_hz = p.get_float("grid_rate_hz");
    o.lowpass_hz = p.get_float("lowpass_hz");
    if (o.lowpass_hz >= 0.5 * o.grid_rate_hz)
      throw std::runtime_error("ble_rss: lowpass_hz (" + std::to_string(o.lowpass_hz) + ") must be below half of grid_rate_hz (" +
                               std::to_string(0.5 * o.grid_rate_hz) + ")");
    o.lowpass_order = static_cast<int>(p.get_int("lowpass_order"));
    o.restart_gap_s = p.get_float("restart_gap_s");
    o.akf_alpha = p.get_float("akf_alpha");
    o.akf_alpha_r = p.get_float("akf_alpha_r");
    o.measurement_var_db2 = p.get_float("measurement_var_db2");
    o.r_min_db2 = p.get_float("r_min_db2");
    o.q_min_db2 = p.get_float("q_min_db2");
    timeout_s_ = p.get_float("tag_timeout_s");
    const dsp::RssAnf prototype(o);
    tags_.assign(static_cast<std::size_t>(p.get_int("max_tags")), Tag{});
    for (Tag& t : tags_) t.anf = prototype;
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
      f.rssi_dbm = static_cast<float>(tag->anf.filter(a.t_s, a.rssi_dbm));
      tag->last_t = a.t_s;
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
    dsp::RssAnf anf;  // Butterworth + AKF (locus/dsp/rss_anf.hpp)
    double last_t = 0.0;
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
    oldest->last_t = a.t_s;
    oldest->anf.restart();  // a new tag in this slot starts its filters afresh
    return oldest;
  }

  Logger* log_ = nullptr;
  std::vector<Tag> tags_;
  double timeout_s_ = 10.0;
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
