// The `tum` localizer: exchange bookkeeping, link plumbing, estimates. See tum.hpp for the design and
// docs/tum.md for the user's view; the maths lives in solver.cpp and tracker.cpp.
#include "tum.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "locus/dsp/signals.hpp"
#include "locus/emitter.hpp"
#include "locus/scene/pose.hpp"
#include "messages.hpp"
#include "network.hpp"
#include "solver.hpp"
#include "sync.hpp"
#include "tracker.hpp"
#include "locus/numbers.hpp"

namespace locus::plugins::tum {

namespace {

constexpr double kNaNd = std::numeric_limits<double>::quiet_NaN();

struct Detection {
  double t_s = 0.0;
  int tone = 0;  ///< 1 or 2
  std::uint32_t channel = 0;
  float snr_db = 0.0f;
};

struct RemoteDevice {
  std::vector<DeviceExchange> exchanges;
  std::vector<Stamp> stamps;
  std::optional<double> offset_s;    ///< its clock minus device 1's, once aligned
  std::deque<double> recent_offsets;
  std::size_t aligned_at = 0;        ///< device 1's exchange count at the last pairing search
  std::size_t aligned_dev_at = 0;    ///< its own exchange count then
  int undecided = 0;                 ///< searches before the first pairing that decided nothing (too few or ambiguous)
};

DeviceExchange to_exchange(const ObsMessage& m) {
  DeviceExchange d;
  d.id = m.device;
  for (const auto& v : m.mics_m) d.mics.emplace_back(v[0], v[1], v[2]);
  if (m.speaker_m) d.speaker = Eigen::Vector3d((*m.speaker_m)[0], (*m.speaker_m)[1], (*m.speaker_m)[2]);
  if (m.q_wxyz) d.attitude = Eigen::Quaterniond((*m.q_wxyz)[0], (*m.q_wxyz)[1], (*m.q_wxyz)[2], (*m.q_wxyz)[3]).normalized();
  d.moving = m.moving;
  if (m.gyro_radps) d.gyro_radps = Eigen::Vector3d((*m.gyro_radps)[0], (*m.gyro_radps)[1], (*m.gyro_radps)[2]);
  d.t1_s = m.t1_s;
  d.t2_s = m.t2_s;
  return d;
}

class TumLocalizer final : public Localizer {
 public:
  ~TumLocalizer() override {
    if (link_ != nullptr) link_->unsubscribe(subscription_);
  }

  /// [main]
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    link_ = &ctx.link;
    clock_ = &ctx.clock;
    emitter_ = ctx.emitter;
    instance_ = std::string(ctx.instance);
    device_ = !ctx.device.empty() ? std::string(ctx.device) : params.get_string("device");
    prefix_ = params.get_string("topic");
    if (prefix_.empty() || prefix_.find_first_of("+#") != std::string::npos || prefix_.back() == '/')
      throw std::runtime_error("tum: param 'topic': expected a non-empty topic prefix without '+', '#' or a trailing '/', got '" +
                               prefix_ + "'");
    detector_ = params.get_string("detector");
    pair_window_s_ = params.get_float("pair_window_s");
    cfg_.speed_of_sound_mps = params.get_float("speed_of_sound_mps");
    calibrate_c_ = cfg_.speed_of_sound_mps == 0.0;
    if (calibrate_c_) cfg_.speed_of_sound_mps = 343.2;
    cfg_.timing_std_s = params.get_float("timing_std_s");
    cfg_.attitude_std_rad = params.get_float("attitude_std_rad");
    cfg_.max_range_m = params.get_float("max_range_m");
    max_spread_m_ = params.get_float("max_spread_m");
    motion_gyro_radps_ = params.get_float("motion_gyro_radps");
    tracker_cfg_.filter = params.get_string("filter") == "particle";
    tracker_cfg_.particles = static_cast<int>(params.get_int("particles"));
    tracker_cfg_.outlier_jump_m = params.get_float("outlier_jump_m");
    tracker_cfg_.moving_speed_mps = params.get_float("moving_speed_mps");
    net_cfg_.window = static_cast<int>(params.get_int("window"));
    net_cfg_.yaw_prior_rad = params.get_float("yaw_prior_rad");
    net_cfg_.height_prior_m = params.get_float("height_prior_m");
    net_cfg_.moving_height_candidates_m = params.get_float("moving_height_candidates_m");
    net_cfg_.still_yaw_prior_rad = params.get_float("still_yaw_prior_rad");
    net_cfg_.speed_mps = tracker_cfg_.moving_speed_mps;
    net_cfg_.outlier_m = tracker_cfg_.outlier_jump_m;
    std_floor_m_ = params.get_float("std_floor_m");
    pairing_tolerance_s_ = params.get_float("pairing_tolerance_s");
    debug_ = params.get_bool("log_fixes");

    // Geometry of this device (from the scene on replay, from the config's geometry on a node).
    if (ctx.geometry != nullptr) {
      for (std::uint32_t k = 0; k < ctx.geometry->mic_count; ++k) mics_.push_back(ctx.geometry->mics_m[k]);
      if (ctx.geometry->has_speaker) speaker_ = ctx.geometry->speaker_m;
    }

    // The working pair and the template index of each tone: the scene's distinct lfm signals in scene
    // order, as the chirp detector numbers them with `from_scene`.
    std::string w1 = params.get_string("device1"), w2 = params.get_string("device2");
    template1_ = static_cast<int>(params.get_int("template1"));
    template2_ = static_cast<int>(params.get_int("template2"));
    if (ctx.geometry != nullptr && !ctx.geometry->scene_emits.empty()) {
      std::vector<const SignalSpec*> lfms;
      std::vector<std::string> emitters;  // emitters of lfm signals, scene order, distinct
      for (const SceneSignal& s : ctx.geometry->scene_emits) {
        if (s.signal.type != "lfm") continue;
        int index = -1;
        for (std::size_t t = 0; t < lfms.size(); ++t) {
          const SignalSpec& o = *lfms[t];
          if (o.f0_hz == s.signal.f0_hz && o.f1_hz == s.signal.f1_hz && o.duration_s == s.signal.duration_s &&
              o.fade_s == s.signal.fade_s)
            index = static_cast<int>(t);
        }
        if (index < 0) {
          index = static_cast<int>(lfms.size());
          lfms.push_back(&s.signal);
        }
        if (std::find(emitters.begin(), emitters.end(), s.id) == emitters.end()) {
          emitters.push_back(s.id);
          template_of_[s.id] = index;
        }
      }
      if (w1.empty() && emitters.size() >= 1) w1 = emitters[0];
      if (w2.empty() && emitters.size() >= 2) w2 = emitters[1];
      if (template_of_.count(w1)) template1_ = template_of_[w1];
      if (template_of_.count(w2)) template2_ = template_of_[w2];
      if (template1_ < static_cast<int>(lfms.size())) scene_tone1_ = *lfms[static_cast<std::size_t>(template1_)];
      if (template2_ < static_cast<int>(lfms.size())) scene_tone2_ = *lfms[static_cast<std::size_t>(template2_)];
    }
    configure_live(params);
    net_cfg_.exchange_motion = params.get_bool("exchange_motion");
    if (net_cfg_.exchange_motion) {
      // Both tones are lfm (the sample rate only matters for gold signals).
      const SignalSpec& t1 = scene_tone1_ ? *scene_tone1_ : tone1_;
      const SignalSpec& t2 = scene_tone2_ ? *scene_tone2_ : tone2_;
      net_cfg_.doppler_instant1_s = dsp::doppler_timing_instant_s(t1, 48000.0);
      net_cfg_.doppler_instant2_s = dsp::doppler_timing_instant_s(t2, 48000.0);
    }
    if (live_ && w1.empty() && w2.empty()) {
      // the working devices are elected on the link (docs/tum.md, "Live roles")
    } else if (w1.empty() || w2.empty() || w1 == w2)
      throw std::runtime_error("tum: cannot tell the two working devices: the scene declares " +
                               std::string(w1.empty() ? "no" : "one") +
                               " emitting device; set params device1 and device2 (and template1, template2)");
    if (template1_ == template2_)
      throw std::runtime_error("tum: the working devices " + w1 + " and " + w2 +
                               " emit the same signal; TUM needs two distinguishable tones (docs/tum.md)");
    device1_ = w1;
    device2_ = w2;
    reporter_ = !device1_.empty() && device_ == device1_;
    if (live_ && !device1_.empty()) {  // fixed roles: announced by device 1 once the clocks are synchronised
      fixed_roles_ = true;
    }

    subscription_ = ctx.link.subscribe(topic_filter(prefix_), [this](const LinkMessage& m) { on_message(m); });
  }

  /// [main]
  std::vector<EventType> subscriptions() const override {
    return {EventType::AudioDetection, EventType::Attitude, EventType::ImuSample};
  }

  /// [main]
  void on_event(const Event& event, Publisher& out) override {
    if (const auto* d = std::get_if<AudioDetection>(&event)) {
      if (d->device.view() != device_ || !(d->sample_rate_hz > 0)) return;
      if (!detector_.empty() && d->detector.view() != detector_ && d->detector.view() != detector_ + "_" + device_) return;
      const int tone = d->template_index == template1_ ? 1 : d->template_index == template2_ ? 2 : 0;
      if (tone == 0 || d->channel >= mics_.size()) return;
      const double t = d->frame / d->sample_rate_hz;
      audio_t_ = std::max(audio_t_, t);
      close_exchanges(horizon());
      pending_.push_back(Detection{t, tone, d->channel, d->snr_db});
    } else if (const auto* a = std::get_if<Attitude>(&event)) {
      if (a->device.view() != device_) return;
      attitudes_.push_back({a->t_s, {a->q_wxyz[0], a->q_wxyz[1], a->q_wxyz[2], a->q_wxyz[3]}});
      while (attitudes_.size() > 256) attitudes_.pop_front();
      attitude_t_ = std::max(attitude_t_, a->t_s);
      close_exchanges(horizon());
    } else if (const auto* s = std::get_if<ImuSample>(&event)) {
      if (s->device.view() != device_) return;
      const double g = std::sqrt(double(s->gyro_radps[0]) * s->gyro_radps[0] + double(s->gyro_radps[1]) * s->gyro_radps[1] +
                                 double(s->gyro_radps[2]) * s->gyro_radps[2]);
      motion_.push_back({s->t_s, g > motion_gyro_radps_, {s->gyro_radps[0], s->gyro_radps[1], s->gyro_radps[2]}});
      while (motion_.size() > 4096) motion_.pop_front();
      imu_t_ = std::max(imu_t_, s->t_s);
      close_exchanges(horizon());
    }
    if (live_) live_tick();
    if (reporter_) process(out, false);
  }

  /// [main] All inputs ended: the exchanges still open go to the reporter before any node finishes.
  void inputs_ended(Publisher& /*out*/) override { close_exchanges(kInf); }

  /// [main] All inputs ended, every node's last exchange delivered.
  void finish(Publisher& out) override {
    if (live_) log_live_summary();
    close_exchanges(kInf);
    if (reporter_) {
      process(out, true);
      if (network_ && network_->restarts() > 0)
        log_->info("tum: " + std::to_string(network_->restarts()) + " window restarts (Sec. VIII: the window disagreed with an exchange)");
      log_->info("tum: " + device_ + ": " + std::to_string(solved_) + " exchanges solved, " + std::to_string(failed_) +
                 " not (" + first_failure_ + "), " + std::to_string(published_) + " estimates");
      for (const auto& [id, r] : remote_)
        if (!r.offset_s && id != device_)
          log_->warn("tum: the exchanges of " + id + " never paired with " + device1_ + "'s (" +
                     std::to_string(r.exchanges.size()) + " heard): it is not located");
    }
    if (bad_messages_ > 0)
      log_->warn("tum: " + std::to_string(bad_messages_) + " malformed link messages ignored (first: " + first_bad_ + ")");
    if (mics_.size() < 2) log_->warn("tum: " + device_ + " has fewer than 2 microphones in its geometry: it cannot be located");
  }

 private:
  struct AttitudeAt {
    double t_s;
    std::array<double, 4> q;
  };
  struct MotionAt {
    double t_s;
    bool moving;
    std::array<double, 3> gyro_radps;
  };

  /// The local time up to which every input stream of this device has been seen: detections, attitude
  /// events and IMU samples arrive interleaved in an order that varies from run to run, and an
  /// exchange takes the attitude and the motion flag around its time, so it closes only once each
  /// stream that has spoken has passed it (a stream never seen does not hold it back).
  double horizon() const {
    double h = audio_t_;
    if (attitude_t_ > -kInf) h = std::min(h, attitude_t_);
    if (imu_t_ > -kInf) h = std::min(h, imu_t_);
    return h;
  }

  /// The attitude at local time t: interpolated between the events around it (scene::bracket) when
  /// they are less than 0.25 s apart, else the nearest within 1 s; none when
  /// there is none. The attitude events of one device arrive in time order.
  std::optional<std::array<double, 4>> attitude_at(double t) const {
    if (attitudes_.empty()) return std::nullopt;
    const scene::TimeBracket b = scene::bracket(attitudes_.size(), t, [&](std::size_t i) { return attitudes_[i].t_s; });
    const AttitudeAt& lo = attitudes_[b.lo];
    const AttitudeAt& hi = attitudes_[b.hi];
    if (b.hi != b.lo && hi.t_s - lo.t_s < 0.25) {
      // Normalised lerp, the shorter way. Eigen's slerp (scene::interpolate_attitude) differs by
      // ~1e-6 rad over 50 ms, and yet moved ellipse seed 6 into a wrong formation (docs/tum.md
      // "Limits": some seeds' basin choice is that fragile), so the measured figures keep this one.
      const double sgn = (lo.q[0] * hi.q[0] + lo.q[1] * hi.q[1] + lo.q[2] * hi.q[2] + lo.q[3] * hi.q[3]) < 0.0 ? -1.0 : 1.0;
      std::array<double, 4> q{};
      double n2 = 0.0;
      for (std::size_t i = 0; i < 4; ++i) {
        q[i] = (1.0 - b.u) * lo.q[i] + b.u * sgn * hi.q[i];
        n2 += q[i] * q[i];
      }
      for (double& v : q) v /= std::sqrt(n2);
      return q;
    }
    const AttitudeAt& nearest = std::abs(lo.t_s - t) <= std::abs(hi.t_s - t) ? lo : hi;
    if (std::abs(nearest.t_s - t) < 1.0) return nearest.q;
    return std::nullopt;
  }

  /// The gyro's body-frame rate at local time t: the mean of its samples within 25 ms (the nearest
  /// within 0.1 s when none); none without an IMU.
  std::optional<Vec3a> gyro_at(double t) const {
    Vec3a sum{0.0, 0.0, 0.0};
    int n = 0;
    const MotionAt* nearest = nullptr;
    for (const auto& mo : motion_) {
      if (std::abs(mo.t_s - t) <= 0.025) {
        for (std::size_t i = 0; i < 3; ++i) sum[i] += mo.gyro_radps[i];
        ++n;
      }
      if (!nearest || std::abs(mo.t_s - t) < std::abs(nearest->t_s - t)) nearest = &mo;
    }
    if (n > 0) return Vec3a{sum[0] / n, sum[1] / n, sum[2] / n};
    if (nearest && std::abs(nearest->t_s - t) < 0.1) return nearest->gyro_radps;
    return std::nullopt;
  }

  /// Publishes every exchange whose window has closed by local time `now`.
  void close_exchanges(double now) {
    std::sort(pending_.begin(), pending_.end(), [](const Detection& a, const Detection& b) { return a.t_s < b.t_s; });
    while (!pending_.empty() && now > pending_.front().t_s + pair_window_s_) {
      const double start = pending_.front().t_s;
      auto end = std::find_if(pending_.begin(), pending_.end(), [&](const Detection& d) { return d.t_s > start + pair_window_s_; });
      ObsMessage m;
      m.device = device_;
      m.seq = seq_++;
      for (const auto& v : mics_) m.mics_m.push_back(v);
      m.speaker_m = speaker_;
      m.t1_s.assign(mics_.size(), kNaNd);
      m.t2_s.assign(mics_.size(), kNaNd);
      std::vector<float> snr1(mics_.size(), -1e9f), snr2(mics_.size(), -1e9f);
      for (auto it = pending_.begin(); it != end; ++it) {
        auto& t = it->tone == 1 ? m.t1_s : m.t2_s;
        auto& s = it->tone == 1 ? snr1 : snr2;
        if (it->snr_db > s[it->channel]) s[it->channel] = it->snr_db, t[it->channel] = it->t_s;
      }
      // The exchange's reference instant: this device's hearing of device 1's tone (the window solve
      // places a moving device there and corrects its other arrivals by its motion, network.hpp).
      double ref = reference_time_s(m.t1_s);
      if (!std::isfinite(ref)) ref = start;
      m.q_wxyz = attitude_at(ref);
      m.gyro_radps = gyro_at(ref);
      // Moving: the gyro saw rotation since the previous exchange (or in the last second).
      const double since = std::max(last_exchange_s_, start - 1.0);
      for (const auto& mo : motion_)
        if (mo.t_s > since && mo.t_s <= start + pair_window_s_ && mo.moving) m.moving = true;
      last_exchange_s_ = start;
      pending_.erase(pending_.begin(), end);
      if (mics_.size() >= 2) link_->publish(topic_obs(prefix_, device_), encode(m));
    }
  }

  /// [main] Link handler: every instance's exchanges (only the reporter, or every instance while the
  /// roles are not elected yet, keeps them) and, live, the sync and role messages.
  void on_message(const LinkMessage& msg) {
    if (msg.topic.rfind(prefix_ + "/obs/", 0) != 0) {
      if (live_) on_sync_message(msg);
      else if (bad_messages_++ == 0) first_bad_ = msg.topic + ": not a TUM observation (a live node's sync message on a replay?)";
      return;
    }
    if (!reporter_ && !(live_ && device1_.empty())) return;
    Decoded d = decode(prefix_, msg.topic, msg.payload);
    if (!d.obs) {
      if (bad_messages_++ == 0) first_bad_ = msg.topic + ": " + d.error;
      return;
    }
    RemoteDevice& r = remote_[d.obs->device];
    DeviceExchange ex = to_exchange(*d.obs);
    r.stamps.push_back(stamp_of(ex));
    r.exchanges.push_back(std::move(ex));
    // Devices in id order, not in the order their first message happened to arrive: the window solve
    // places the monitors one after another, so an arrival order that varies from run to run (the
    // link is asynchronous) would make a replay's result vary with it.
    auto at = std::lower_bound(order_.begin(), order_.end(), d.obs->device);
    if (at == order_.end() || *at != d.obs->device) order_.insert(at, d.obs->device);
  }

  double interval_tolerance_s() const { return 2.0 * max_spread_m_ / cfg_.speed_of_sound_mps + 0.002; }

  /// Solves the reporter's exchanges whose partners have all arrived (or `final`).
  void process(Publisher& out, bool final) {
    auto self = remote_.find(device1_);
    auto second = remote_.find(device2_);
    if (self == remote_.end() || second == remote_.end()) return;
    RemoteDevice& ref = self->second;
    // Between exchanges the apparent offset (device tone-1 time minus device 1's) changes only by the
    // devices' motion over the propagation (a few ms at walking speed), while a wrong pairing is off by
    // a round period plus the random speaker latencies: a tight tolerance tells them apart.
    const double tol = pairing_tolerance_s_;
    // Clock pairing: first after kAlignAfter exchanges, and only when the best offset beats every other
    // round's by a margin (a device whose exchanges lag device 1's by one pairs as many under a
    // one-period shift when the intervals do not tell the rounds apart); then again every kAlignAfter
    // exchanges over the latest ones, switching when another offset pairs clearly more of them.
    constexpr std::size_t kAlignAfter = 6, kAlignSpan = 30;
    for (auto& [id, r] : remote_) {
      if (id == device1_) continue;
      const std::size_t n = std::min(ref.stamps.size(), r.stamps.size());
      if (n == 0 || (!final && ref.stamps.size() < kAlignAfter)) continue;
      if (r.offset_s) {
        if (ref.stamps.size() < r.aligned_at + kAlignAfter && !final) continue;
        if (final && ref.stamps.size() == r.aligned_at) continue;
      } else if (ref.stamps.size() == r.aligned_at && r.stamps.size() == r.aligned_dev_at) {
        continue;  // undecided: searched again once either side has another exchange
      }
      const std::vector<Stamp> rs(ref.stamps.end() - static_cast<std::ptrdiff_t>(std::min(ref.stamps.size(), kAlignSpan)), ref.stamps.end());
      const std::vector<Stamp> ds(r.stamps.end() - static_cast<std::ptrdiff_t>(std::min(r.stamps.size(), kAlignSpan)), r.stamps.end());
      const int m = static_cast<int>(std::min(rs.size(), ds.size()));
      const int need = std::max(2, m / 2);
      const ClockPairing p = align_clocks(rs, ds, tol, interval_tolerance_s(), need, std::max(2, need / 2));
      r.aligned_at = ref.stamps.size();
      r.aligned_dev_at = r.stamps.size();
      if (!p.offset_s) {
        if (!r.offset_s) ++r.undecided;
        continue;
      }
      if (r.offset_s && std::abs(*p.offset_s - *r.offset_s) < tol) continue;  // the same offset
      const int current = r.offset_s ? count_pairs(rs, ds, *r.offset_s, tol, interval_tolerance_s()) : 0;
      if (!r.offset_s || (p.pairs > current + 2 && 2 * p.pairs > m)) {
        if (r.offset_s) log_->info("tum: " + id + ": clock pairing moved to another offset (" + std::to_string(p.pairs) + " vs " +
                                   std::to_string(current) + " exchanges agree)");
        r.offset_s = p.offset_s;
        r.recent_offsets.clear();
      }
    }
    while (next_ < ref.exchanges.size()) {
      const Stamp& rs = ref.stamps[next_];
      const double t_ref = std::isfinite(rs.t1) ? rs.t1 : rs.t2;
      std::vector<DeviceExchange> devs{ref.exchanges[next_]};
      std::vector<std::string> ids{device1_};
      bool wait = false;
      std::vector<std::string> order{device2_};
      for (const auto& id : order_)
        if (id != device1_ && id != device2_) order.push_back(id);
      for (const auto& id : order) {
        RemoteDevice& r = remote_[id];
        if (!r.offset_s) {
          // On replay a device heard from but not yet paired is waited for (the end flushes): whether
          // its pairing is decided before this exchange is solved must not depend on how fast the
          // asynchronous link delivered its messages, or one scene gives different results run to
          // run. Live, only device 2 is waited for (a monitor must not stall the output).
          if (!final && (id == device2_ || !live_)) wait = true;
          if (id == device2_) break;
          continue;
        }
        const int j = match_stamp(rs, r.stamps, *r.offset_s, tol, interval_tolerance_s());
        if (j >= 0) {
          devs.push_back(r.exchanges[static_cast<std::size_t>(j)]);
          ids.push_back(id);
          const Stamp& ds = r.stamps[static_cast<std::size_t>(j)];
          const double o = std::isfinite(ds.t1) && std::isfinite(rs.t1) ? ds.t1 - rs.t1 : ds.t2 - rs.t2;
          r.recent_offsets.push_back(o);
          while (r.recent_offsets.size() > 9) r.recent_offsets.pop_front();
          std::vector<double> s(r.recent_offsets.begin(), r.recent_offsets.end());
          std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
          r.offset_s = s[s.size() / 2];  // follows clock drift
        } else if (!final) {
          const double last = r.stamps.empty() ? -kInf : std::isfinite(r.stamps.back().t1) ? r.stamps.back().t1 : r.stamps.back().t2;
          if (last < t_ref + *r.offset_s + 2.0 * tol) wait = true;  // may still come
        }
        if (id == device2_ && devs.size() < 2) break;
      }
      if (wait) return;
      ++next_;
      if (devs.size() < 2 || devs[1].id != device2_) {
        note_failure(device2_ + " did not hear exchange " + std::to_string(next_ - 1));
        continue;
      }
      solve_and_publish(devs, out);
    }
  }

  // ------------------------------------------------------------------ live roles (docs/tum.md)

  /// [main] Live when the node has an emitter (locusd with a `playback:` section): the sync, the
  /// election and the emissions run; on a replay (no emitter) the scene holds what was played.
  void configure_live(const Params& params) {
    live_ = emitter_ != nullptr;
    sync_period_s_ = params.get_float("sync_period_s");
    sync_samples_ = static_cast<int>(params.get_int("sync_samples"));
    sync_min_samples_ = static_cast<int>(params.get_int("sync_min_samples"));
    elect_devices_ = static_cast<std::size_t>(params.get_int("elect_devices"));
    elect_tie_s_ = params.get_float("elect_tie_s");
    elect_order_.clear();
    for (std::size_t b = 0, e; b <= params.get_string("elect_order").size(); b = e + 1) {
      const std::string& list = params.get_string("elect_order");
      e = std::min(list.find(',', b), list.size());
      std::string id = list.substr(b, e - b);
      id.erase(0, id.find_first_not_of(' '));
      id.erase(id.find_last_not_of(' ') + 1);
      if (!id.empty()) elect_order_.push_back(id);
    }
    exchange_period_s_ = params.get_float("exchange_period_s");
    tone_delay_s_ = params.get_float("tone_delay_s");
    tone_jitter_s_ = params.get_float("tone_jitter_s");
    tone_gain_ = params.get_float("tone_gain");
    schedule_ahead_s_ = params.get_float("schedule_ahead_s");
    start_delay_s_ = params.get_float("start_delay_s");
    SignalSpec up;
    up.type = "lfm";
    up.f0_hz = params.get_float("tone_f0_hz");
    up.f1_hz = params.get_float("tone_f1_hz");
    up.duration_s = params.get_float("tone_duration_s");
    up.fade_s = params.get_float("tone_fade_s");
    up.amplitude = 1.0;
    SignalSpec down = up;
    std::swap(down.f0_hz, down.f1_hz);
    tone1_ = up;
    tone2_ = down;
    if (live_ && up.f0_hz == up.f1_hz) throw std::runtime_error("tum: params tone_f0_hz and tone_f1_hz must differ (an up and a down chirp)");
    if (live_ && 2.0 * up.fade_s > up.duration_s) throw std::runtime_error("tum: param tone_fade_s must be at most half of tone_duration_s");
    can_work_ = live_ && speaker_.has_value() && mics_.size() >= 2;
  }

  /// [main] Live housekeeping, on every event and link message (the IMU's 100 Hz keeps it going).
  void live_tick() {
    const double now = clock_->now_s();
    if (now >= next_ping_s_) {
      next_ping_s_ = now + sync_period_s_;
      link_->publish(topic_ping(prefix_, device_), encode(Ping{device_, ping_seq_++, now}));
      publish_table();
      if (role_ && role_->election.device1 == device_ && now >= next_role_s_) {  // late joiners hear it too
        next_role_s_ = now + 2.0;
        link_->publish(topic_role(prefix_), encode(*role_));
      }
    }
    if (!role_) try_elect(now);
    if (role_) schedule_emissions(now);
  }

  void publish_table() {
    SyncTable t;
    t.device = device_;
    t.can_work = can_work_;
    for (const auto& [id, trips] : trips_)
      if (auto e = estimate_clock(trips, 1, sync_samples_)) t.peers[id] = *e;
    link_->publish(topic_table(prefix_, device_), encode(t));
  }

  void on_sync_message(const LinkMessage& msg) {
    const double now = clock_->now_s();
    SyncDecoded d = decode_sync(prefix_, msg.topic, msg.payload);
    if (!d.error.empty()) {
      if (bad_messages_++ == 0) first_bad_ = msg.topic + ": " + d.error;
      return;
    }
    if (d.ping && d.ping->from != device_) {
      link_->publish(topic_pong(prefix_, d.ping->from), encode(Pong{device_, d.ping->from, d.ping->seq, d.ping->t0_s, now, now}));
    } else if (d.pong && d.pong->to == device_ && d.pong->from != device_) {
      auto& trips = trips_[d.pong->from];
      trips.push_back(RoundTrip{d.pong->t0_s, d.pong->t1_s, d.pong->t2_s, now});
      if (trips.size() > static_cast<std::size_t>(4 * sync_samples_)) trips.erase(trips.begin());
    } else if (d.table) {
      tables_[d.table->device] = *d.table;
    } else if (d.role) {
      adopt(*d.role, now);
    }
    live_tick();
  }

  /// The clock estimate of `peer` (its clock minus ours), once enough round trips are in.
  std::optional<ClockEstimate> clock_of(const std::string& peer) const {
    auto it = trips_.find(peer);
    if (it == trips_.end()) return std::nullopt;
    return estimate_clock(it->second, sync_min_samples_, sync_samples_);
  }

  /// Elects once `elect_devices` devices have reported every other of them with enough round trips; the
  /// elected device 1 announces the roles (t0 on its clock); every node adopts the first announcement.
  void try_elect(double now) {
    std::vector<SyncTable> tables;
    for (const auto& [id, t] : tables_) tables.push_back(t);
    if (tables.size() < std::max<std::size_t>(2, elect_devices_)) return;
    for (const SyncTable& t : tables)
      for (const SyncTable& o : tables) {
        if (o.device == t.device) continue;
        auto f = t.peers.find(o.device);
        if (f == t.peers.end() || f->second.samples < sync_min_samples_) return;
      }
    std::optional<Election> e;
    if (fixed_roles_) e = Election{device1_, device2_, 0.0};
    else e = elect(tables, elect_tie_s_, elect_order_);
    if (!e) {
      if (!warned_no_pair_) log_->warn("tum: no pair of devices can work (a speaker, an emitter and two mics each): no election");
      warned_no_pair_ = true;
      return;
    }
    if (e->device1 != device_) return;  // device 1 announces
    if (!fixed_roles_) {
      auto t1 = std::find_if(tables.begin(), tables.end(), [&](const SyncTable& t) { return t.device == e->device1; });
      auto f = t1->peers.find(e->device2);
      if (f != t1->peers.end()) e->rtt_s = f->second.rtt_s;
    }
    Role r{*e, now + start_delay_s_, exchange_period_s_, tone_delay_s_};
    link_->publish(topic_role(prefix_), encode(r));
    adopt(r, now);
  }

  void adopt(const Role& r, double now) {
    if (role_) {
      if (r.election.device1 != role_->election.device1 || r.election.device2 != role_->election.device2 || r.t0_s != role_->t0_s)
        if (conflicting_roles_++ == 0)
          log_->warn("tum: another role announcement (" + r.election.device1 + ", " + r.election.device2 + ") after (" +
                     role_->election.device1 + ", " + role_->election.device2 + "): the first one stays");
      return;
    }
    role_ = r;
    device1_ = r.election.device1;
    device2_ = r.election.device2;
    reporter_ = device_ == device1_;
    if (!reporter_) {
      remote_.clear();
      order_.clear();
    }
    log_->info("tum: working devices " + device1_ + " and " + device2_ + " (RTT " + std::to_string(r.election.rtt_s * 1e3) +
               " ms); exchanges every " + std::to_string(r.period_s) + " s from " + std::to_string(r.t0_s) + " s on " + device1_ +
               "'s clock" + (reporter_ ? "; this node solves" : ""));
    if (device_ == device1_ || device_ == device2_) {
      anchor_s_ = now;
      anchor_frame_ = emitter_->playback_frame();
    }
  }

  /// Working devices: schedule the next emissions within `schedule_ahead_s` through the emitter.
  void schedule_emissions(double now) {
    const bool one = device_ == device1_, two = device_ == device2_;
    if (!one && !two) return;
    double offset = 0.0;  // device 1's clock minus ours
    if (two) {
      const auto c = clock_of(device1_);
      if (!c) return;  // not yet: device 2 needs device 1's clock
      offset = c->offset_s;
      if (!emitting_) device2_offset_ = *c;
    }
    if (!emitting_) {
      emitting_ = true;
      next_k_ = next_emission_index(role_->t0_s, role_->period_s, now + offset + 0.05);
    }
    const double fs = emitter_->sample_rate_hz();
    const std::uint64_t pf = emitter_->playback_frame();
    const SignalSpec& tone = one ? tone1_ : tone2_;
    for (;;) {
      const double t = role_->t0_s + static_cast<double>(next_k_) * role_->period_s +
                       (two ? tone2_delay_s(role_->delay_s, tone_jitter_s_, next_k_) : 0.0);
      const std::int64_t f = frame_for(t, offset, anchor_s_, anchor_frame_, fs);
      if (f > static_cast<std::int64_t>(pf) + static_cast<std::int64_t>(schedule_ahead_s_ * fs)) break;
      ++next_k_;
      if (f <= static_cast<std::int64_t>(pf)) {
        ++emissions_missed_;  // its frame has been played already (the node was busy)
        continue;
      }
      std::string err;
      if (emitter_->schedule(tone, static_cast<std::uint64_t>(f), tone_gain_, &err)) {
        ++emissions_;
      } else if (emit_failures_++ == 0) {
        emit_error_ = err;
      }
    }
  }

  void log_live_summary() {
    for (const auto& [id, trips] : trips_)
      if (auto e = estimate_clock(trips, 1, sync_samples_))
        log_->info("tum: link sync " + device_ + " -> " + id + ": offset " + std::to_string(e->offset_s) + " s, RTT " +
                   std::to_string(e->rtt_s * 1e3) + " ms, spread " + std::to_string(e->spread_s * 1e3) + " ms over " +
                   std::to_string(e->samples) + " round trips");
    if (!role_) {
      log_->warn("tum: " + device_ + ": no working devices were elected (" + std::to_string(tables_.size()) + " of " +
                 std::to_string(std::max<std::size_t>(2, elect_devices_)) + " devices reported their clocks)");
      return;
    }
    if (device_ == device1_ || device_ == device2_)
      log_->info("tum: " + device_ + " emitted tone " + (device_ == device1_ ? "1" : "2") + ": " + std::to_string(emissions_) +
                 " scheduled, " + std::to_string(emissions_missed_) + " missed (their frame had played), " +
                 std::to_string(emit_failures_) + " refused" + (emit_failures_ ? " (" + emit_error_ + ")" : "") + ", " +
                 std::to_string(emitter_->late_emissions()) + " late");
    if (reporter_)
      for (const auto& [id, r] : remote_)
        if (id != device1_) {
          const std::string waited = " (" + std::to_string(r.undecided) + " searches before decided nothing: too few or ambiguous)";
          if (r.offset_s)
            log_->info("tum: recordings pair " + id + "'s audio clock at " + std::to_string(*r.offset_s) + " s from " + device1_ + "'s" + waited);
          else
            log_->warn("tum: the recordings never paired " + id + "'s audio clock with " + device1_ + "'s" + waited);
        }
  }

  void note_failure(const std::string& why) {
    if (failed_++ == 0) first_failure_ = why;
  }

  void solve_and_publish(const std::vector<DeviceExchange>& devs, Publisher& out) {
    if (calibrate_c_) {
      if (auto c = speed_of_sound_sample(devs[0], devs[0].t1_s)) c_samples_.push_back(*c);
      if (auto c = speed_of_sound_sample(devs[1], devs[1].t2_s)) c_samples_.push_back(*c);
      if (!c_samples_.empty()) {
        std::vector<double> s = c_samples_;
        std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
        if (s[s.size() / 2] > 300.0 && s[s.size() / 2] < 400.0) cfg_.speed_of_sound_mps = s[s.size() / 2];
      }
    }
    if (!network_) network_.emplace(cfg_, net_cfg_);
    network_->set_speed_of_sound(cfg_.speed_of_sound_mps);
    const NetworkResult res = network_->add(devs);
    if (!res.ok) {
      note_failure("exchange at " + std::to_string(devs[0].t1_s.empty() ? 0.0 : devs[0].t1_s[0]) + " s could not be solved");
      return;
    }
    ++solved_;
    for (const NetworkPlacement& p : res.devices) {
      if (!p.ok) continue;
      Eigen::Vector3d x = p.origin;
      Eigen::Matrix3d cov = p.cov;
      bool outlier = false;
      double confidence = 1.0;
      if (p.id != device1_ && tracker_cfg_.filter && !p.still) {
        Tracker& tr = trackers_.try_emplace(p.id, tracker_cfg_, std::hash<std::string>{}(p.id)).first->second;
        const TrackOutput t = tr.update_gaussian(p.origin, p.cov, !p.still, res.t_ref_s);
        x = t.origin, cov = t.cov, outlier = t.outlier, confidence = t.confidence;
      } else if (p.id != device1_) {
        confidence = 1.0 / (1.0 + std::sqrt(std::max(0.0, cov.trace())) / 0.1);
      }
      if (debug_)
        log_->debug("tum: t=" + std::to_string(res.t_ref_s) + " " + p.id + " x=" + std::to_string(x[0]) + "," + std::to_string(x[1]) +
                    "," + std::to_string(x[2]) + " yaw_off=" + std::to_string(p.yaw_offset_rad) + " rms=" + std::to_string(p.rms_sigma) + " basins=" + std::to_string(p.basins) + " w=" + std::to_string(p.basin_weight) + " vstd=" + std::to_string(p.vertical_std_m) +
                    " chi2=" + std::to_string(res.chi2_dof) + (p.still ? " still" : " moving"));
      Estimate e;
      e.plugin.assign(instance_);
      e.reference.assign(device1_);
      e.frame.assign("body");
      e.target.assign(p.id);
      e.t_s = res.t_ref_s;
      e.position_m = {x[0], x[1], x[2]};
      e.dims = 3;
      e.distance_m = x.norm();
      if (p.id != device1_) {
        // 1-sigma of the 3D position; where the data leave the height to the prior (network.hpp), the
        // vertical is not known: flagged, and std_m covers device 1's horizontal plane only (docs/tum.md,
        // "Uncertainty").
        double var = std::max(0.0, cov.trace());
        if (!p.height_observed) {
          const Eigen::Vector3d up = res.up;
          const Eigen::Matrix3d h = Eigen::Matrix3d::Identity() - up * up.transpose();
          var = std::max(0.0, (h * cov * h).trace());
          e.flags |= kEstimateHeightUnobserved;
        }
        e.std_m = std::sqrt(var + std_floor_m_ * std_floor_m_);
        const double r = x.norm();
        if (r > 0) e.distance_std_m = std::sqrt(std::max(0.0, (x / r).dot(cov * (x / r))));
      }
      e.confidence = static_cast<float>(confidence);
      if (outlier) e.flags |= kEstimateInconsistent;
      out.publish(e);
      ++published_;
    }
  }

  Logger* log_ = nullptr;
  Link* link_ = nullptr;
  const Clock* clock_ = nullptr;
  Emitter* emitter_ = nullptr;
  // live roles
  bool live_ = false, fixed_roles_ = false, can_work_ = false, emitting_ = false, warned_no_pair_ = false;
  double sync_period_s_ = 0.25, elect_tie_s_ = 0.002, exchange_period_s_ = 1.0 / 3.0, tone_delay_s_ = 0.07, tone_jitter_s_ = 0.05;
  double tone_gain_ = 0.8;
  double schedule_ahead_s_ = 0.2, start_delay_s_ = 1.0;
  int sync_samples_ = 8, sync_min_samples_ = 4;
  std::size_t elect_devices_ = 2;
  std::vector<std::string> elect_order_;
  SignalSpec tone1_, tone2_;
  double next_ping_s_ = -kInf, next_role_s_ = -kInf, anchor_s_ = 0.0;
  std::uint64_t ping_seq_ = 0, anchor_frame_ = 0, emissions_ = 0, emissions_missed_ = 0, emit_failures_ = 0, conflicting_roles_ = 0;
  std::int64_t next_k_ = 0;
  std::string emit_error_;
  std::map<std::string, std::vector<RoundTrip>> trips_;
  std::map<std::string, SyncTable> tables_;
  std::optional<Role> role_;
  std::optional<ClockEstimate> device2_offset_;
  std::uint64_t subscription_ = 0;
  std::string instance_, device_, prefix_, detector_, device1_, device2_;
  bool reporter_ = false;
  int template1_ = 0, template2_ = 1;
  std::optional<SignalSpec> scene_tone1_, scene_tone2_;  ///< the working devices' tones, from the scene
  std::map<std::string, int> template_of_;
  std::vector<std::array<double, 3>> mics_;
  std::optional<std::array<double, 3>> speaker_;
  double pair_window_s_ = 0.15, max_spread_m_ = 5.0, motion_gyro_radps_ = 0.05;
  bool calibrate_c_ = true;
  bool debug_ = false;
  SolverConfig cfg_;
  TrackerConfig tracker_cfg_;
  NetworkConfig net_cfg_;
  std::optional<NetworkSolver> network_;
  double std_floor_m_ = 0.0;
  double pairing_tolerance_s_ = 0.006;
  // every instance
  std::vector<Detection> pending_;
  double audio_t_ = -kInf, attitude_t_ = -kInf, imu_t_ = -kInf;  ///< latest local time per input stream
  std::deque<AttitudeAt> attitudes_;
  std::deque<MotionAt> motion_;
  std::uint64_t seq_ = 0;
  double last_exchange_s_ = -kInf;
  // reporter
  std::map<std::string, RemoteDevice> remote_;
  std::vector<std::string> order_;
  std::map<std::string, Tracker> trackers_;
  std::vector<double> c_samples_;
  std::size_t next_ = 0;
  std::uint64_t solved_ = 0, failed_ = 0, published_ = 0, bad_messages_ = 0;
  std::string first_failure_, first_bad_;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema{
      string_param("device", "", "Device this instance serves when the host gives none."),
      string_param("device1", "", "Working device 1 (the output frame); \"\" = the first device of the scene that emits."),
      string_param("device2", "", "Working device 2; \"\" = the second device of the scene that emits."),
      int_param("template1", 0, 0, 65535, "", "Detector template of device 1's tone when the host knows no scene."),
      int_param("template2", 1, 0, 65535, "", "Detector template of device 2's tone when the host knows no scene."),
      string_param("topic", "tum", "Link topic prefix of the TUM messages (<topic>/obs/<device>)."),
      string_param("detector", "", "Only detections of this detector instance (or <detector>_<device>); \"\" = any."),
      float_param("pair_window_s", 0.15, 0.01, 5.0, "s",
                  "Detections within this time of an exchange's first belong to it (loose sync: the two tones' offset)."),
      float_param("speed_of_sound_mps", 0.0, 0.0, 400.0, "m/s",
                  "Speed of sound; 0 = measured from the working devices' own emissions (known mic-speaker geometry)."),
      bool_param("exchange_motion", true,
                 "Correct a moving device's arrivals for its motion within an exchange (Eq. 7-10: the tones are heard and "
                 "sent at different instants) and for the chirps' range-Doppler coupling (docs/tum.md, \"Motion within an exchange\")."),
      float_param("timing_std_s", 5.0e-6, 1e-7, 1e-2, "s", "Arrival timing error (1 sigma) assumed by the solver."),
      float_param("attitude_std_rad", 0.02, 0.0, 1.0, "rad", "Relative attitude error (1 sigma), applied to the mic/speaker lever arms."),
      float_param("max_range_m", 10.0, 0.2, 100.0, "m", "Roots farther from device 1 are dropped."),
      float_param("max_spread_m", 5.0, 0.1, 100.0, "m", "Largest distance between devices (pairs exchanges across clocks)."),
      float_param("pairing_tolerance_s", 0.006, 0.0005, 1.0, "s",
                  "Clock pairing: how much a device's apparent clock offset may change between exchanges (motion over the propagation)."),
      float_param("motion_gyro_radps", 0.05, 0.0, 10.0, "rad/s", "Gyro rate above which a device counts as moving."),
      enum_param("filter", "none", {"none", "particle"}, "none: the window solve alone (network.hpp); particle: its fixes of moving devices through the Sec. V filter (tracker.hpp)."),
      int_param("particles", 200, 10, 100000, "", "Particles per tracked device."),
      float_param("outlier_jump_m", 0.3, 0.01, 100.0, "m",
                  "Sec. VIII: a window whose device 2 disagrees with the exchange's own range by more restarts; a filtered fix "
                  "farther than this (plus the motion allowed) from the track is an outlier."),
      float_param("moving_speed_mps", 0.5, 0.01, 20.0, "m/s", "1-sigma speed of a moving device between exchanges (window smoother and filter)."),
      int_param("window", 12, 1, 200, "", "Exchanges solved together (network solve, network.hpp)."),
      float_param("yaw_prior_rad", 0.35, 0.001, 3.2, "rad", "1-sigma heading error of a device's attitude relative to device 1's (estimated per device)."),
      float_param("still_yaw_prior_rad", 0.35, 0.001, 3.2, "rad",
                  "The same while no device moves in the window (offsets are then unobservable: the attitude's own accuracy)."),
      float_param("height_prior_m", 0.5, 0.0, 100.0, "m",
                  "1-sigma height of a device relative to device 1 (0 = none); only matters where the geometry leaves height unobservable."),
      float_param("moving_height_candidates_m", 0.3, 0.0, 5.0, "m",
                  "While the window fills, a moving device 2's roots are also tried this much higher and lower (0 = off): the pair sees its height least."),
      bool_param("log_fixes", false, "Log every fix and every root at debug level (log_level: debug)."),
      float_param("std_floor_m", 0.0, 0.0, 10.0, "m", "Added in quadrature to every reported std (unmodelled errors)."),
      // live roles (a node with an emitter; docs/tum.md "Live roles")
      float_param("sync_period_s", 0.25, 0.01, 60.0, "s", "live: how often each node pings every other (link round trips) and reports its clock table."),
      int_param("sync_samples", 8, 1, 1000, "", "live: a peer's clock offset and RTT are the medians over its last this many round trips."),
      int_param("sync_min_samples", 4, 1, 1000, "", "live: round trips needed before a peer's clock counts (election, device 2's schedule)."),
      int_param("elect_devices", 2, 2, 1000, "", "live: the election waits for the clock tables of this many devices, each measured to every other."),
      float_param("elect_tie_s", 0.002, 0.0, 10.0, "s", "live: pairs whose RTT is within this of the smallest tie; the best ranked pair wins (elect_order)."),
      string_param("elect_order", "",
                   "live: tie-break ranking, comma-separated device ids (the rest follow by id); device 1 is the better ranked of the pair."),
      float_param("exchange_period_s", 1.0 / 3.0, 0.05, 60.0, "s", "live: working device 1 emits its tone every this long (the paper's 3 exchanges/s)."),
      float_param("tone_delay_s", 0.07, 0.0, 5.0, "s",
                  "live: working device 2 emits this long (plus the jitter) after device 1 (on device 1's clock, through "
                  "the link sync); delay + jitter must stay below pair_window_s minus the sync error and the propagation."),
      float_param("tone_jitter_s", 0.05, 0.0, 5.0, "s",
                  "live: device 2's delay varies by up to this from exchange to exchange (a fixed pseudo-random sequence): "
                  "the recordings' clock pairing tells the rounds apart by the interval between the tones."),
      float_param("tone_gain", 0.8, 0.0, 1.0, "", "live: gain of the emitted tones."),
      float_param("schedule_ahead_s", 0.2, 0.01, 10.0, "s", "live: emissions are handed to the emitter this long before they play."),
      float_param("start_delay_s", 1.0, 0.0, 60.0, "s", "live: the first exchange is this long after the election's announcement."),
      float_param("tone_f0_hz", 2000.0, 20.0, 96000.0, "Hz", "live: device 1's tone sweeps tone_f0_hz -> tone_f1_hz, device 2's the reverse."),
      float_param("tone_f1_hz", 8000.0, 20.0, 96000.0, "Hz", "live: see tone_f0_hz."),
      float_param("tone_duration_s", 0.04, 0.001, 2.0, "s", "live: length of each tone."),
      float_param("tone_fade_s", 0.004, 0.0, 1.0, "s", "live: raised-cosine fade in and out of each tone."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "tum", "1",
      "TUM: 3D relative positions of two-mic devices from a two-way tone exchange (paper 000)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new TumLocalizer); }};
  return &d;
}

}  // namespace locus::plugins::tum
