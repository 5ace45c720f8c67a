// The `locble` localizer (see locble.hpp): plugin API glue around solver.hpp.
//
// Why it is shaped this way: every input is an event the host already produces (raw BLE adverts from
// BlueZ or ble.csv, steps from `steps`, headings from `attitude`), so the same config runs a replay
// and a live phone-like node. Readings are kept per tag with their time only; positions along the
// path are looked up when the estimate is computed, because a step event arrives after the step it
// measures (the detector confirms it half a step later) and the path before it is only known then.
// Estimates are published every `update_period_s` of data time for every tag with enough readings,
// and once more at the end.
#include "locble.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "locus/dsp/rss_anf.hpp"
#include "envaware.hpp"
#include "messages.hpp"
#include "solver.hpp"

namespace locus::plugins::locble {

namespace {

bool detector_matches(std::string_view got, const std::string& want, const std::string& device) {
  if (want.empty()) return true;
  return got == want || got == want + "_" + device;
}

class LocBleLocalizer final : public Localizer {
 public:
  /// [main] The link must not call a destroyed instance.
  ~LocBleLocalizer() override {
    if (link_ != nullptr && subscribed_) link_->unsubscribe(subscription_);
  }

  /// [main]
  void configure(const Params& p, HostContext& ctx) override {
    log_ = &ctx.log;
    link_ = &ctx.link;
    instance_ = std::string(ctx.instance);
    device_ = !ctx.device.empty() ? std::string(ctx.device) : p.get_string("device");
    steps_detector_ = p.get_string("steps_detector");
    attitude_detector_ = p.get_string("attitude_detector");
    stride_scale_ = p.get_float("stride_scale");
    default_stride_m_ = p.get_float("default_stride_m");
    bin_m_ = p.get_float("bin_m");
    min_readings_ = static_cast<std::size_t>(p.get_int("min_readings"));
    update_period_s_ = p.get_float("update_period_s");
    gamma_offset_db_ = p.get_float("gamma_offset_db");
    default_tx_power_dbm_ = p.get_float("default_tx_power_dbm");
    std_scale_ = p.get_float("std_scale");
    std_floor_m_ = p.get_float("std_floor_m");
    turn_rad_ = p.get_float("turn_deg") * std::numbers::pi / 180.0;
    ambiguous_mass_ = p.get_float("ambiguous_mass");
    method_ = p.get_string("method");
    point_ = p.get_string("point");
    max_tags_ = static_cast<std::size_t>(p.get_int("max_tags"));
    reg_.n_min = p.get_float("n_min");
    reg_.n_max = p.get_float("n_max");
    if (reg_.n_max < reg_.n_min)
      throw std::runtime_error("locble: n_max (" + std::to_string(reg_.n_max) + ") must be >= n_min (" +
                               std::to_string(reg_.n_min) + ")");
    PosteriorOptions po;
    po.gamma_sd_db = p.get_float("gamma_sd_db");
    po.n_mean = p.get_float("n_mean");
    po.n_sd = p.get_float("n_sd");
    po.shadowing_sd_db = p.get_float("shadowing_sd_db");
    po.fading_sd_db = p.get_float("fading_sd_db");
    po.search_radius_m = p.get_float("search_radius_m");
    po.grid_step_m = p.get_float("grid_step_m");
    po.min_distance_m = p.get_float("min_distance_m");
    if (po.grid_step_m > po.search_radius_m)
      throw std::runtime_error("locble: grid_step_m must not exceed search_radius_m");
    posterior_.emplace(po);  // validates the rest (std::invalid_argument names the field)
    adaptive_noise_ = p.get_bool("adaptive_noise");
    min_noise_ratio_ = p.get_float("min_noise_ratio");
    cluster_ = p.get_bool("clustering");
    copt_.segment = static_cast<std::size_t>(p.get_int("cluster_segment"));
    copt_.window = static_cast<std::size_t>(p.get_int("cluster_window"));
    copt_.threshold = p.get_float("cluster_threshold");
    cluster_min_speed_mps_ = p.get_float("cluster_min_speed_mps");
    cluster_min_bf_ = p.get_float("cluster_min_bayes_factor");
    cluster_grid_dt_ = 1.0 / p.get_float("cluster_rate_hz");
    anf_.grid_rate_hz = p.get_float("cluster_rate_hz");
    anf_.lowpass_hz = p.get_float("anf_lowpass_hz");
    if (anf_.lowpass_hz >= 0.5 * anf_.grid_rate_hz)
      throw std::runtime_error("locble: anf_lowpass_hz must be below half of cluster_rate_hz");
    const std::string model = p.get_string("envaware_model");
    if (model == "builtin") envaware_ = parse_envaware_model(builtin_envaware_yaml(), "builtin EnvAware model (config/locble-envaware.yaml)");
    else if (!model.empty()) envaware_ = load_envaware_model(model);  // errors name the file and the field
    const std::string topic = p.get_string("topic");
    if (!topic.empty()) {
      subscription_ = ctx.link.subscribe(topic + "/motion/+", [this](const LinkMessage& m) { on_motion(m); });
      subscribed_ = true;
    }
  }

  /// [main]
  std::vector<EventType> subscriptions() const override {
    return {EventType::BleAdvertisement, EventType::Step, EventType::Attitude};
  }

  /// [main]
  void on_event(const Event& event, Publisher& out) override {
    if (const auto* a = std::get_if<BleAdvertisement>(&event)) {
      if (device_.empty()) device_ = std::string(a->device.view());
      if (a->device.view() != device_) return;
      on_advert(*a);
      data_t_ = std::max(data_t_, a->t_s);
    } else if (const auto* s = std::get_if<Step>(&event)) {
      if (s->device.view() != device_ || !detector_matches(s->detector.view(), steps_detector_, device_)) return;
      const double stride = std::isfinite(s->stride_m) && s->stride_m > 0.0f ? s->stride_m * stride_scale_ : default_stride_m_;
      if (!dr_.add_step(s->t_s, stride, s->frequency_hz)) ++bad_steps_;
      data_t_ = std::max(data_t_, s->t_s);
    } else if (const auto* at = std::get_if<Attitude>(&event)) {
      if (at->device.view() != device_ || !detector_matches(at->detector.view(), attitude_detector_, device_)) return;
      if (!dr_.has_frame()) north_heading0_ = at->heading_rad;
      dr_.add_heading(at->t_s, at->heading_rad);
      data_t_ = std::max(data_t_, at->t_s);
    } else {
      return;
    }
    if (!next_update_t_) next_update_t_ = data_t_ + update_period_s_;
    if (data_t_ >= *next_update_t_) {
      publish_all(out, data_t_);
      *next_update_t_ = data_t_ + update_period_s_;
    }
  }

  /// [main] All inputs ended: the final estimate of every tag.
  void finish(Publisher& out) override {
    publish_all(out, data_t_);
    if (bad_steps_ > 0) log_->warn("locble: " + std::to_string(bad_steps_) + " step events out of order or invalid, ignored");
    if (bad_messages_ > 0) log_->warn("locble: " + std::to_string(bad_messages_) + " malformed motion messages ignored");
    if (dropped_tags_ > 0)
      log_->warn("locble: " + std::to_string(dropped_tags_) + " adverts of tags beyond max_tags (" + std::to_string(max_tags_) +
                 ") ignored");
    // Only an observer (a device that heard tags) misses its motion; other devices are not its business.
    if (!tags_.empty() && !dr_.has_frame())
      log_->warn("locble: " + std::to_string(tags_.size()) + " tags heard but no heading from attitude detector '" +
                 attitude_detector_ + "': no estimates");
    else if (!tags_.empty() && dr_.steps() == 0)
      log_->warn("locble: " + std::to_string(tags_.size()) + " tags heard but no steps from step detector '" +
                 steps_detector_ + "': no estimates (the observer must walk)");
    for (const auto& [addr, tag] : tags_) {
      if (!tag.last_why.empty()) log_->info("locble: " + addr + ": " + tag.last_why);
      if (envaware_ && tag.env_class >= 0)
        log_->info("locble: " + addr + ": EnvAware class " + kEnvClasses[static_cast<std::size_t>(tag.env_class)] + ", " +
                   std::to_string(tag.restarts) + " updates restarted after an environment change");
    }
  }

 private:
  struct Tag {
    std::array<std::uint8_t, 6> address{};
    std::vector<Reading> readings;
    double tx_power_dbm = 0.0;
    bool has_tx = false;
    double last_t = -1e300;
    float last_rssi = 0.0f;
    std::vector<std::array<double, 3>> motion;  ///< t, east, north (moving-target mode)
    std::optional<TagEstimate> est;
    std::string last_why;
    int env_class = -1;         ///< EnvAware class of the latest window (-1 = none / off)
    std::uint64_t restarts = 0; ///< updates that used only the readings since an environment change
    bool one_leg = false;       ///< the latest estimate used readings of one leg only
  };

  void on_advert(const BleAdvertisement& a) {
    if (!std::isfinite(a.rssi_dbm) || !std::isfinite(a.t_s)) return;
    const std::string key = format_address(a.address);
    auto it = tags_.find(key);
    if (it == tags_.end()) {
      if (tags_.size() >= max_tags_) {
        ++dropped_tags_;
        return;
      }
      it = tags_.emplace(key, Tag{}).first;
      it->second.address = a.address;
    }
    Tag& t = it->second;
    // A detector's copy of this advert (ble_rss re-emits each advert with a filtered RSS, same address
    // and time): the raw reading came first; the regression wants raw readings.
    if (a.t_s == t.last_t) return;
    t.last_t = a.t_s;
    t.last_rssi = a.rssi_dbm;
    if (a.has_tx_power && std::isfinite(a.tx_power_dbm)) {
      t.tx_power_dbm = a.tx_power_dbm;
      t.has_tx = true;
    }
    t.readings.push_back({a.t_s, a.rssi_dbm});
  }

  void on_motion(const LinkMessage& m) {
    std::string why;
    const auto msg = decode(m.payload, &why);
    if (!msg) {
      ++bad_messages_;
      log_->debug("locble: motion message ignored: " + why);
      return;
    }
    auto it = tags_.find(format_address(msg->address));
    if (it == tags_.end()) {
      if (tags_.size() >= max_tags_) return;
      it = tags_.emplace(format_address(msg->address), Tag{}).first;
      it->second.address = msg->address;
    }
    auto& mo = it->second.motion;
    if (!mo.empty() && msg->t_s <= mo.back()[0]) return;
    mo.push_back({msg->t_s, msg->east_m, msg->north_m});
  }

  /// The target's displacement at t in the observer's start frame (moving-target mode), 0 when the
  /// target reports none. North-referenced (x north, y west, locus/dsp/ahrs.hpp) → start frame.
  Vec2 target_shift(const Tag& t, double time) const {
    if (t.motion.empty()) return {0.0, 0.0};
    const auto& mo = t.motion;
    std::array<double, 3> v = mo.front();
    if (time >= mo.back()[0]) v = mo.back();
    else if (time > mo.front()[0]) {
      const auto it = std::upper_bound(mo.begin(), mo.end(), time, [](double x, const auto& e) { return x < e[0]; });
      const auto& b = *it;
      const auto& a = *(it - 1);
      const double f = (time - a[0]) / (b[0] - a[0]);
      v = {time, a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2])};
    }
    const double east = v[1], north = v[2], psi = north_heading0_;
    return {north * std::sin(psi) + east * std::cos(psi), north * std::cos(psi) - east * std::sin(psi)};
  }

  std::vector<Bin> bins_of(const Tag& t) const {
    std::vector<Vec2> pos(t.readings.size());
    std::vector<double> len(t.readings.size());
    for (std::size_t i = 0; i < t.readings.size(); ++i) {
      const double time = t.readings[i].t_s;
      pos[i] = dr_.position_at(time) - target_shift(t, time);
      len[i] = dr_.path_length_at(time);
    }
    return make_bins(t.readings, pos, len, bin_m_);
  }

  void solve(Tag& t) {
    t.est.reset();
    if (t.readings.size() < min_readings_) {
      t.last_why = std::to_string(t.readings.size()) + " readings (< min_readings " + std::to_string(min_readings_) + ")";
      return;
    }
    std::vector<Bin> bins = bins_of(t);
    if (envaware_) {
      // EnvAware (Sec. 4): classify consecutive windows; after the last change of class that held
      // for at least two windows, restart the regression on the readings since the change (when they
      // are enough: min_readings and 3 bins), as the paper starts a new regression model.
      const double w = envaware_->window_s;
      std::vector<std::pair<double, int>> cls;  // window start, class
      std::size_t i = 0;
      std::vector<double> x;
      while (i < t.readings.size()) {
        const double t0 = t.readings[i].t_s;
        x.clear();
        std::size_t j = i;
        for (; j < t.readings.size() && t.readings[j].t_s < t0 + w; ++j) x.push_back(t.readings[j].rssi_dbm);
        if (x.size() >= 4) cls.emplace_back(t0, envaware_->predict(envaware_features(x)));
        i = j;
      }
      // A single window whose class differs from two agreeing neighbours is a flicker of the
      // classifier (or a bystander crossing for a second), not an environment change: locble-105's T1
      // read LOS, pLOS, LOS over its final stand-still, and that flicker hid its real pLOS → LOS change
      // at the turn, so its mirror-prone fit mixed a 9 dB-weaker leg with the LOS one.
      for (std::size_t k = 1; k + 1 < cls.size(); ++k)
        if (cls[k - 1].second == cls[k + 1].second && cls[k].second != cls[k - 1].second) cls[k].second = cls[k - 1].second;
      t.env_class = cls.empty() ? -1 : cls.back().second;
      // The latest change whose new class held for two windows or more (a newer one-window class is
      // not a change yet, and does not hide an older change).
      for (std::size_t k = cls.size(); k-- > 1;) {
        if (cls[k].second == cls[k - 1].second || k + 2 > cls.size() || cls[k + 1].second != cls[k].second) continue;
        Tag sub = t;
        sub.readings.erase(std::remove_if(sub.readings.begin(), sub.readings.end(),
                                          [&](const Reading& r) { return r.t_s < cls[k].first; }),
                           sub.readings.end());
        if (sub.readings.size() >= min_readings_) {
          std::vector<Bin> since = bins_of(sub);
          if (since.size() >= 3) {
            bins = std::move(since);
            ++t.restarts;
          }
        }
        break;
      }
    }
    const std::optional<std::size_t> turn = dr_.turn_step(turn_rad_);
    // Readings from one leg only (no turn yet, or an EnvAware restart after it): a straight walk
    // leaves the mirror about that leg open, and a far tag's position along it too: flagged weak.
    t.one_leg = !turn || bins.front().t_s >= dr_.step_begin_s(*turn) || bins.back().t_s < dr_.step_begin_s(*turn);
    Vec2 leg_axis{0.0, 0.0};
    if (dr_.steps() > 0) leg_axis = Vec2{-std::sin(dr_.step_heading_rad(0)), std::cos(dr_.step_heading_rad(0))};
    posterior_->set_gamma_mean((t.has_tx ? t.tx_power_dbm : default_tx_power_dbm_) + gamma_offset_db_);
    // Coarse over the whole square, then fine around it; with adaptive_noise the fine solve uses the
    // noise the residuals show when the link is cleaner than configured (solver.hpp).
    TagEstimate e = posterior_->solve_coarse_to_fine(bins, leg_axis, adaptive_noise_, min_noise_ratio_);
    if (!e.ok) {
      t.last_why = e.why;
      return;
    }
    if (point_ == "map" && method_ == "posterior") {
      // The most probable cell; the std is the posterior's spread about it (E|x - map|²), so a ring or
      // a flat tail that pulls the mean towards the square's centre widens it instead.
      const Vec2 d = e.map_m - e.position_m;
      e.cov_m2 += d * d.transpose();
      e.std_m = std::sqrt(std::max(0.0, e.cov_m2.trace()));
      e.position_m = e.map_m;
    }
    if (method_ == "regression") {
      // The paper's estimator: Eq. 2-5 on both legs, mirror resolved by the L (Sec. 5.1); without a
      // turn yet, the joint fit. The posterior still gives std and confidence.
      std::optional<Vec2> p;
      if (turn) {
        const double t_turn = dr_.step_begin_s(*turn);
        std::vector<std::size_t> l1, l2;
        for (std::size_t i = 0; i < bins.size(); ++i) (bins[i].t_s < t_turn ? l1 : l2).push_back(i);
        p = l_shape(bins, l1, l2, reg_);
      }
      if (!p && bins.size() >= 5) {
        std::vector<Vec2> o;
        std::vector<double> r;
        for (const Bin& b : bins) {
          o.push_back(b.observer_m);
          r.push_back(b.rssi_dbm);
        }
        const RegressionFit f = elliptical_regression(o, r, reg_);
        if (f.ok) p = f.position_m;
      }
      if (!p) {
        t.last_why = "Eq. 2-5 has no solution on these readings (method: regression)";
        return;
      }
      e.position_m = *p;
    }
    t.last_why.clear();
    t.est = e;
  }

  void publish_all(Publisher& out, double now) {
    if (!dr_.has_frame() || dr_.steps() == 0) return;
    for (auto& [key, t] : tags_) solve(t);
    if (cluster_) calibrate_clusters();
    char frame[32];
    std::snprintf(frame, sizeof frame, "observer_start@%.6f", dr_.frame_time_s());
    const Vec2 here = dr_.position_at(now);
    for (auto& [key, t] : tags_) {
      if (!t.est) continue;
      const TagEstimate& e = *t.est;
      Estimate est;
      est.plugin.assign(instance_);
      est.reference.assign(device_);
      est.frame.assign(frame);
      est.target.assign(key);
      est.t_s = now;
      // Moving target: the fit gives where it started (p_i = b_i − a_i); it is now that plus its motion.
      const Vec2 where = e.position_m + target_shift(t, now);
      est.position_m = {where.x(), where.y(), kNaN};
      est.dims = 2;
      const double sd = std::hypot(e.std_m * std_scale_, std_floor_m_);
      est.std_m = sd;
      // Guidance: from where the observer is now (same frame), the bearing and the distance to walk.
      const Vec2 v = where - here;
      est.distance_m = v.norm();
      est.direction_rad = std::atan2(v.y(), v.x());
      est.distance_std_m = sd / std::numbers::sqrt2;
      est.direction_std_rad = est.distance_m > 0.0 ? std::min(std::numbers::pi, est.distance_std_m / est.distance_m) : kNaN;
      est.confidence = static_cast<float>(std::clamp(e.confidence, 0.0, 1.0));
      if (e.mirror_mass > ambiguous_mass_) est.flags |= kEstimateAmbiguous;
      if (t.one_leg || e.bins < 4) est.flags |= kEstimateWeak;
      out.publish(est);
    }
  }

  /// Sec. 6, Algo. 2: tags whose RSS traces move together (DTW voting) are one cluster; each member's
  /// position becomes the confidence-weighted mean of the cluster's.
  void calibrate_clusters() {
    std::vector<Tag*> ts;
    for (auto& [k, t] : tags_)
      if (t.est) ts.push_back(&t);
    if (ts.size() < 2) return;
    double t0 = 1e300, t1 = -1e300;
    for (const Tag* t : ts) {
      t0 = std::min(t0, t->readings.front().t_s);
      t1 = std::max(t1, t->readings.back().t_s);
    }
    const std::size_t n = static_cast<std::size_t>((t1 - t0) / cluster_grid_dt_) + 1;
    if (n < copt_.segment + 1) return;
    // Each trace through the paper's ANF (Butterworth + adaptive Kalman, locus/dsp/rss_anf.hpp, the
    // filter of the ble_rss detector), then on a common grid by linear interpolation between packets
    // (NaN outside a tag's span and across gaps longer than 1 s).
    std::vector<std::vector<float>> traces(ts.size(), std::vector<float>(n, std::numeric_limits<float>::quiet_NaN()));
    // Only what was heard while the observer walked is compared: standing still (before the walk,
    // after it, at the turn) every tag's trace is flat, so those segments match for any two tags and
    // outvote the walk (locble-105: 4 s before and 7 s after a 6 s walk fused tags 9 m apart). The
    // paper's premise is the walk: "such a pattern becomes unique in geometry" (Sec. 6.1).
    std::vector<char> walking(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      const double t = t0 + static_cast<double>(i) * cluster_grid_dt_;
      walking[i] = dr_.path_length_at(t + 0.5) - dr_.path_length_at(t - 0.5) >= cluster_min_speed_mps_;
    }
    for (std::size_t k = 0; k < ts.size(); ++k) {
      dsp::RssAnf anf(anf_);
      std::vector<double> ft, fv;
      for (const Reading& r : ts[k]->readings) {
        ft.push_back(r.t_s);
        anf.filter(r.t_s, r.rssi_dbm);
        fv.push_back(anf.lowpass_db());  // the smooth (Butterworth) part: the AKF output keeps fading
      }
      std::size_t j = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const double t = t0 + static_cast<double>(i) * cluster_grid_dt_;
        while (j + 1 < ft.size() && ft[j + 1] < t) ++j;
        if (!walking[i] || j + 1 >= ft.size() || t < ft[j] || ft[j + 1] - ft[j] > 1.0) continue;
        const double f = (t - ft[j]) / std::max(ft[j + 1] - ft[j], 1e-9);
        traces[k][i] = static_cast<float>(fv[j] + f * (fv[j + 1] - fv[j]));
      }
    }
    std::vector<Vec2> fused(ts.size());
    auto member = cluster_matrix(traces, copt_);
    // Traces that move together are not enough: in a world of per-link shadowing and per-link
    // environment changes, the DTW costs of tags metres apart have the same distribution as those of
    // tags 0.3-1 m apart (docs/locble.md, "Clustering"), so on their own they fuse distinct tags
    // (locble-105: T2, 9 m from T1, dragged onto it). A pair is one cluster only when their position
    // posteriors also favour one place: Bayes factor of co-location >= cluster_min_bayes_factor.
    for (std::size_t a = 0; a < ts.size(); ++a)
      for (std::size_t b = a + 1; b < ts.size(); ++b)
        if (member[a][b] && !(colocation_bayes_factor(ts[a]->est->grid, ts[b]->est->grid) >= cluster_min_bf_))
          member[a][b] = member[b][a] = false;
    for (std::size_t k = 0; k < ts.size(); ++k) {
      std::vector<Vec2> pos{ts[k]->est->position_m};
      std::vector<double> w{std::max(ts[k]->est->confidence, 1e-9)};
      for (std::size_t j = 0; j < ts.size(); ++j)
        if (j != k && member[k][j]) {
          pos.push_back(ts[j]->est->position_m);
          w.push_back(std::max(ts[j]->est->confidence, 1e-9));
        }
      fused[k] = fuse(pos, w);
    }
    for (std::size_t k = 0; k < ts.size(); ++k) ts[k]->est->position_m = fused[k];
  }

  Logger* log_ = nullptr;
  Link* link_ = nullptr;
  bool subscribed_ = false;
  std::uint64_t subscription_ = 0;
  std::string instance_, device_, steps_detector_, attitude_detector_, method_, point_;
  double stride_scale_ = 1.0, default_stride_m_ = 0.7, bin_m_ = 0.5, update_period_s_ = 1.0;
  double gamma_offset_db_ = 0.0, default_tx_power_dbm_ = -59.0, std_scale_ = 1.0, std_floor_m_ = 0.0;
  double turn_rad_ = 0.8, ambiguous_mass_ = 0.3, north_heading0_ = 0.0, cluster_grid_dt_ = 0.1;
  std::size_t min_readings_ = 10, max_tags_ = 64;
  std::uint64_t bad_steps_ = 0, bad_messages_ = 0, dropped_tags_ = 0;
  RegressionOptions reg_;
  ClusterOptions copt_;
  dsp::RssAnfOptions anf_;
  bool cluster_ = false;
  double cluster_min_speed_mps_ = 0.2, cluster_min_bf_ = 3.0;
  std::optional<PositionPosterior> posterior_;
  std::optional<EnvAwareModel> envaware_;
  double min_noise_ratio_ = 0.1;
  bool adaptive_noise_ = true;
  DeadReckoning dr_;
  std::map<std::string, Tag> tags_;
  double data_t_ = -1e300;
  std::optional<double> next_update_t_;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema{
      string_param("device", "", "Observer device when the host gives none (\"\" = the first device whose BLE adverts arrive)."),
      string_param("steps_detector", "steps", "Step events of this detector instance (or <name>_<device>) move the observer."),
      string_param("attitude_detector", "attitude", "Attitude events of this instance (or <name>_<device>) give its heading."),
      float_param("stride_scale", 1.0, 0.1, 5.0, "", "Multiplies every detected stride (calibration of the step detector's model)."),
      float_param("default_stride_m", 0.7, 0.1, 2.0, "m", "Stride used when a step event carries none."),
      enum_param("point", "mean", {"mean", "map"},
                 "The published point of the posterior (method posterior): its mean, or its most probable cell "
                 "(std then about that cell)."),
      enum_param("method", "posterior", {"posterior", "regression"},
                 "posterior: the grid posterior mean (solver.hpp); regression: the paper's Eq. 2-5 with the L-shape mirror choice."),
      float_param("bin_m", 0.5, 0.05, 10.0, "m", "Readings within this much walked distance form one measurement bin."),
      int_param("min_readings", std::int64_t{10}, 2, 100000, "", "A tag is located once it has this many readings."),
      float_param("update_period_s", 1.0, 0.05, 3600.0, "s", "Estimates are published every this much data time (and at the end)."),
      float_param("default_tx_power_dbm", -59.0, -120.0, 20.0, "dBm", "RSS at 1 m assumed for adverts without a TX power field."),
      float_param("gamma_offset_db", 0.0, -30.0, 30.0, "dB", "Added to the advertised 1 m power: prior mean of Γ (receiver offset)."),
      float_param("gamma_sd_db", 6.0, 0.1, 50.0, "dB", "Prior 1-sigma of Γ around that mean."),
      float_param("n_mean", 2.3, 1.0, 6.0, "", "Prior mean of the fading coefficient n."),
      float_param("n_sd", 0.5, 0.01, 5.0, "", "Prior 1-sigma of n."),
      float_param("n_min", 1.5, 0.5, 6.0, "", "Eq. 5 search range of n: lowest (method regression)."),
      float_param("n_max", 5.0, 0.5, 10.0, "", "Eq. 5 search range of n: highest (method regression)."),
      float_param("shadowing_sd_db", 3.0, 0.0, 30.0, "dB", "Shadowing 1-sigma per bin (correlated along the walk)."),
      float_param("fading_sd_db", 6.0, 0.0, 30.0, "dB", "Fading 1-sigma per reading (independent)."),
      bool_param("adaptive_noise", true, "Solve again with the noise scaled down when the residuals show a cleaner link."),
      float_param("min_noise_ratio", 0.1, 0.01, 1.0, "", "Lowest scaling of the configured noise (adaptive_noise)."),
      float_param("search_radius_m", 20.0, 1.0, 200.0, "m", "Half size of the square searched around the walk."),
      float_param("grid_step_m", 1.0, 0.05, 10.0, "m", "Posterior grid step (refined 4x around concentrated posteriors)."),
      float_param("min_distance_m", 0.5, 0.01, 10.0, "m", "Distances below this count as this (near field)."),
      float_param("std_scale", 1.0, 0.1, 10.0, "", "Multiplies the posterior std (calibration against measured errors, docs/locble.md)."),
      float_param("std_floor_m", 0.0, 0.0, 100.0, "m", "Added in quadrature to every reported std."),
      float_param("turn_deg", 45.0, 5.0, 180.0, "deg", "A heading change of this much after the first step starts the second leg."),
      float_param("ambiguous_mass", 0.3, 0.0, 1.0, "", "Posterior mass across the first leg's line above which the estimate is flagged ambiguous."),
      int_param("max_tags", std::int64_t{64}, 1, 100000, "", "Tags tracked at once; adverts of more are counted and ignored."),
      bool_param("clustering", false, "Sec. 6 calibration: fuse the estimates of tags whose RSS traces match (DTW voting)."),
      int_param("cluster_segment", std::int64_t{10}, 2, 1000, "", "DTW segment length in grid points (paper: 10)."),
      int_param("cluster_window", std::int64_t{2}, 0, 1000, "", "DTW warping band in grid points."),
      float_param("cluster_threshold", 6.1, 0.0, 1e6, "dB^2", "LB_Keogh and DTW threshold per segment (paper: 6.1)."),
      float_param("cluster_min_bayes_factor", 3.0, 0.0, 1e9, "",
                  "DTW-matched tags fuse only when their position posteriors favour one place by this Bayes factor (0 = DTW alone, the paper)."),
      float_param("cluster_min_speed_mps", 0.2, 0.0, 10.0, "m/s",
                  "DTW compares only trace points where the observer walked at least this fast (over 1 s); 0 = every point."),
      float_param("cluster_rate_hz", 10.0, 0.5, 100.0, "Hz", "Grid the RSS traces are filtered and compared on (DTW)."),
      float_param("anf_lowpass_hz", 0.5, 0.01, 50.0, "Hz", "Butterworth cutoff of the ANF the traces go through (ble_rss default)."),
      string_param("envaware_model", "",
                   "EnvAware model: builtin (config/locble-envaware.yaml as built), a file written by locus train locble (relative to the working directory), or \"\" = off."),
      string_param("topic", "locble", "Link topic prefix of moving targets' motion (<topic>/motion/<address>); \"\" = none."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "locble", "0.1.0",
      "LocBLE: BLE tags located from RSS along the observer's L-shaped walk (paper 003)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new LocBleLocalizer); }};
  return &d;
}

}  // namespace locus::plugins::locble
