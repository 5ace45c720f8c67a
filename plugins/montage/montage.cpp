// The `montage` localizer: round assembly, movement vectors, the reporter's formation. Design in
// montage.hpp; solver.cpp and movement.cpp hold the maths, messages.cpp the link format.
#include "montage.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <memory>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "messages.hpp"
#include "movement.hpp"
#include "solver.hpp"

namespace locus::plugins::montage {

namespace {

struct Detection {
  double t_s;
  std::size_t user;
  double confidence;
};

class MontageLocalizer final : public Localizer {
 public:
  ~MontageLocalizer() override {
    if (link_ != nullptr)
      for (std::uint64_t s : subs_) link_->unsubscribe(s);
  }

  /// [main]
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    link_ = &ctx.link;
    clock_ = &ctx.clock;
    instance_ = std::string(ctx.instance);
    device_ = std::string(ctx.device);
    if (device_.empty()) throw std::runtime_error("montage: runs on a device (a node's device or a replay device), not node-wide");
    prefix_ = params.get_string("topic");
    detector_ = params.get_string("detector");
    steps_detector_ = params.get_string("steps_detector");
    c_ = params.get_float("speed_of_sound_mps");
    max_range_ = params.get_float("max_range_m");
    const std::vector<double> gate = params.get_floats("round_window_s");
    if (gate.size() != 2) throw std::runtime_error("montage: param 'round_window_s': expected [before_s, after_s]");
    before_s_ = gate[0];
    after_s_ = gate[1];
    wait_s_ = params.get_float("solve_wait_s");
    silent_after_s_ = params.get_float("silent_after_s");
    std_scale_ = params.get_float("std_scale");
    std_floor_ = params.get_float("std_floor_m");
    publish_steps_ = params.get_bool("publish_steps");
    step_estimates_ = params.get_bool("step_estimates");
    FormationConfig fc;
    fc.range_std_m = params.get_float("range_std_m");
    fc.step_std_m = params.get_float("step_std_m");
    fc.drift_std_m_per_m = params.get_float("drift_std_m_per_m");
    fc.offset_prior_std_rad = params.get_float("offset_prior_std_rad");
    fc.scale_prior_std = params.get_float("stride_scale_prior_std");
    fc.window_rounds = static_cast<int>(params.get_int("window_rounds"));
    fc.shared_frame_rotation = params.get_bool("shared_frame_rotation");
    fc.chi2_std_inflation = params.get_bool("chi2_std_inflation");

    // The users: the scene's gold emitters in scene order (the goldcode detector's template order),
    // or param `users` (a live node).
    {
      std::string id;
      for (char ch : params.get_string("users") + ",") {
        if (ch == ',' || ch == ' ') {
          if (!id.empty()) users_.push_back(id);
          id.clear();
        } else {
          id += ch;
        }
      }
    }
    if (users_.empty()) {
      if (ctx.geometry == nullptr || ctx.geometry->scene_emits.empty())
        throw std::runtime_error("montage: param 'users': expected the users' device ids in code order (the goldcode "
                                 "detector's `codes` order); none given and the host knows no scene");
      for (const SceneSignal& s : ctx.geometry->scene_emits)
        if (s.signal.type == "gold") users_.push_back(s.id);
    }
    if (users_.size() < 2) throw std::runtime_error("montage: at least two users (gold emitters) are needed");
    for (std::size_t i = 0; i < users_.size(); ++i) {
      if (users_[i] == device_) me_ = i;
      for (std::size_t j = 0; j < i; ++j)
        if (users_[i] == users_[j]) throw std::runtime_error("montage: user '" + users_[i] + "' listed twice");
    }
    if (!me_) throw std::runtime_error("montage: device '" + device_ + "' is not one of the users (gold emitters)");
    self_m_ = params.get_float("self_distance_m");
    if (ctx.geometry != nullptr && ctx.geometry->has_speaker && ctx.geometry->mic_count > 0) {
      const auto& m = ctx.geometry->mics_m[0];
      const auto& s = ctx.geometry->speaker_m;
      self_m_ = std::sqrt(std::pow(m[0] - s[0], 2) + std::pow(m[1] - s[1], 2) + std::pow(m[2] - s[2], 2));
    }
    reporter_ = params.get_string("reporter");
    if (reporter_.empty()) reporter_ = users_.back();
    if (std::find(users_.begin(), users_.end(), reporter_) == users_.end())
      throw std::runtime_error("montage: param 'reporter': '" + reporter_ + "' is not one of the users");
    // One anchor user with a known start -> absolute positions (Sec. 2): its position at the radio start
    // signal (tau 0) in the world frame, and where magnetic north points in that frame (a site plan's
    // north arrow): the movement vectors are magnetic (`attitude` with the magnetometer: x = north,
    // y = west), so the formation's axes are magnetic up to the origin user's offset estimate.
    const std::string anchor = params.get_string("anchor_user");
    if (!anchor.empty()) {
      const auto it = std::find(users_.begin(), users_.end(), anchor);
      if (it == users_.end()) throw std::runtime_error("montage: param 'anchor_user': '" + anchor + "' is not one of the users");
      const std::vector<double> start = params.get_floats("anchor_start_m");
      if (start.size() != 2)
        throw std::runtime_error("montage: param 'anchor_start_m': expected [x, y] (the anchor user's world position at the start signal) with anchor_user set");
      anchor_ = static_cast<std::size_t>(it - users_.begin());
      anchor_start_m_ = {start[0], start[1]};
      north_world_rad_ = params.get_float("magnetic_north_world_deg") * std::numbers::pi / 180.0;
      anchor_start_std_m_ = params.get_float("anchor_start_std_m");
      frame_rotation_std_rad_ = params.get_float("frame_rotation_std_rad");
    }
    if (device_ == reporter_) {
      formation_ = std::make_unique<Formation>(users_, fc);
      book_ = RoundBook(params.get_float("round_match_s"));
      pair_clocks_ = params.get_bool("pair_clocks");
      one_way_ = params.get_bool("one_way_ranges");
      progress_.assign(users_.size(), -1e300);
      heard_wall_s_.assign(users_.size(), clock_->now_s());
      subs_.push_back(link_->subscribe(prefix_ + "/round/+", [this](const LinkMessage& m) { on_round(m); }));
      subs_.push_back(link_->subscribe(prefix_ + "/step/+", [this](const LinkMessage& m) { on_step(m); }));
      subs_.push_back(link_->subscribe(prefix_ + "/progress/+", [this](const LinkMessage& m) { on_progress(m); }));
    }
  }

  /// [main]
  std::vector<EventType> subscriptions() const override {
    return {EventType::AudioDetection, EventType::RadioSync, EventType::Step, EventType::Attitude, EventType::ImuSample};
  }

  /// [main]
  void on_event(const Event& event, Publisher& out) override {
    if (const auto* s = std::get_if<RadioSync>(&event)) {
      if (s->device.view() != device_) return;
      syncs_.push_back(s->t_s);
      std::sort(syncs_.begin(), syncs_.end());
    } else if (const auto* d = std::get_if<AudioDetection>(&event)) {
      if (d->device.view() != device_ || !(d->sample_rate_hz > 0)) return;
      if (!detector_.empty() && d->detector.view() != detector_) return;
      if (d->template_index >= users_.size()) {
        ++unknown_codes_;
        return;
      }
      const double t = d->frame / d->sample_rate_hz;
      // The detector reports its own emission up to a window early (the canceller looks ahead) and
      // the other users' codes in time order: a round closes once another user's arrival after its
      // window, or an own emission well after it, or the IMU stream 5 s later, has come.
      if (d->template_index == *me_) {
        own_.push_back(t);
        own_now_ = std::max(own_now_, t);
      } else {
        dets_.push_back(Detection{t, d->template_index, d->confidence});
        audio_now_ = std::max(audio_now_, t);
      }
      close_rounds(false);
      advance_time(t);
    } else if (const auto* a = std::get_if<Attitude>(&event)) {
      if (a->device.view() != device_) return;
      q_ = Eigen::Quaterniond(a->q_wxyz[0], a->q_wxyz[1], a->q_wxyz[2], a->q_wxyz[3]).normalized();
      have_q_ = true;
      double h = a->heading_rad;
      if (!headings_.empty()) h = headings_.back().second + std::remainder(h - last_raw_heading_, 2.0 * M_PI);
      last_raw_heading_ = a->heading_rad;
      headings_.emplace_back(a->t_s, h);
      while (headings_.size() > 2 && headings_.back().first - headings_.front().first > 10.0) headings_.pop_front();
      advance_time(a->t_s);
    } else if (const auto* im = std::get_if<ImuSample>(&event)) {
      if (im->device.view() != device_ || !have_q_) return;
      const Eigen::Vector3d a(im->accel_mps2[0], im->accel_mps2[1], im->accel_mps2[2]);
      walk_.add_sample(im->t_s, q_ * a);
    } else if (const auto* st = std::get_if<Step>(&event)) {
      if (st->device.view() != device_) return;
      if (!steps_detector_.empty() && st->detector.view() != steps_detector_) return;
      step(*st);
    }
    if (formation_) process(out, false);
  }

  /// [main] All inputs ended: the rounds still open go to the reporter before any node finishes.
  void inputs_ended(Publisher& /*out*/) override { close_rounds(true); }

  /// [main] All inputs ended, every node's last round delivered.
  void finish(Publisher& out) override {
    close_rounds(true);
    if (formation_) process(out, true);
    if (no_sync_ > 0)
      log_->warn("montage " + device_ + ": " + std::to_string(no_sync_) +
                 " own emissions before any start signal (RadioSync): not ranged");
    if (unknown_codes_ > 0) log_->warn("montage " + device_ + ": " + std::to_string(unknown_codes_) + " detections of codes beyond the users");
    if (bad_ > 0) log_->warn("montage: " + std::to_string(bad_) + " malformed link messages ignored (first: " + first_bad_ + ")");
    if (formation_) {
      std::string k;
      for (std::size_t u = 0; u < users_.size(); ++u)
        k += " " + users_[u] + " k=" + std::to_string(formation_->stride_scale(u)) +
             " offset=" + std::to_string(formation_->heading_offset_rad(u) * 180.0 / M_PI) + "deg";
      log_->info("montage reporter " + device_ + ": " + std::to_string(book_.rounds().size()) + " rounds, " +
                 std::to_string(ranges_) + " two-way and " + std::to_string(one_way_ranges_) + " one-way ranges (" + std::to_string(formation_->dropped_ranges()) + " dropped as outliers), " +
                 std::to_string(late_reports_) + " late reports, " + std::to_string(published_) + " estimates;" + k);
    }
  }

 private:
  // ------------------------------------------------------------------ every device
  std::optional<double> sync_before(double t) const {
    std::optional<double> s;
    for (double x : syncs_)
      if (x <= t) s = x;
    return s;
  }

  void advance_time(double t) {
    now_ = std::max(now_, t);
    close_rounds(false);
    if (const auto s = sync_before(now_); s && closed_until_ > -1e299 && now_ - last_progress_ >= 0.5) {
      last_progress_ = now_;
      // Every round up to the last closed one has been sent, every step up to now_.
      link_->publish(topic_progress(prefix_, device_), encode(ProgressMessage{device_, std::min(now_, closed_until_) - *s}));
    }
  }

  /// Own emissions whose round window has passed: their round message.
  void close_rounds(bool all) {
    std::sort(own_.begin(), own_.end());
    while (!own_.empty()) {
      const double end = own_.front() + after_s_;
      if (!(all || audio_now_ > end || own_now_ > end + 1.5 || now_ > end + 5.0)) break;
      const double e = own_.front();
      own_.pop_front();
      closed_until_ = std::max(closed_until_, e + 0.5);
      if (e - last_own_ < 0.2) continue;  // the same emission twice
      last_own_ = e;
      const auto s = sync_before(e);
      if (!s) {
        ++no_sync_;
        continue;
      }
      std::sort(dets_.begin(), dets_.end(), [](const Detection& a, const Detection& b) { return a.t_s < b.t_s; });
      RoundMessage m;
      m.device = device_;
      m.tau_own_s = e - *s;
      m.self_m = self_m_;
      for (std::size_t u = 0; u < users_.size(); ++u) {
        if (u == *me_) continue;
        const Detection* best = nullptr;
        for (const Detection& d : dets_)
          if (d.user == u && d.t_s >= e - before_s_ && d.t_s <= e + after_s_ && (!best || d.confidence > best->confidence)) best = &d;
        if (best) m.arrivals.emplace_back(users_[u], best->t_s - e);
      }
      log_->debug("montage " + device_ + ": round " + encode(m));
      link_->publish(topic_round(prefix_, device_), encode(m));
      while (!dets_.empty() && dets_.front().t_s < e - 2.0) dets_.pop_front();
    }
  }

  double heading_mean(double t0, double t1) const {
    double sum = 0.0;
    int n = 0;
    for (const auto& [t, h] : headings_)
      if (t >= t0 && t <= t1) {
        sum += h;
        ++n;
      }
    if (n > 0) return sum / n;
    // No sample inside: the nearest one.
    double best = NAN, bd = 1e300;
    for (const auto& [t, h] : headings_)
      if (std::abs(t - 0.5 * (t0 + t1)) < bd) {
        bd = std::abs(t - 0.5 * (t0 + t1));
        best = h;
      }
    return best;
  }

  void step(const Step& st) {
    if (!std::isfinite(st.stride_m) || !(st.stride_m >= 0.0)) return;
    const double t0 = last_step_t_ && st.t_s - *last_step_t_ < 1.5 ? *last_step_t_
                                                                   : st.t_s - 1.0 / std::max(0.5f, st.frequency_hz);
    last_step_t_ = st.t_s;
    const double h = heading_mean(t0, st.t_s);
    if (!std::isfinite(h)) return;
    walk_.add_step(t0, st.t_s, h);
    const auto s = sync_before(st.t_s);
    if (!s) return;
    StepMessage m;
    m.device = device_;
    m.tau_s = st.t_s - *s;
    m.t_s = st.t_s;
    m.stride_m = std::min<double>(st.stride_m, 5.0);
    m.heading_rad = h;
    const auto off = walk_.offset_rad();
    m.offset_valid = off.has_value();
    m.offset_rad = off.value_or(0.0);
    link_->publish(topic_step(prefix_, device_), encode(m));
  }

  // ------------------------------------------------------------------ the reporter
  std::optional<std::size_t> user_index(const std::string& id) const {
    for (std::size_t u = 0; u < users_.size(); ++u)
      if (users_[u] == id) return u;
    return std::nullopt;
  }
  void bad(const LinkMessage& m, const std::string& why) {
    if (bad_++ == 0) first_bad_ = m.topic + ": " + why;
  }
  /// The publishing device (the topic's last level) must be the message's device, and a user.
  std::optional<std::size_t> sender(const LinkMessage& m, const std::string& device) {
    const std::string last = m.topic.substr(m.topic.rfind('/') + 1);
    if (last != device) {
      bad(m, "device '" + device + "' published on another device's topic");
      return std::nullopt;
    }
    const auto u = user_index(device);
    if (!u) bad(m, "'" + device + "' is not a user");
    return u;
  }

  void on_round(const LinkMessage& lm) {
    std::string why;
    const auto m = decode_round(lm.payload, &why);
    if (!m) return bad(lm, why);
    const auto u = sender(lm, m->device);
    if (!u) return;
    if (m->tau_own_s < processed_tau_ + 0.3) {  // a round already solved
      ++late_reports_;
      return;
    }
    book_.add(*m);
    heard(*u, m->tau_own_s);
  }
  void on_step(const LinkMessage& lm) {
    std::string why;
    const auto m = decode_step(lm.payload, &why);
    if (!m) return bad(lm, why);
    const auto u = sender(lm, m->device);
    if (!u) return;
    formation_->add_step(*u, m->tau_s, m->stride_m, m->heading_rad,
                         m->offset_valid ? std::optional<double>(m->offset_rad) : std::nullopt);
    steps_[*u].push_back(*m);
    // Alive, but no progress: a step says nothing about the sender's rounds (a round closes after the
    // next user's arrival, its own next emission or 5 s of IMU time, later than the steps up to it);
    // counting it as progress let the reporter solve a round before that user's report came, then drop
    // the report as late, depending on thread timing (montage-103: 1 replay in ~10 lost a walker).
    heard_wall_s_[*u] = clock_->now_s();
  }
  void on_progress(const LinkMessage& lm) {
    std::string why;
    const auto m = decode_progress(lm.payload, &why);
    if (!m) return bad(lm, why);
    const auto u = sender(lm, m->device);
    if (!u) return;
    heard(*u, m->tau_s);
  }
  /// User u has sent every round report and step up to scene time tau_s (since its start signal): its
  /// round messages and progress messages say so; heard now (host time).
  void heard(std::size_t u, double tau_s) {
    progress_[u] = std::max(progress_[u], tau_s);
    heard_wall_s_[u] = clock_->now_s();
  }

  /// Solves every round that every user has passed by solve_wait_s (all at the end).
  void process(Publisher& out, bool all) {
    // Every user that is still talking holds the rounds back until it has passed them, also one not
    // heard from yet (its reports may be on their way: boards and replay nodes start at different
    // moments) or far behind in scene time (replayed nodes run at different speeds). Only a user
    // silent for silent_after_s of host time stops holding them: a node that died or left.
    const double wall = clock_->now_s();
    double min_progress = 1e300;
    for (std::size_t u = 0; u < progress_.size(); ++u)
      if (wall - heard_wall_s_[u] <= silent_after_s_) min_progress = std::min(min_progress, progress_[u]);
    const auto& rounds = book_.rounds();
    while (next_round_ < rounds.size()) {
      const Round& r = rounds[next_round_];
      const bool ready = all || r.tau_s + wait_s_ <= min_progress;
      if (!ready) break;
      std::vector<RangeObs> ranges = round_ranges(r, users_, c_, max_range_);
      // The pairs' clock lines (solver.hpp, PairClocks): a two-way round off its pair's line has a
      // wrong arrival and is dropped; a pair that only one device heard is ranged one way.
      if (pair_clocks_) learn_clocks(r, users_, c_, ranges, clocks_);
      ranges_ += ranges.size();
      for (const RangeObs& ro : ranges)
        log_->debug("montage range tau " + std::to_string(r.tau_s) + " " + users_[ro.i] + "-" + users_[ro.j] + " " + std::to_string(ro.distance_m));
      if (pair_clocks_ && one_way_) {
        std::vector<RangeObs> one_way = one_way_ranges(r, users_, c_, max_range_, clocks_);
        std::erase_if(one_way, [&](const RangeObs& ro) { return !formation_->is_localized(ro.i) || !formation_->is_localized(ro.j); });
        one_way_ranges_ += one_way.size();
        for (const RangeObs& ro : one_way) {
          clocks_.accept(ro.i, ro.j, r.tau_s, ro.distance_m);
          log_->debug("montage one-way range tau " + std::to_string(r.tau_s) + " " + users_[ro.i] + "-" + users_[ro.j] + " " +
                      std::to_string(ro.distance_m) + " sd " + std::to_string(ro.extra_std_m));
        }
        ranges.insert(ranges.end(), one_way.begin(), one_way.end());
      }
      const std::size_t k = formation_->add_round(r.tau_s, std::move(ranges));
      const std::vector<UserFix> fixes = formation_->solve(k);
      processed_tau_ = r.tau_s;
      publish(r, fixes, out);
      ++next_round_;
    }
  }

  /// The published frame and position of a formation-frame point: `world` once the anchor user is
  /// localized (anchor_user), else `relative_trace`.
  /// The std of a published point: the formation's, plus in the `world` frame what the anchor adds
  /// (its start's std, and the frame's rotation error growing with the distance from the anchor's start).
  double output_std(const Eigen::Vector2d& p, double formation_std_m) const {
    double v = formation_std_m * formation_std_m;
    if (anchor_origin_) {
      const double rot = frame_rotation_std_rad_ * (p - *anchor_origin_).norm();
      v += anchor_start_std_m_ * anchor_start_std_m_ + rot * rot;
    }
    return std::sqrt(v);
  }

  std::pair<const char*, Eigen::Vector2d> output_frame(const Eigen::Vector2d& p) const {
    if (!anchor_origin_) return {"relative_trace", p};
    const double c = std::cos(north_world_rad_), sn = std::sin(north_world_rad_);
    const Eigen::Vector2d d = p - *anchor_origin_;
    return {"world", anchor_start_m_ + Eigen::Vector2d(c * d.x() - sn * d.y(), sn * d.x() + c * d.y())};
  }

  void publish(const Round& r, const std::vector<UserFix>& fixes, Publisher& out) {
    const auto s = sync_before(now_);
    if (!s) return;  // the reporter's clock is unknown without its own start signal
    // The anchor's formation-frame position at the start signal: its first fix moved back by its steps.
    if (anchor_ && !anchor_origin_ && fixes[*anchor_].localized)
      anchor_origin_ = fixes[*anchor_].position_m - formation_->move(*anchor_, 0.0, r.tau_s);
    for (std::size_t u = 0; u < users_.size(); ++u) {
      auto& st = steps_[u];
      // A position at every step since the user's previous fix: that fix moved by the user's own
      // steps (its current offset and stride scale), with what the steps miss of this round's fix
      // spread over them in proportion to time (so both rounds are met). Published a round late.
      if (step_estimates_ && fixes[u].localized && last_fix_.count(u)) {
        const LastFix& prev = last_fix_.at(u);
        const Eigen::Vector2d closure =
            fixes[u].position_m - (prev.position_m + formation_->move(u, prev.tau_s, r.tau_s));
        const double span = r.tau_s - prev.tau_s;
        for (const StepMessage& m : st) {
          if (m.tau_s <= prev.tau_s) continue;
          if (m.tau_s >= r.tau_s) break;
          const double f = span > 0.0 ? (m.tau_s - prev.tau_s) / span : 1.0;
          const Eigen::Vector2d p = prev.position_m + formation_->move(u, prev.tau_s, m.tau_s) + f * closure;
          Estimate e;
          e.plugin = NameTag(instance_);
          e.reference = DeviceId(device_);
          const auto [frame, q] = output_frame(p);
          e.frame = NameTag(frame);
          e.target = NameTag(users_[u]);
          e.t_s = m.tau_s + *s;
          e.position_m = {q.x(), q.y(), 0.0};
          e.dims = 2;
          // Between two fixes the position is at least as uncertain as the worse of them, and the
          // steps' own error grows towards the middle (bounded by the closure they had to absorb).
          const double between = std::min(f, 1.0 - f) * closure.norm();
          e.std_m = std::max(std_floor_, output_std(p, std_scale_ * std::hypot(std::max(prev.std_m, fixes[u].std_m), between)));
          e.confidence = static_cast<float>(std::exp(-e.std_m / 1.0));
          out.publish(Event{e});
          ++published_;
        }
      }
      if (fixes[u].localized) last_fix_[u] = LastFix{r.tau_s, fixes[u].position_m, fixes[u].std_m};
      // Steps up to this round, with the stride calibrated by ranging (k_u).
      while (!st.empty() && st.front().tau_s <= r.tau_s) {
        if (publish_steps_) {
          Step e;
          e.device = DeviceId(users_[u]);
          e.detector = NameTag(instance_);
          e.t_s = st.front().t_s;
          e.stride_m = static_cast<float>(st.front().stride_m * formation_->stride_scale(u));
          e.frequency_hz = 0.0f;
          out.publish(Event{e});
        }
        st.pop_front();
      }
      if (!fixes[u].localized) continue;
      Estimate e;
      e.plugin = NameTag(instance_);
      e.reference = DeviceId(device_);
      const auto [frame, q] = output_frame(fixes[u].position_m);
      e.frame = NameTag(frame);
      e.target = NameTag(users_[u]);
      e.t_s = r.tau_s + *s;
      e.position_m = {q.x(), q.y(), 0.0};
      e.dims = 2;
      e.std_m = std::max(std_floor_, output_std(fixes[u].position_m, std_scale_ * fixes[u].std_m));
      e.confidence = static_cast<float>(std::exp(-e.std_m / 1.0));
      out.publish(Event{e});
      ++published_;
    }
  }

  Logger* log_ = nullptr;
  Link* link_ = nullptr;
  std::vector<std::uint64_t> subs_;
  std::string instance_, device_, prefix_, detector_, steps_detector_, reporter_;
  std::vector<std::string> users_;
  std::optional<std::size_t> me_;
  double c_ = 343.2, max_range_ = 40.0, before_s_ = 0.16, after_s_ = 0.22, wait_s_ = 2.0, self_m_ = 0.0;
  double std_scale_ = 1.0, std_floor_ = 0.05;
  bool publish_steps_ = true;
  // every device
  std::vector<double> syncs_;
  std::deque<double> own_;
  std::deque<Detection> dets_;
  double now_ = -1e300, closed_until_ = -1e300, audio_now_ = -1e300, own_now_ = -1e300, last_progress_ = -1e300, last_own_ = -1e300;
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  bool have_q_ = false;
  double last_raw_heading_ = 0.0;
  std::deque<std::pair<double, double>> headings_;  ///< (t, unwrapped heading)
  std::optional<double> last_step_t_;
  WalkDirection walk_;
  std::uint64_t no_sync_ = 0, unknown_codes_ = 0;
  // the reporter
  std::unique_ptr<Formation> formation_;
  RoundBook book_;
  std::vector<double> progress_;
  std::vector<double> heard_wall_s_;  ///< host time of each user's last message (reporter)
  const Clock* clock_ = nullptr;
  double silent_after_s_ = 5.0;
  std::map<std::size_t, std::deque<StepMessage>> steps_;
  struct LastFix {
    double tau_s = 0.0;
    Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
    double std_m = 0.0;
  };
  std::map<std::size_t, LastFix> last_fix_;  ///< each user's latest published round fix
  std::optional<std::size_t> anchor_;           ///< anchor_user
  Eigen::Vector2d anchor_start_m_ = Eigen::Vector2d::Zero();
  double north_world_rad_ = 0.0, anchor_start_std_m_ = 0.1, frame_rotation_std_rad_ = 0.1;
  std::optional<Eigen::Vector2d> anchor_origin_;  ///< the anchor at tau 0, formation frame
  bool step_estimates_ = true;
  std::size_t next_round_ = 0;
  double processed_tau_ = -1e300;
  std::uint64_t bad_ = 0, late_reports_ = 0, ranges_ = 0, one_way_ranges_ = 0, published_ = 0;
  bool pair_clocks_ = true, one_way_ = false;
  PairClocks clocks_;
  std::string first_bad_;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema s = {
      string_param("topic", std::string("montage"), "Link topic prefix (<topic>/round|step|progress/<device>)."),
      string_param("users", std::string(""),
                   "The users' device ids, comma-separated, in the goldcode detector's code order (template k = the "
                   "k-th); \"\" = the scene's gold emitters in scene order (replay)."),
      string_param("reporter", std::string(""),
                   "The device whose instance solves and publishes the formation (\"\" = the last user: on replay the "
                   "last node to finish, so it has every other node's messages)."),
      string_param("detector", std::string("goldcode"), "Instance name of the goldcode detector (\"\" = any)."),
      string_param("steps_detector", std::string("steps"), "Instance name of the steps detector (\"\" = any)."),
      float_param("speed_of_sound_mps", 343.2, 300.0, 400.0, "m/s", "Speed of sound."),
      float_param("self_distance_m", 0.0, 0.0, 1.0, "m",
                  "The device's speaker-to-mic distance when the host gives no geometry (replay takes it from the scene)."),
      float_list_param("round_window_s", std::vector<double>{0.16, 0.22}, 0.0, 5.0, "s",
                       "[before_s, after_s]: another user's arrival belongs to this device's round when it lies within "
                       "before_s before to after_s after its own emission (the goldcode round gate).", 2, 2),
      float_param("round_match_s", 0.3, 0.01, 10.0, "s",
                  "Reports of two devices are the same round when their times since the start signal differ by less."),
      float_param("max_range_m", 40.0, 1.0, 500.0, "m", "Longest ETOA range accepted."),
      float_param("silent_after_s", 5.0, 0.1, 600.0, "s",
                  "Reporter: a user silent this long (host time) stops holding rounds back (a node that died or left)."),
      float_param("solve_wait_s", 2.0, 0.0, 60.0, "s",
                  "The reporter solves a round once every user's messages have passed it by this much (steps lag)."),
      float_param("range_std_m", 0.15, 0.001, 10.0, "m", "1-sigma of an ETOA range in the formation adjustment."),
      bool_param("pair_clocks", true,
                 "Fit each pair's clock line to its two-way rounds and drop a two-way round off it: one of its arrivals "
                 "is wrong (docs/montage.md, \"Pair clock lines\")."),
      bool_param("one_way_ranges", false,
                 "With pair_clocks: also range a round where only one device heard the other, through the pair's clock "
                 "line (off: more ranges on the simulator, a wrong formation on montage-103; docs/montage.md)."),
      float_param("step_std_m", 0.08, 0.001, 2.0, "m", "Per-step error of a movement vector (isotropic)."),
      float_param("drift_std_m_per_m", 0.05, 0.0, 1.0, "", "Movement error growing with the distance walked."),
      float_param("offset_prior_std_rad", 0.35, 0.001, 10.0, "rad",
                  "Prior std of a walker's heading offset around its acceleration estimate."),
      float_param("stride_scale_prior_std", 0.2, 0.001, 10.0, "", "Prior std of a walker's stride scale k around 1."),
      int_param("window_rounds", std::int64_t{30}, 2, 1000, "", "Rounds adjusted together (older ones are fixed)."),
      bool_param("shared_frame_rotation", false,
                 "Estimate the frame's rotation from the world from every walker's offset prior (else from the "
                 "origin's alone; docs/montage.md)."),
      bool_param("chi2_std_inflation", true,
                 "Widen the position std by sqrt of the window's reduced chi-square when above 1 (ranges and "
                 "movements fitting worse than range_std_m / step_std_m say)."),
      float_param("std_scale", 1.0, 0.01, 100.0, "", "Reported std_m = this x the adjustment's position std."),
      float_param("std_floor_m", 0.05, 0.0, 10.0, "m", "Smallest reported std_m."),
      string_param("anchor_user", std::string(""),
                   "A user whose start is known (\"\" = none): once it is localized, positions are published in the "
                   "`world` frame instead of `relative_trace`."),
      float_list_param("anchor_start_m", std::vector<double>{}, -1e6, 1e6, "m",
                       "[x, y]: the anchor user's world position at the radio start signal.", 0, 2),
      float_param("magnetic_north_world_deg", 90.0, -360.0, 360.0, "deg",
                  "Direction of magnetic north in the world frame, counter-clockwise from +x (a site plan's north arrow; "
                  "90 = world y points north)."),
      float_param("anchor_start_std_m", 0.1, 0.0, 100.0, "m", "1-sigma of anchor_start_m (added to every world-frame std)."),
      float_param("frame_rotation_std_rad", 0.1, 0.0, 3.2, "rad",
                  "1-sigma of the world frame's rotation (magnetic north's direction and the origin user's offset "
                  "estimate): a world-frame std grows by this x the distance from the anchor's start."),
      bool_param("step_estimates", true,
                 "The reporter also publishes each walker's position at every step between two of its round fixes "
                 "(the earlier fix moved by the steps, the closure to the later spread over them; one round late)."),
      bool_param("publish_steps", true,
                 "The reporter publishes every walker's steps again (detector = this instance) with the stride "
                 "calibrated by ranging."),
  };
  return s;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "montage", "1",
      "Montage: multi-user ETOA ranging with Gold codes, movement vectors, formation tracking (paper 002)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new MontageLocalizer); }};
  return &d;
}

}  // namespace locus::plugins::montage
