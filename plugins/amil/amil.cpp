// The `amil` localizer: roles, link plumbing, beep bookkeeping and estimates. See amil.hpp for the
// design and docs/amil.md for the user's view; the maths lives in tracker.cpp (IMU) and solver.cpp.
#include "amil.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "messages.hpp"
#include "solver.hpp"
#include "tracker.hpp"

namespace locus::plugins::amil {

namespace {

using amil::GestureTracker;
using amil::Session;

enum class Role { Player, Listener };

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

class AmilLocalizer final : public Localizer {
 public:
  // The player's handler captures `this`: once we are gone it must not run (found by ASan in
  // AmilPlugin.Roles, where a later instance's hello reached a destroyed player).
  ~AmilLocalizer() override {
    if (link_ != nullptr && subscribed_) link_->unsubscribe(subscription_);
  }

  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    link_ = &ctx.link;
    clock_ = &ctx.clock;
    emitter_ = ctx.emitter;
    instance_ = std::string(ctx.instance);
    device_ = !ctx.device.empty() ? std::string(ctx.device) : params.get_string("device");
    prefix_ = params.get_string("topic");
    if (prefix_.empty() || prefix_.find_first_of("+#") != std::string::npos || prefix_.back() == '/') {
      throw std::runtime_error("amil: param 'topic': expected a non-empty topic prefix without '+', '#' or a trailing '/', got '" +
                               prefix_ + "'");
    }
    detector_ = params.get_string("detector");
    channel_ = static_cast<std::uint32_t>(params.get_int("channel"));
    template_index_ = static_cast<int>(params.get_int("template_index"));

    // The beep: the device's own `emits` entry when the scene declares one, else the beep_* params.
    beep_duration_s_ = params.get_float("beep_duration_s");
    beep_.type = "lfm";
    beep_.f0_hz = params.get_float("beep_f0_hz");
    beep_.f1_hz = params.get_float("beep_f1_hz");
    beep_.duration_s = beep_duration_s_;
    beep_.fade_s = params.get_float("beep_fade_s");
    beep_.amplitude = 1.0;
    bool emits_acoustic = false;
    if (ctx.geometry != nullptr) {
      for (std::size_t i = 0; i < ctx.geometry->emits.size() && !emits_acoustic; ++i) {
        const SignalSpec& entry = ctx.geometry->emits[i];
        if (!entry.acoustic()) continue;
        if (const auto issues = check_signal(entry, "emits[" + std::to_string(i) + "]"); !issues.empty()) {
          throw std::runtime_error("amil: the device's " + issues.front().field + ": " + issues.front().message);
        }
        emits_acoustic = true;
        beep_ = entry;
        if (entry.duration_s > 0.0) beep_duration_s_ = entry.duration_s;  // lfm, multitone (a Gold code has none)
      }
    }
    // One carrier cycle of the beep: the timing error of an arrival whose cycle the detector is unsure of.
    if (beep_.type == "lfm" && beep_.f0_hz + beep_.f1_hz > 0.0) carrier_period_s_ = 2.0 / (beep_.f0_hz + beep_.f1_hz);
    else if (beep_.type == "gold" && beep_.carrier_hz > 0.0) carrier_period_s_ = 1.0 / beep_.carrier_hz;
    // The listening mic's horizontal offset from the device origin (what a listener's position means).
    if (ctx.geometry != nullptr && channel_ < ctx.geometry->mic_count)
      mic_offset_m_ = std::hypot(ctx.geometry->mics_m[channel_][0], ctx.geometry->mics_m[channel_][1]);
    beep_gain_ = params.get_float("beep_gain");
    beep_delay_s_ = params.get_float("beep_delay_s");

    // Role.
    const std::string role = params.get_string("role");
    player_id_ = params.get_string("player");
    if (role == "player") {
      role_ = Role::Player;
    } else if (role == "listener") {
      role_ = Role::Listener;
    } else if (!player_id_.empty()) {
      role_ = device_ == player_id_ ? Role::Player : Role::Listener;
    } else if (ctx.geometry != nullptr) {
      role_ = emits_acoustic ? Role::Player : Role::Listener;
    } else {
      role_ = emitter_ != nullptr ? Role::Player : Role::Listener;
    }
    if (role_ == Role::Player && device_.empty() && !player_id_.empty()) device_ = player_id_;

    // Solver.
    const auto method = amil::parse_method(params.get_string("method"));
    if (!method) throw std::runtime_error("amil: param 'method': unknown method '" + params.get_string("method") + "'");
    solver_.method = *method;
    solver_.speed_of_sound_mps = params.get_float("speed_of_sound_mps");
    solver_.timing_std_s = params.get_float("timing_std_s");
    solver_.position_std_m = params.get_float("position_std_m");
    position_std_auto_ = solver_.position_std_m == 0.0;
    if (position_std_auto_) solver_.position_std_m = 0.01;  // unused: every beep carries the tracker's
    solver_.known_skew = params.get_float("known_skew_ppm") * 1e-6;
    solver_.max_range_m = params.get_float("max_range_m");
    solver_.min_session_factor = params.get_float("min_noise_factor");
    match_tolerance_s_ = params.get_float("match_tolerance_s");
    min_beeps_ = static_cast<int>(params.get_int("min_beeps"));
    listener_wait_s_ = params.get_float("listener_wait_s");
    const std::string when = params.get_string("estimates");
    gesture_mode_ = when == "gesture" || (when == "auto" && emitter_ != nullptr);
    track_csv_ = params.get_string("track_csv");

    amil::TrackerConfig tc;
    tc.bin_s = params.get_float("bin_s");
    tc.motion_threshold_mps2 = params.get_float("motion_threshold_mps2");
    tc.quiet_bins = static_cast<int>(params.get_int("quiet_bins"));
    tc.min_rest_s = params.get_float("min_rest_s");
    tc.session_gap_s = params.get_float("session_gap_s");
    tc.session_movements = static_cast<int>(params.get_int("session_movements"));
    tc.max_gap_s = params.get_float("max_gap_s");
    tc.accel_scale_error = params.get_float("accel_scale_error");
    tc.drift_shape_factor = params.get_float("drift_shape_factor");
    tc.position_floor_m = params.get_float("position_floor_m");
    if (ctx.geometry != nullptr && ctx.geometry->has_speaker) {
      tc.speaker_body_m = Eigen::Vector3d(ctx.geometry->speaker_m[0], ctx.geometry->speaker_m[1], ctx.geometry->speaker_m[2]);
    }
    tracker_ = std::make_unique<GestureTracker>(tc);
    tracker_->on_pause([this](const Session&, double) { beep_now("pause"); });
    tracker_->on_session_closed([this](const Session& s, double) {
      if (gesture_mode_) pending_.push_back(Pending{s.id, clock_->now_s() + listener_wait_s_});
    });

    if (role_ == Role::Player) {
      subscription_ = link_->subscribe(amil::topic_filter(prefix_), [this](const LinkMessage& m) { on_link(m); });
      subscribed_ = true;
      log_->info("amil: player" + (device_.empty() ? std::string(" (device from the first event)") : " " + device_) +
                 "; estimates " + (gesture_mode_ ? "after each gesture" : "at the end") + "; beep " + signal_to_json(beep_));
    } else {
      if (!device_.empty()) link_->publish(amil::topic_hello(prefix_, device_), amil::encode(amil::HelloMessage{device_, channel_, mic_offset_m_}));
      log_->debug("amil: listener " + device_);
    }
  }

  std::vector<EventType> subscriptions() const override {
    if (role_ == Role::Player) return {EventType::AudioDetection, EventType::ImuSample};
    return {EventType::AudioDetection};
  }

  void on_event(const Event& event, Publisher& out) override {
    if (const auto* d = std::get_if<AudioDetection>(&event)) {
      if (!own(d->device.view())) return;
      if (d->channel != channel_ || (template_index_ >= 0 && d->template_index != template_index_)) return;
      if (!detector_.empty() && !matches_detector(d->detector.view())) return;
      if (!(d->sample_rate_hz > 0.0) || !std::isfinite(d->frame)) return;
      if (role_ == Role::Listener) {
        amil::ArrivalMessage m{device_, seq_++, d->frame, d->sample_rate_hz, d->channel, d->snr_db, d->confidence};
        if (d->carrier_period > 0.0f && std::isfinite(d->envelope_frame)) {
          m.envelope_frame = d->envelope_frame;
          m.carrier_period = d->carrier_period;
        }
        link_->publish(amil::topic_arrival(prefix_, device_), amil::encode(m));
      } else {
        add_self_beep(d->frame / d->sample_rate_hz, d->amplitude);
      }
    } else if (const auto* s = std::get_if<ImuSample>(&event)) {
      if (role_ != Role::Player || !own(s->device.view())) return;
      ++imu_samples_;
      tracker_->add(s->t_s, Eigen::Vector3d(s->accel_mps2[0], s->accel_mps2[1], s->accel_mps2[2]),
                    Eigen::Vector3d(s->gyro_radps[0], s->gyro_radps[1], s->gyro_radps[2]));
      // Live: the first beep marks the origin once the device rests.
      if (emitter_ != nullptr && !origin_beeped_ && !tracker_->moving() &&
          tracker_->rest_s() >= tracker_->config().min_rest_s) {
        origin_beeped_ = true;
        beep_now("origin");
      }
      if (gesture_mode_) publish_ready(out, false);
    }
  }

  void finish(Publisher& out) override {
    if (role_ == Role::Listener) {
      if (!device_.empty()) link_->publish(amil::topic_done(prefix_, device_), amil::encode(amil::DoneMessage{device_, seq_}));
      log_->debug("amil: listener " + device_ + ": " + std::to_string(seq_) + " arrivals published");
      return;
    }
    tracker_->close_session();
    publish_ready(out, true);
    const auto& c = tracker_->counters();
    if (imu_samples_ == 0) log_->warn("amil: player " + device_ + ": no IMU samples; the gesture cannot be tracked");
    if (c.non_finite > 0) log_->warn("amil: " + std::to_string(c.non_finite) + " non-finite IMU samples ignored");
    if (c.gaps > 0)
      log_->warn("amil: " + std::to_string(c.gaps) + " IMU gaps or time reversals (" + std::to_string(c.abandoned_sessions) +
                 " sessions abandoned)");
    if (bad_messages_ > 0)
      log_->warn("amil: " + std::to_string(bad_messages_) + " malformed link messages ignored (first: " + first_bad_ + ")");
    if (emit_failures_ > 0) log_->warn("amil: " + std::to_string(emit_failures_) + " beeps could not be scheduled: " + emit_error_);
    log_->info("amil: player " + device_ + ": " + std::to_string(tracker_->sessions().size()) + " sessions, " +
               std::to_string(self_beeps_.size()) + " beeps in the self-recording, " + std::to_string(listeners_.size()) +
               " listeners heard from, " + std::to_string(published_) + " estimates");
    if (!track_csv_.empty()) write_track();
  }

 private:
  struct ListenerState {
    std::vector<double> arrivals_s;
    std::vector<double> confidence;  ///< per arrival (same order)
    std::vector<double> cycle_offset_s;  ///< per arrival: frame - envelope_frame (s)
    std::vector<double> period_s;        ///< per arrival: carrier period (s), 0 = not carrier-timed
    double mic_offset_m = 0.0;       ///< from its hello
    std::uint64_t received = 0;
    std::uint64_t lost = 0;       ///< gaps in seq
    std::uint64_t next_seq = 0;
    bool done = false;
    std::uint64_t done_count = 0;
  };
  struct Pending {
    std::uint64_t session;
    double deadline_s;
  };

  bool own(std::string_view dev) {
    if (device_.empty()) {
      device_ = std::string(dev);
      log_->info("amil: serving device " + device_ + " (the first event's)");
      if (role_ == Role::Listener) link_->publish(amil::topic_hello(prefix_, device_), amil::encode(amil::HelloMessage{device_, channel_, mic_offset_m_}));
    }
    return dev == device_;
  }

  bool matches_detector(std::string_view name) const {
    if (name == detector_) return true;
    return name.size() > detector_.size() && name.substr(0, detector_.size()) == detector_ && name[detector_.size()] == '_';
  }

  void add_self_beep(double t_s, double amplitude) {
    // One beep per beep length (a second detector or channel may report the same beep).
    for (double b : self_beeps_)
      if (std::abs(b - t_s) < beep_duration_s_) return;
    const auto at = std::upper_bound(self_beeps_.begin(), self_beeps_.end(), t_s);
    self_amplitude_.insert(self_amplitude_.begin() + (at - self_beeps_.begin()), amplitude);
    self_beeps_.insert(at, t_s);
  }

  /// A beep of the player's own speaker a few cm from its mic is far louder than anything else the
  /// self-recording holds (an echo, another device's beep, a burst that correlates): detections well
  /// below the loudest ones are not its beeps.
  bool own_beep(std::size_t i) const {
    std::vector<double> a(self_amplitude_);
    if (a.size() < 3) return true;
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
    return self_amplitude_[i] >= kSelfBeepMinRatio * a[a.size() / 2];
  }
  static constexpr double kSelfBeepMinRatio = 0.25;  // -12 dB below the median self-beep

  void beep_now(const char* why) {
    if (emitter_ == nullptr) return;
    const double fs = emitter_->sample_rate_hz();
    const std::uint64_t start = emitter_->playback_frame() + static_cast<std::uint64_t>(std::llround(beep_delay_s_ * fs));
    std::string err;
    if (emitter_->schedule(beep_, start, beep_gain_, &err)) {
      ++beeps_scheduled_;
      log_->debug(std::string("amil: beep scheduled (") + why + ") at playback frame " + std::to_string(start));
    } else {
      ++emit_failures_;
      emit_error_ = err;
    }
  }

  void on_link(const LinkMessage& m) {
    const amil::Decoded d = amil::decode(prefix_, m.topic, m.payload);
    if (!d.error.empty()) {
      if (bad_messages_++ == 0) first_bad_ = m.topic + ": " + d.error;
      return;
    }
    if (d.hello) {
      listeners_[d.hello->listener].mic_offset_m = d.hello->mic_offset_m;
    } else if (d.arrival) {
      if (d.arrival->listener == device_) return;
      ListenerState& l = listeners_[d.arrival->listener];
      if (d.arrival->seq > l.next_seq) l.lost += d.arrival->seq - l.next_seq;
      l.next_seq = std::max(l.next_seq, d.arrival->seq + 1);
      ++l.received;
      l.arrivals_s.push_back(d.arrival->t_s());
      l.confidence.push_back(d.arrival->confidence);
      l.cycle_offset_s.push_back(d.arrival->cycle_offset_s());
      l.period_s.push_back(d.arrival->carrier_period_s());
    } else if (d.done) {
      ListenerState& l = listeners_[d.done->listener];
      l.done = true;
      l.done_count = d.done->arrivals;
    }
  }

  /// The beeps of a session (emission order): self-recorded time and speaker position.
  std::vector<amil::Beep> session_beeps(const Session& s, int* in_motion) const {
    std::vector<amil::Beep> out;
    if (s.pauses.empty()) return out;
    const double lo = s.pauses.front().t_start_s, hi = s.pauses.back().t_end_s;
    for (std::size_t i = 0; i < self_beeps_.size(); ++i) {
      const double t = self_beeps_[i];
      if (t < lo - 0.5 * beep_duration_s_ || t >= hi || !own_beep(i)) continue;
      Eigen::Vector3d sp;
      bool in_pause = false;
      double track_std_m = 0.0;
      if (!s.speaker_at(t + 0.5 * beep_duration_s_, sp, &in_pause, &track_std_m)) continue;
      if (!in_pause && in_motion != nullptr) ++*in_motion;
      amil::Beep b;
      b.position_m = sp.head<2>();
      b.player_time_s = t;
      // The tracker's own error model (tracker.hpp "Uncertainty"); position_std_m: "auto" = that.
      b.position_std_m = position_std_auto_ ? track_std_m : solver_.position_std_m;
      out.push_back(b);
    }
    return out;
  }

  /// Publishes the estimates of every closed session that is ready (all at finish()).
  void publish_ready(Publisher& out, bool at_finish) {
    const double now = clock_->now_s();
    for (const Session& s : tracker_->sessions()) {
      if (!s.closed) continue;
      auto& done_set = published_for_[s.id];
      if (!at_finish) {
        const auto p = std::find_if(pending_.begin(), pending_.end(), [&](const Pending& x) { return x.session == s.id; });
        if (p == pending_.end()) continue;
        if (now < p->deadline_s && !all_reported(s)) continue;
        pending_.erase(p);
      }
      solve_session(s, done_set, out);
    }
    if (at_finish) pending_.clear();
  }

  bool all_reported(const Session& s) const {
    if (listeners_.empty()) return false;
    const std::vector<amil::Beep> beeps = session_beeps(s, nullptr);
    if (beeps.empty()) return false;
    // A live player beeps in every pause: a session closed at its last stroke (session_movements) is
    // ready once the beep of its last pause is in the self-recording, not before (else it would be
    // solved without it as soon as the listeners reported the earlier ones).
    if (emitter_ != nullptr && !s.pauses.empty() && beeps.back().player_time_s < s.pauses.back().t_start_s) return false;
    std::vector<double> times;
    for (const auto& b : beeps) times.push_back(b.player_time_s);
    for (const auto& [id, l] : listeners_) {
      if (l.done) continue;
      const std::vector<double> m = amil::match_arrivals(times, l.arrivals_s, match_tolerance_s_);
      if (!std::isfinite(m.back())) return false;
    }
    return true;
  }

  void solve_session(const Session& s, std::set<std::string>& done_set, Publisher& out) {
    int in_motion = 0;
    const std::vector<amil::Beep> beeps = session_beeps(s, &in_motion);
    const std::string tag = "amil: session " + std::to_string(s.id) + " (T = " + fmt("%.3f", s.t_start_s) + " s)";
    if (!reported_sessions_.count(s.id)) {
      reported_sessions_.insert(s.id);
      log_->info(tag + ": " + std::to_string(s.movements.size()) + " movements, " + std::to_string(beeps.size()) +
                 " beeps" + (in_motion > 0 ? " (" + std::to_string(in_motion) + " while moving)" : std::string()));
    }
    if (static_cast<int>(beeps.size()) < min_beeps_) {
      if (!warned_few_.count(s.id)) {
        warned_few_.insert(s.id);
        log_->warn(tag + ": " + std::to_string(beeps.size()) + " beeps found in the self-recording, " +
                   std::to_string(min_beeps_) + " needed: no estimate");
      }
      return;
    }
    std::vector<double> times;
    for (const auto& b : beeps) times.push_back(b.player_time_s);
    char frame[32];
    std::snprintf(frame, sizeof frame, "player_start@%.6f", s.t_start_s);
    // Pair every listener's arrivals with the beeps, then solve them (one by one, or all at once for
    // the network method: the listeners share the beep positions).
    std::vector<std::string> ids;
    std::vector<amil::ListenerArrivals> arrs;
    std::vector<amil::CycleAlternative> alts;
    for (const auto& [id, l] : listeners_) {
      if (done_set.count(id) || l.arrivals_s.empty()) continue;
      int matched = 0;
      amil::ListenerArrivals arr;
      amil::CycleAlternative alt;  // resolve_cycles()'s runner-up, solved too (cycle_mixture())
      arr.arrival_s = amil::match_arrivals(times, l.arrivals_s, match_tolerance_s_, &matched);
      // Per-arrival timing error: the base error plus, for a detection unsure of its carrier cycle
      // (confidence < 1: the multipath fit disagreed), that fraction of a cycle. Then the carrier
      // cycles are chosen over all the listener's arrivals at once (amil::resolve_cycles).
      const std::size_t nb = arr.arrival_s.size();
      arr.arrival_std_s.assign(nb, solver_.timing_std_s);
      arr.cycle_offset_s.assign(nb, 0.0);
      double period_sum = 0.0;
      int timed = 0;
      for (std::size_t k = 0; k < nb; ++k) {
        const auto it = std::find(l.arrivals_s.begin(), l.arrivals_s.end(), arr.arrival_s[k]);
        if (it == l.arrivals_s.end()) continue;
        const auto i = static_cast<std::size_t>(it - l.arrivals_s.begin());
        const double conf = std::clamp(l.confidence[i], 0.0, 1.0);
        arr.arrival_std_s[k] = std::hypot(solver_.timing_std_s, (1.0 - conf) * carrier_period_s_);
        arr.cycle_offset_s[k] = l.cycle_offset_s[i];
        if (l.period_s[i] > 0.0) {
          period_sum += l.period_s[i];
          ++timed;
        }
      }
      if (timed > 0 && timed == static_cast<int>(std::count_if(arr.arrival_s.begin(), arr.arrival_s.end(),
                                                              [](double a) { return std::isfinite(a); }))) {
        arr.carrier_period_s = period_sum / timed;
        // the cycle is settled over all the arrivals below (their std back to the base); the
        // detector's doubt stays as a doubt about the path (the `weak` flag)
        arr.path_doubt_s.assign(nb, 0.0);
        for (std::size_t k = 0; k < nb; ++k) {
          arr.path_doubt_s[k] = std::sqrt(std::max(0.0, arr.arrival_std_s[k] * arr.arrival_std_s[k] -
                                                            solver_.timing_std_s * solver_.timing_std_s));
          arr.arrival_std_s[k] = solver_.timing_std_s;
        }
        const bool mixture = solver_.method != amil::Method::Network;  // network: half-cycle stds, as before
        const int moved = amil::resolve_cycles(beeps, arr, solver_, {}, mixture ? &alt : nullptr);
        if (moved > 0)
          log_->debug(tag + ": listener " + id + ": " + std::to_string(moved) + " arrival(s) moved by whole carrier cycles");
      }
      // The listener's position is its device's; the mic is at an unknown heading mic_offset_m away.
      arr.reference_offset_std_m = l.mic_offset_m / std::sqrt(2.0);
      if (matched < 3) {
        log_->warn(tag + ": listener " + id + ": " + std::to_string(matched) + " of " + std::to_string(beeps.size()) +
                   " beeps paired with its arrivals (3 needed)");
        continue;
      }
      ids.push_back(id);
      arrs.push_back(std::move(arr));
      alts.push_back(std::move(alt));
    }
    std::vector<amil::Solution> sols(ids.size());
    try {
      if (solver_.method == amil::Method::Network && !ids.empty()) {
        amil::NetworkSolution ns = amil::solve_network(beeps, arrs, solver_);
        if (ns.listeners.size() == ids.size()) sols = std::move(ns.listeners);
        log_->info(tag + ": network of " + std::to_string(ns.listeners_in_network) + " listeners" +
                   (ns.note.empty() ? std::string() : " (" + ns.note + ")"));
      } else {
        for (std::size_t i = 0; i < ids.size(); ++i) {
          sols[i] = amil::solve(beeps, arrs[i], solver_);
          amil::cycle_mixture(beeps, arrs[i], alts[i], solver_, sols[i]);
        }
        // One listener's fit has ~1 degree of freedom: scale the uncertainty by the session's pooled
        // residuals and flag listeners far beyond them (solver.hpp calibrate_session()).
        const double factor = amil::calibrate_session(sols, solver_);
        for (std::size_t i = 0; i < ids.size(); ++i)
          if (!sols[i].located() && (sols[i].weak || sols[i].inconsistent)) amil::widen_by_jackknife(beeps, arrs[i], solver_, sols[i]);
        log_->info(tag + ": session noise factor " + fmt("%.2f", factor) + " (pooled chi2/dof of the listeners)");
      }
    } catch (const std::exception& e) {
      log_->error(tag + ": solver: " + e.what());
      return;
    }
    for (std::size_t i = 0; i < ids.size(); ++i) {
      const std::string& id = ids[i];
      const amil::Solution& sol = sols[i];
      done_set.insert(id);
      if (sol.status == amil::Status::Failed || !std::isfinite(sol.direction_rad)) {
        log_->warn(tag + ": listener " + id + ": not located (" + sol.note + ")");
        continue;
      }
      Estimate e;
      e.plugin = std::string_view(instance_);
      e.reference = std::string_view(device_);
      e.frame = std::string_view(frame);
      e.target = std::string_view(id);
      e.t_s = s.t_start_s;
      e.dims = 2;
      e.direction_rad = sol.direction_rad;
      e.direction_std_rad = sol.direction_std_rad;
      if (sol.located()) {
        e.position_m = {sol.position_m.x(), sol.position_m.y(), kNaN};
        e.distance_m = sol.distance_m;
        e.std_m = sol.std_m;
        e.distance_std_m = sol.distance_std_m;
      } else {
        e.flags |= kEstimateDirectionOnly;
      }
      if (sol.status == amil::Status::Ambiguous) e.flags |= kEstimateAmbiguous;
      if (sol.inconsistent) e.flags |= kEstimateInconsistent;
      if (sol.weak) e.flags |= kEstimateWeak;
      e.confidence = static_cast<float>(std::clamp(sol.confidence, 0.0, 1.0));
      out.publish(e);
      ++published_;
      std::string msg = tag + ": " + id + " " + amil::to_string(sol.status) + " dir " +
                        fmt("%.1f", sol.direction_rad * 180.0 / M_PI) + " deg dist " + fmt("%.2f", sol.distance_m) +
                        " m, skew " + fmt("%.1f", sol.skew * 1e6) + " ppm, " + std::to_string(sol.beeps_used) + "/" +
                        std::to_string(sol.beeps_heard) + " beeps";
      if (!sol.note.empty()) msg += " (" + sol.note + ")";
      if (sol.status == amil::Status::Ambiguous && !sol.alternatives.empty())
        msg += "; alternative " + fmt("%.2f", sol.alternatives[0].x()) + ", " + fmt("%.2f", sol.alternatives[0].y());
      log_->info(msg);
    }
  }

  void write_track() {
    std::ofstream f(track_csv_);
    if (!f) {
      log_->error("amil: param 'track_csv': cannot write '" + track_csv_ + "'");
      return;
    }
    f << "session,t0_s,kind,t_s,x_m,y_m,std_m\n";
    f.precision(9);
    for (const Session& s : tracker_->sessions()) {
      for (std::size_t k = 0; k < s.movements.size(); ++k) {
        const auto& m = s.movements[k];
        for (std::size_t i = 0; i < m.t_s.size(); ++i)
          f << s.id << ',' << s.t_start_s << ",path," << m.t_s[i] << ',' << m.body_m[i].x() << ',' << m.body_m[i].y() << ",\n";
      }
      for (const auto& b : session_beeps(s, nullptr))
        f << s.id << ',' << s.t_start_s << ",beep," << b.player_time_s << ',' << b.position_m.x() << ',' << b.position_m.y()
          << ',' << b.position_std_m << '\n';
    }
  }

  Logger* log_ = nullptr;
  Link* link_ = nullptr;
  std::uint64_t subscription_ = 0;
  bool subscribed_ = false;
  const Clock* clock_ = nullptr;
  Emitter* emitter_ = nullptr;
  std::string instance_, device_, prefix_, detector_, player_id_, track_csv_;
  SignalSpec beep_;  // what a beep plays: the device's first acoustic `emits` entry, else the beep_* params
  bool position_std_auto_ = true;
  std::uint32_t channel_ = 0;
  int template_index_ = -1;
  Role role_ = Role::Listener;
  double beep_duration_s_ = 0.05, beep_gain_ = 0.8, beep_delay_s_ = 0.05;
  amil::SolverConfig solver_;
  double match_tolerance_s_ = 0.02, listener_wait_s_ = 1.0;
  int min_beeps_ = 3;
  bool gesture_mode_ = false;
  std::unique_ptr<GestureTracker> tracker_;
  // listener
  std::uint64_t seq_ = 0;
  // player
  std::vector<double> self_beeps_;
  std::vector<double> self_amplitude_;  ///< detection amplitude of each self beep (same order)
  double carrier_period_s_ = 1.0 / 20000.0;
  double mic_offset_m_ = 0.0;
  std::map<std::string, ListenerState> listeners_;
  std::map<std::uint64_t, std::set<std::string>> published_for_;
  std::set<std::uint64_t> reported_sessions_, warned_few_;
  std::vector<Pending> pending_;
  std::uint64_t imu_samples_ = 0, published_ = 0, bad_messages_ = 0, emit_failures_ = 0, beeps_scheduled_ = 0;
  std::string first_bad_, emit_error_;
  bool origin_beeped_ = false;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema{
      enum_param("role", "auto", {"auto", "player", "listener"},
                 "player or listener; auto: the `player` device, else the device whose scene geometry emits a sound, "
                 "else a node with an emitter"),
      string_param("player", "", "Device id of the player (\"\" = decided by `role`)."),
      string_param("device", "", "Device this instance serves when the host gives none (\"\" = the first event's)."),
      string_param("topic", "amil", "Link topic prefix of the AMIL messages (<topic>/arrivals/<listener>, ...)."),
      string_param("detector", "", "Only detections of this detector instance (or <detector>_<device>); \"\" = any."),
      int_param("channel", 0, 0, 31, "", "Microphone (audio channel) whose detections are the beep arrivals."),
      int_param("template_index", -1, -1, 65535, "", "Only detections of this template index (-1 = any)."),
      enum_param("method", "robust", {"paper", "paper_joint_skew", "joint", "robust", "network"},
                 "Positioning method (solver.hpp): the paper's subsets + 10-degree filter, joint position+skew least squares, or all listeners at once."),
      float_param("speed_of_sound_mps", 343.2, 300.0, 400.0, "m/s", "Speed of sound."),
      float_param("timing_std_s", 1.0e-6, 1e-9, 1e-2, "s", "Arrival timing error (1 sigma) assumed by the solver."),
      float_param("position_std_m", 0.0, 0.0, 1.0, "m",
                  "Beep position error per axis (1 sigma) assumed by the solver; 0 = the tracker's own error model per beep."),
      float_param("accel_scale_error", 0.003, 0.0, 0.2, "",
                  "Tracker error model: relative accelerometer scale + cross-axis error (1 sigma)."),
      float_param("drift_shape_factor", 0.01, 0.0, 10.0, "",
                  "Tracker error model: residual of the linear velocity de-drift as a fraction of v_end*T (1 sigma)."),
      float_param("min_noise_factor", 1.0, 0.05, 1.0, "",
                  "Lowest session noise factor (the listeners' pooled chi2/dof that scales every covariance); "
                  "below 1 the noise model may shrink when the residuals are smaller than it says."),
      float_param("position_floor_m", 0.0005, 0.0, 0.1, "m", "Tracker error model: per-axis floor of a pause position (1 sigma)."),
      float_param("known_skew_ppm", 0.0, -1000.0, 1000.0, "ppm", "paper method: the listeners' calibrated clock skew."),
      float_param("max_range_m", 30.0, 0.5, 1000.0, "m", "Farther solutions are reported as a direction only."),
      float_param("match_tolerance_s", 0.02, 1e-4, 0.5, "s", "Pairing window of a listener arrival with a player beep."),
      int_param("min_beeps", 3, 3, 1000, "", "Fewest beeps a session needs to be solved."),
      enum_param("estimates", "auto", {"auto", "gesture", "finish"},
                 "When to publish: after each gesture (live), at the end (replay); auto = gesture with an emitter."),
      float_param("listener_wait_s", 1.0, 0.0, 60.0, "s", "gesture mode: longest wait (host time) for listeners after a gesture."),
      float_param("bin_s", 0.1, 0.005, 2.0, "s", "Motion-detection bin length."),
      float_param("motion_threshold_mps2", 0.5, 0.01, 50.0, "m/s^2", "RMS accelerometer deviation from rest that marks motion."),
      int_param("quiet_bins", 2, 1, 100, "", "Consecutive quiet bins that end a movement."),
      float_param("min_rest_s", 0.3, 0.0, 60.0, "s", "Rest needed before a gesture (gravity and gyro bias)."),
      float_param("session_gap_s", 2.0, 0.1, 3600.0, "s", "A rest this long ends the gesture session."),
      int_param("session_movements", 0, 0, 1000, "",
                "> 0: a session also ends when its Nth movement ends (a gesture of known strokes: 4 for one triangle drawn from the middle of its base); "
                "live, its estimates then follow its last beep instead of session_gap_s later. 0 = by session_gap_s only."),
      float_param("max_gap_s", 0.25, 0.001, 60.0, "s", "Longer IMU gaps abandon the current session."),
      float_param("beep_f0_hz", 18000.0, 1.0, 96000.0, "Hz", "Beep (lfm) start frequency when the scene does not declare one."),
      float_param("beep_f1_hz", 22000.0, 1.0, 96000.0, "Hz", "Beep end frequency."),
      float_param("beep_duration_s", 0.05, 0.001, 2.0, "s", "Beep duration."),
      float_param("beep_fade_s", 0.005, 0.0, 1.0, "s", "Beep fade in/out."),
      float_param("beep_gain", 0.8, 0.0, 1.0, "", "live: gain of the scheduled beeps."),
      float_param("beep_delay_s", 0.05, 0.0, 5.0, "s", "live: how far ahead of the playback position a beep is scheduled."),
      string_param("track_csv", "", "player: write the tracked gesture path and beep positions here at the end (\"\" = no)."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "amil", "1",
      "AMIL: a beeping gesture of one device locates every listening device (paper 004)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new AmilLocalizer); }};
  return &d;
}

}  // namespace locus::plugins::amil
