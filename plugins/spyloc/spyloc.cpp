// The `spyloc` localizer: sync/beep pairing, LoS classification, fix and tracking. Design in
// spyloc.hpp; classifier.cpp, solver.cpp and tracker.cpp hold the maths.
#include "spyloc.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <deque>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "classifier.hpp"
#include "locus/dsp/dead_reckoning.hpp"
#include "solver.hpp"
#include "tracker.hpp"

namespace locus::plugins::spyloc {

namespace {

// A relative model path is looked up from the working directory and then its parents (so
// `config/spyloc-los.yaml` works from the source tree and from a build directory inside it).
std::string find_model(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (p.is_absolute() || fs::exists(p)) return path;
  std::error_code ec;
  for (fs::path dir = fs::current_path(ec); !ec && !dir.empty(); dir = dir.parent_path()) {
    if (fs::exists(dir / p)) return (dir / p).string();
    if (dir == dir.parent_path()) break;
  }
  return path;  // not found: load() reports it
}

struct Beacon {
  std::string id;
  std::uint32_t mask = 0;
  std::array<double, 3> anchor{};
  double delay_s = 0.0;
  std::deque<double> syncs;  ///< recent sync receive times (local)
};

struct PendingBeep {
  double frame = 0.0;
  double t_s = 0.0;
  std::size_t beacon = 0;
};

/// A range ready for the tracker (paired, classified), waiting in dead-reckoning mode until the
/// walker's steps up to its time are known.
struct RangeMeas {
  double t_s = 0.0;
  std::size_t beacon = 0;
  double range_m = 0.0;
  double std_m = 0.0;
  double p_los_decay = 1.0;  ///< the classifier's P(LoS); the verdict is made against the track (fuse_los)
  double range_var_m2 = 0.0;  ///< the range's own variance before the NLoS-bias term
  bool los = true;
};

struct InitRange {
  std::size_t beacon = 0;
  double t_s = 0.0;
  double range_m = 0.0;
};

class SpyLocLocalizer final : public Localizer {
 public:
  /// [main]
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    instance_ = std::string(ctx.instance);
    device_ = !ctx.device.empty() ? std::string(ctx.device) : params.get_string("device");
    if (device_.empty()) throw std::runtime_error("spyloc: param 'device': expected the walker's device id (none given, no replay device)");
    detector_ = params.get_string("detector");
    c_ = params.get_float("speed_of_sound_mps");
    if (c_ == 0.0) c_ = 331.3 * std::sqrt(1.0 + params.get_float("temperature_c") / 273.15);
    z_ = params.get_float("device_height_m");
    height_std_ = params.get_float("height_std_m");
    range_std_ = params.get_float("range_std_m");
    max_range_ = params.get_float("max_range_m");
    slack_s_ = params.get_float("sync_slack_s");
    los_thr_ = params.get_float("los_threshold");
    init_window_s_ = params.get_float("init_window_s");
    reinit_after_ = static_cast<int>(params.get_int("reinit_after"));
    std_scale_ = params.get_float("std_scale");
    std_floor_ = params.get_float("std_floor_m");
    nlos_bias_m_ = params.get_float("nlos_bias_m");
    nlos_excess_max_m_ = params.get_float("nlos_excess_max_m");
    decay_evidence_scale_ = params.get_float("decay_evidence_scale");
    tcfg_.accel_std_mps2 = params.get_float("accel_std_mps2");
    tcfg_.max_speed_mps = params.get_float("max_speed_mps");
    tcfg_.gate_sigma = params.get_float("gate_sigma");
    tcfg_.gate_long_sigma = params.get_float("gate_long_sigma");
    dead_reckoning_ = params.get_bool("dead_reckoning");
    n_hyp_ = static_cast<int>(params.get_int("heading_hypotheses"));
    publish_steps_ = params.get_bool("publish_steps");
    stride_scale_max_std_ = params.get_float("stride_scale_max_std");
    prune_loglik_ = params.get_float("prune_loglik");
    hold_s_ = params.get_float("step_wait_s");
    pdr_std_scale_ = params.get_float("pdr_std_scale");
    pcfg_.stride_std_frac = params.get_float("stride_std");
    pcfg_.heading_std_rad = params.get_float("step_heading_std_rad");
    pcfg_.gate_sigma = tcfg_.gate_sigma;
    pcfg_.gate_long_sigma = tcfg_.gate_long_sigma;
    pcfg_.huber_sigma = params.get_float("range_huber_sigma");
    region_ = params.get_floats("region_m");
    if (!region_.empty() && (region_.size() != 4 || !(region_[2] > region_[0]) || !(region_[3] > region_[1])))
      throw std::runtime_error("spyloc: param 'region_m': expected [x_min, y_min, x_max, y_max] with max > min, or []");
    const std::vector<double>& tones = params.get_floats("tones_hz");

    if (ctx.geometry == nullptr || ctx.geometry->scene_emits.empty())
      throw std::runtime_error("spyloc: no scene geometry: the beacons (anchored multitone emitters with sync_delay_s) "
                               "come from the scene (locus replay SCENE)");
    for (const SceneSignal& s : ctx.geometry->scene_emits) {
      if (s.signal.type != "multitone") continue;
      const std::string what = "spyloc: scene emitter '" + s.id + "'";
      if (!s.has_anchor) {
        ctx.log.warn(what + ": multitone without an anchor: not a beacon, ignored");
        continue;
      }
      if (!s.signal.sync_delay_s) throw std::runtime_error(what + ": field 'sync_delay_s': a beacon's multitone needs its sync-to-beep delay");
      Beacon b;
      b.id = s.id;
      b.anchor = s.anchor_m;
      b.delay_s = *s.signal.sync_delay_s;
      for (double f : s.signal.tones_hz) {
        std::size_t k = tones.size();
        for (std::size_t i = 0; i < tones.size(); ++i)
          if (std::fabs(tones[i] - f) < 0.5) k = i;
        if (k == tones.size())
          throw std::runtime_error(what + ": field 'tones_hz': " + std::to_string(f) + " Hz is not in the tone grid (param tones_hz)");
        b.mask |= 1u << k;
      }
      for (const Beacon& o : beacons_)
        if (o.mask == b.mask) throw std::runtime_error(what + ": same tone set as beacon '" + o.id + "': beeps could not be told apart");
      beacons_.push_back(std::move(b));
    }
    if (beacons_.size() < 3)
      throw std::runtime_error("spyloc: the scene declares " + std::to_string(beacons_.size()) +
                               " anchored multitone beacons; at least 3 are needed for a fix");
    const std::string model = params.get_string("los_model");
    if (!model.empty()) {
      if (model == "builtin")
        classifier_.load_text(LosClassifier::builtin_text(), "builtin LoS/NLoS model (config/spyloc-los.yaml)");
      else
        classifier_.load(find_model(model));
    } else {
      ctx.log.warn("spyloc: no los_model: every beep is taken as LoS (only the innovation gate rejects NLoS ranges)");
    }
    tracker_ = Tracker(tcfg_);
  }

  /// [main]
  std::vector<EventType> subscriptions() const override {
    if (dead_reckoning_)
      return {EventType::RadioSync, EventType::AudioDetection, EventType::DecayFeatures, EventType::Step,
              EventType::Attitude};
    return {EventType::RadioSync, EventType::AudioDetection, EventType::DecayFeatures};
  }

  /// [main]
  void on_event(const Event& event, Publisher& out) override {
    if (const auto* s = std::get_if<RadioSync>(&event)) {
      if (s->device.view() != device_) return;
      for (Beacon& b : beacons_)
        if (s->source.view() == b.id) {
          b.syncs.push_back(s->t_s);
          while (b.syncs.size() > 16) b.syncs.pop_front();
        }
    } else if (const auto* d = std::get_if<AudioDetection>(&event)) {
      if (d->device.view() != device_ || !(d->sample_rate_hz > 0)) return;
      if (!detector_.empty() && d->detector.view() != detector_) return;
      for (std::size_t i = 0; i < beacons_.size(); ++i)
        if (beacons_[i].mask == d->template_index) {
          pending_.push_back(PendingBeep{d->frame, d->frame / d->sample_rate_hz, i});
          while (pending_.size() > 8) pending_.pop_front();
          return;
        }
      ++unknown_;
    } else if (const auto* a = std::get_if<Attitude>(&event)) {
      if (a->device.view() != device_) return;
      dr_.add_heading(a->t_s, a->heading_rad);
    } else if (const auto* st = std::get_if<Step>(&event)) {
      if (st->device.view() != device_) return;
      if (dr_.add_step(st->t_s, st->stride_m, st->frequency_hz)) {
        ++steps_;
        latest_t_ = std::max(latest_t_, st->t_s);
        flush_ranges(out, false);
        if (publish_steps_) {  // the step again, its stride scaled by what ranging learnt (k)
          Step calibrated = *st;
          calibrated.detector = NameTag(instance_);
          if (pdr_active()) {
            const PdrTracker& best = hyps_[best_hyp()].tracker;
            if (best.stride_scale_std() <= stride_scale_max_std_ && pdr_spread_m() <= 1.0)
              calibrated.stride_m = static_cast<float>(st->stride_m * best.stride_scale());
          }
          out.publish(Event{calibrated});
        }
      }
    } else if (const auto* f = std::get_if<DecayFeatures>(&event)) {
      if (f->device.view() != device_) return;
      if (!detector_.empty() && f->detector.view() != detector_) return;
      for (auto it = pending_.begin(); it != pending_.end(); ++it)
        if (it->frame == f->frame) {
          const PendingBeep p = *it;
          pending_.erase(it);
          DecayVector v;
          for (std::size_t k = 0; k < kDecayFeatures; ++k) v[k] = f->decay_s[k];
          beep(p, v, out);
          return;
        }
    }
  }

  /// [main]
  void finish(Publisher& out) override {
    flush_ranges(out, true);
    if (log_) {
      log_->info("spyloc " + instance_ + ": " + std::to_string(beeps_) + " beeps, " + std::to_string(no_sync_) +
                 " without a sync, " + std::to_string(nlos_) + " NLoS (" + std::to_string(too_long_) +
                 " of them too long for the track), " + std::to_string(cleared_) + " cleared as LoS by the track, " +
                 std::to_string(gated_) + " ranges gated out, " +
                 std::to_string(inits_) + " fixes, " + std::to_string(published_) + " estimates");
      if (pdr_active()) {
        const PdrTracker& t = hyps_[best_hyp()].tracker;
        log_->info("spyloc " + instance_ + ": dead reckoning from t = " + std::to_string(pdr_since_s_) + " s (" +
                   std::to_string(steps_) + " steps, " + std::to_string(hyps_.size()) + " of " + std::to_string(n_hyp_) +
                   " heading hypotheses left): heading offset " + std::to_string(t.psi_rad() * 180.0 / M_PI) + " deg +- " +
                   std::to_string(t.psi_std_rad() * 180.0 / M_PI) + ", stride scale " + std::to_string(t.stride_scale()));
      } else if (dead_reckoning_) {
        log_->info("spyloc " + instance_ + ": no dead reckoning (" + std::to_string(steps_) +
                   " steps: no fix after the first step)");
      }
    }
  }

 private:
  void beep(const PendingBeep& p, const DecayVector& decay, Publisher& out) {
    ++beeps_;
    Beacon& b = beacons_[p.beacon];
    // The latest sync that can precede this beep.
    std::optional<double> sync;
    for (auto it = b.syncs.rbegin(); it != b.syncs.rend(); ++it) {
      const double tof = p.t_s - *it - b.delay_s;
      if (tof >= -slack_s_ && tof <= max_range_ / c_) {
        sync = *it;
        break;
      }
    }
    if (!sync) {
      ++no_sync_;
      return;
    }
    const double range = std::max(0.0, c_ * (p.t_s - *sync - b.delay_s));
    const double pl_decay = classifier_.ready() ? classifier_.p_los(decay) : 1.0;
    const double dz = b.anchor[2] - z_;
    const double var = range_std_ * range_std_ + std::pow(dz * height_std_ / std::max(range, 1.0), 2);
    if (dead_reckoning_ && !pdr_active() && dr_.steps() > 0 && tracker_.initialised()) {
      tracker_.predict(p.t_s);
      start_pdr(p.t_s, tracker_.position(), tracker_.position_cov());
    }
    if (pdr_active()) {
      queued_.push_back(RangeMeas{p.t_s, p.beacon, range, 0.0, pl_decay, var, true});
      latest_t_ = std::max(latest_t_, p.t_s);
      flush_ranges(out, false);
      return;
    }
    // The verdict: the decay's, weighed by what the track predicts for this range once there is one.
    if (tracker_.initialised()) tracker_.predict(p.t_s);
    const double pl = tracker_.initialised() ? verdict(pl_decay, tracker_.predict_range(b.anchor, z_), range, var) : pl_decay;
    bool los = pl >= los_thr_;
    if (!los) ++nlos_;
    if (los && pl_decay < los_thr_) ++cleared_;
    // An uncertain verdict carries the NLoS bias it may hide as variance: + (1 − P(LoS))·nlos_bias_m².
    const double sd = std::sqrt(var + (1.0 - pl) * nlos_bias_m_ * nlos_bias_m_);
    bool gated = false;
    if (!tracker_.initialised()) {
      if (!los) return;
      init_.push_back(InitRange{p.beacon, p.t_s, range});
      while (!init_.empty() && p.t_s - init_.front().t_s > init_window_s_) init_.pop_front();
      if (!try_init(p.t_s)) return;
    } else {
      if (los) {
        const double predicted = tracker_.predict_range(b.anchor, z_).range_m;
        init_.push_back(InitRange{p.beacon, p.t_s, range});
        while (!init_.empty() && p.t_s - init_.front().t_s > init_window_s_) init_.pop_front();
        double nis = 0.0;
        const bool ok = tracker_.update_range(b.anchor, z_, range, sd, nis);
        recent_.push_back(!ok);
        while (recent_.size() > static_cast<std::size_t>(2 * reinit_after_)) recent_.pop_front();
        int recent_rejects = 0;
        for (bool r : recent_) recent_rejects += r;
        if (!ok) {
          gated = true;
          ++gated_;
          // Gated out as too long: what an NLoS beep looks like; it was not used as LoS, and says so.
          if (range > predicted) {
            los = false;
            ++nlos_;
            ++too_long_;
          }
          // Lost: reinit_after gated-out LoS ranges among the last 2·reinit_after (a track in a mirror
          // image keeps agreeing with the beacons of one line, so consecutive counts would miss it):
          // a new fix from the recent LoS ranges of all beacons.
          if (recent_rejects >= reinit_after_) {
            last_xy_ = tracker_.position();
            have_last_ = true;
            tracker_ = Tracker(tcfg_);
            recent_.clear();
            if (!try_init(p.t_s)) return;
          }
        }
      }
    }
    publish(p.t_s, los, gated, out);
  }

  /// Dead reckoning starts at the track's current fix with one hypothesis per heading offset ψ
  /// (the rotation from the phone's relative heading to the world is unknown: n_hyp evenly spaced,
  /// each ± half the spacing) and stride scale 1 ± 0.15; the ranges weigh them (a Gaussian sum:
  /// each hypothesis an EKF, its weight the likelihood of the ranges it saw).
  void start_pdr(double t, const std::array<double, 2>& xy, const std::array<double, 3>& cov) {
    hyps_.clear();
    for (int i = 0; i < n_hyp_; ++i) {
      PdrTracker p(pcfg_);
      p.init(xy, cov, -M_PI + 2.0 * M_PI * (i + 0.5) / n_hyp_, M_PI / n_hyp_, 1.0, 0.15);
      hyps_.push_back(Hypothesis{p, 0.0});
    }
    const Eigen::Vector2d d = dr_.position_at(t);
    applied_dr_ = d;
    pdr_since_s_ = t;
  }
  bool pdr_active() const noexcept { return !hyps_.empty(); }
  /// P(LoS) of a range against a track's prediction (fuse_los; `nlos_excess_max_m` 0: the decay's alone).
  /// The track only clears beeps the decay calls NLoS, and only while it is not ambiguous (its mirror
  /// fix or heading hypotheses disagree by more than 1 m): one the decay calls LoS keeps its P(LoS) and
  /// is left to the gate, so that a track that drifted still sees the ranges that disagree with it, and
  /// an ambiguous track cannot confirm itself with NLoS ranges (either lost seed 103's track:
  /// p90 0.70 -> 2.7 m, docs/spyloc.md "LoS/NLoS verdict").
  double verdict(double p_los_decay, const RangePrediction& pred, double range_m, double range_var_m2) const {
    if (pdr_active() ? pdr_spread_m() > 1.0 : ambiguous_) return p_los_decay;
    // The decay's log-odds tempered (decay_evidence_scale, temper_los) before the innovation weighs them.
    return std::max(p_los_decay, fuse_los(temper_los(p_los_decay, decay_evidence_scale_), range_m - pred.range_m,
                                          std::sqrt(pred.var_m2 + range_var_m2), nlos_excess_max_m_));
  }
  /// Dead reckoning: how far the hypotheses nearly as likely as the best (within 3 in log-likelihood)
  /// are from it.
  double pdr_spread_m() const {
    const std::size_t b = best_hyp();
    const auto xy = hyps_[b].tracker.position();
    double spread = 0.0;
    for (const Hypothesis& h : hyps_)
      if (h.loglik >= hyps_[b].loglik - 3.0) {
        const auto q = h.tracker.position();
        spread = std::max(spread, std::hypot(q[0] - xy[0], q[1] - xy[1]));
      }
    return spread;
  }
  std::size_t best_hyp() const {
    std::size_t b = 0;
    for (std::size_t i = 1; i < hyps_.size(); ++i)
      if (hyps_[i].loglik > hyps_[b].loglik) b = i;
    return b;
  }

  /// PDR mode: the queued ranges whose time the steps already cover (or older than step_wait_s:
  /// the walker stands), in time order; all of them at the end.
  void flush_ranges(Publisher& out, bool all) {
    if (!pdr_active() || queued_.empty()) return;
    std::sort(queued_.begin(), queued_.end(), [](const RangeMeas& x, const RangeMeas& y) { return x.t_s < y.t_s; });
    const double covered = dr_.steps() > 0 ? dr_.step_end_s(dr_.steps() - 1) : -1e300;
    while (!queued_.empty()) {
      const RangeMeas m = queued_.front();
      if (!all && m.t_s > covered && m.t_s > latest_t_ - hold_s_) break;
      queued_.pop_front();
      pdr_range(m, out);
    }
  }

  void pdr_range(RangeMeas m, Publisher& out) {
    const Eigen::Vector2d d = dr_.position_at(m.t_s);
    for (Hypothesis& h : hyps_) h.tracker.step({d.x() - applied_dr_.x(), d.y() - applied_dr_.y()});
    applied_dr_ = d;
    {  // the verdict against the most likely hypothesis' track
      const auto& bp = beacons_[m.beacon].anchor;
      const double pl = verdict(m.p_los_decay, hyps_[best_hyp()].tracker.predict_range(bp, z_), m.range_m, m.range_var_m2);
      m.los = pl >= los_thr_;
      if (!m.los) ++nlos_;
      if (m.los && m.p_los_decay < los_thr_) ++cleared_;
      m.std_m = std::sqrt(m.range_var_m2 + (1.0 - pl) * nlos_bias_m_ * nlos_bias_m_);
    }
    bool gated = false;
    if (m.los) {
      const auto& bp = beacons_[m.beacon].anchor;
      std::vector<char> ok(hyps_.size()), too_long(hyps_.size());
      for (std::size_t i = 0; i < hyps_.size(); ++i) {
        PdrTracker& t = hyps_[i].tracker;
        const auto xy = t.position();
        const double predicted = std::sqrt(std::pow(xy[0] - bp[0], 2) + std::pow(xy[1] - bp[1], 2) + std::pow(z_ - bp[2], 2));
        double nis = 0.0;
        ok[i] = t.update_range(bp, z_, m.range_m, m.std_m, nis);
        too_long[i] = !ok[i] && m.range_m > predicted;
        // The range's likelihood under this hypothesis; a gated-out one costs what the gate allows
        // (an NLoS beep must not decide between hypotheses on its own).
        const double g = too_long[i] ? pcfg_.gate_long_sigma : pcfg_.gate_sigma;
        hyps_[i].loglik += -0.5 * (ok[i] ? nis : g * g) - 0.5 * std::log(t.last_innovation_var());
      }
      const std::size_t b = best_hyp();
      // Hypotheses far less likely than the best are dropped (never the best).
      std::vector<Hypothesis> kept;
      for (const Hypothesis& h : hyps_)
        if (h.loglik >= hyps_[b].loglik - prune_loglik_) kept.push_back(h);
      const bool b_ok = ok[b], b_long = too_long[b];
      if (b_long) {  // gated out as too long: not used as LoS, and the verdict says so
        m.los = false;
        ++nlos_;
        ++too_long_;
      }
      hyps_ = std::move(kept);
      // A range longer than the best track allows is what an NLoS beep the classifier missed looks
      // like: no sign that the track is lost, and kept out of a next fix. Too SHORT ranges (no path
      // is shorter than the direct one), or nearly every range rejected, say the track is wrong.
      if (!b_long) {
        init_.push_back(InitRange{m.beacon, m.t_s, m.range_m});
        while (!init_.empty() && m.t_s - init_.front().t_s > init_window_s_) init_.pop_front();
        pool_.push_back(InitRange{m.beacon, m.t_s, m.range_m});
        while (!pool_.empty() && m.t_s - pool_.front().t_s > pdr_fix_window_s_) pool_.pop_front();
      }
      // A too-long range (taken for an NLoS beep the classifier missed) says nothing either way: it is
      // left out of the window instead of counting as a range that agreed.
      if (!b_long) recent_.push_back(!b_ok);
      while (recent_.size() > static_cast<std::size_t>(2 * reinit_after_)) recent_.pop_front();
      if (b_ok) {
        rejected_run_ = 0;
        rejected_beacons_ = 0;
      } else {
        ++rejected_run_;
        rejected_beacons_ |= 1u << (m.beacon % 32);
      }
      int recent_rejects = 0;
      for (bool r : recent_) recent_rejects += r;
      if (!b_ok) {
        gated = true;
        ++gated_;
        // Lost: too-short ranges, or every range of two or more beacons rejected for a while (a track
        // that drifted away sees the true ranges as "too long" too).
        const bool all_rejected = rejected_run_ >= 2 * reinit_after_ && std::popcount(rejected_beacons_) >= 2;
        if (recent_rejects >= reinit_after_ || all_rejected) {  // a new fix
          last_xy_ = hyps_[best_hyp()].tracker.position();
          have_last_ = true;
          tracker_ = Tracker(tcfg_);
          recent_.clear();
          rejected_run_ = 0;
          rejected_beacons_ = 0;
          if (const auto fix = pdr_fix(m.t_s)) {
            for (Hypothesis& h : hyps_) h.tracker.reset_position(fix->xy_m, fix->cov, 0.1);
            ++inits_;
          }
        }
      }
    }
    publish(m.t_s, m.los, gated, out);
  }

  /// A new position at t from the ranges of the last pdr_fix_window_s, each moved to time t by the
  /// walker's own steps (best hypothesis' ψ and k): a range r_i at t_i to beacon b_i is a range at t
  /// to the "virtual" beacon b_i + k·R(ψ)·(dr(t) − dr(t_i)). Walking, one beacon gives several such
  /// beacons (a synthetic aperture), so a fix no longer needs three beacons within init_window_s.
  /// Of a fix's mirror images, the one nearest the current track.
  std::optional<Fix> pdr_fix(double t) {
    if (pool_.size() < 3) return std::nullopt;
    const PdrTracker& best = hyps_[best_hyp()].tracker;
    const double c = std::cos(best.psi_rad()), sn = std::sin(best.psi_rad()), k = best.stride_scale();
    const Eigen::Vector2d dt_now = dr_.position_at(t);
    std::vector<RangeObs> obs;
    for (const InitRange& r : pool_) {
      const Eigen::Vector2d d = dt_now - dr_.position_at(r.t_s);
      RangeObs o;
      o.beacon_m = beacons_[r.beacon].anchor;
      o.beacon_m[0] += k * (c * d.x() - sn * d.y());
      o.beacon_m[1] += k * (sn * d.x() + c * d.y());
      o.range_m = r.range_m;
      o.std_m = std::hypot(range_std_, 0.1 * d.norm());  // the steps' own error over that walk
      obs.push_back(o);
    }
    std::vector<Fix> fixes = trilaterate(obs, z_);
    if (fixes.empty()) return std::nullopt;
    const auto cur = best.position();
    const Fix* pick = &fixes[0];
    for (const Fix& f : fixes)
      if (std::hypot(f.xy_m[0] - cur[0], f.xy_m[1] - cur[1]) < std::hypot(pick->xy_m[0] - cur[0], pick->xy_m[1] - cur[1]) &&
          f.rms_residual_m < 2.0 * fixes[0].rms_residual_m + 0.1)
        pick = &f;
    if (pick->rms_residual_m > 0.5) return std::nullopt;  // the ranges disagree: keep the track
    return *pick;
  }

  bool try_init(double t) {
    // Latest range per beacon.
    std::map<std::size_t, InitRange> latest;
    for (const InitRange& r : init_) latest[r.beacon] = r;
    if (latest.size() < 3) return false;
    std::vector<RangeObs> obs;
    double span = 0.0;
    for (const auto& [i, r] : latest) {
      RangeObs o;
      o.beacon_m = beacons_[i].anchor;
      o.range_m = r.range_m;
      // The walker moved between the beeps: their age widens them (walking speed ~1.4 m/s).
      o.std_m = std::hypot(range_std_, 1.4 * (t - r.t_s));
      obs.push_back(o);
      span = std::max(span, t - r.t_s);
    }
    std::vector<Fix> fixes = trilaterate(obs, z_);
    if (fixes.empty()) return false;
    Fix best = fixes[0];
    ambiguous_ = false;
    if (fixes.size() > 1 && fixes[1].rms_residual_m < 2.0 * fixes[0].rms_residual_m + 0.1) {
      ambiguous_ = true;
      auto score = [&](const Fix& f) {
        if (have_last_) return -std::hypot(f.xy_m[0] - last_xy_[0], f.xy_m[1] - last_xy_[1]);  // continuity
        if (region_.size() == 4) {
          const double dx = std::max({region_[0] - f.xy_m[0], 0.0, f.xy_m[0] - region_[2]});
          const double dy = std::max({region_[1] - f.xy_m[1], 0.0, f.xy_m[1] - region_[3]});
          return -std::hypot(dx, dy);
        }
        return std::min(f.xy_m[0], f.xy_m[1]);
      };
      if (score(fixes[1]) > score(fixes[0])) best = fixes[1];
    }
    // A poor fit (ranges inconsistent: an NLoS beep taken for LoS, or too much motion): wait.
    if (best.rms_residual_m > 1.0) {
      init_.pop_front();
      return false;
    }
    std::array<double, 3> cov = best.cov;
    const double motion2 = std::pow(0.7 * span, 2);  // half the walk since the oldest range
    cov[0] += motion2;
    cov[2] += motion2;
    tracker_.init(t, best.xy_m, cov, 1.5);
    ++inits_;
    recent_.clear();
    return true;
  }

  void publish(double t, bool los, bool gated, Publisher& out) {
    Estimate e;
    e.plugin = NameTag(instance_);
    e.reference = DeviceId("");
    e.frame = NameTag("world");
    e.target = NameTag(device_);
    e.t_s = t;
    const bool pdr = pdr_active();
    const std::size_t b = pdr ? best_hyp() : 0;
    const auto xy = pdr ? hyps_[b].tracker.position() : tracker_.position();
    e.position_m = {xy[0], xy[1], z_};
    e.dims = 2;
    e.std_m = std::max(std_floor_, pdr ? pdr_std_scale_ * hyps_[b].tracker.position_std() : std_scale_ * tracker_.position_std());
    bool pdr_ambiguous = false;
    if (pdr) {  // other heading hypotheses nearly as likely elsewhere: say so, and widen the std
      const double spread = pdr_spread_m();
      if (spread > 1.0) pdr_ambiguous = true;
      e.std_m = std::hypot(e.std_m, spread);
    }
    double conf = std::exp(-e.std_m / 1.0);
    // The fix's mirror ambiguity matters until dead reckoning weighs the track; then only the
    // hypotheses' disagreement does.
    if (pdr ? pdr_ambiguous : ambiguous_) {
      e.flags |= kEstimateAmbiguous;
      conf *= 0.5;
    }
    if (gated) {
      e.flags |= kEstimateInconsistent;
      conf *= 0.5;
    }
    e.confidence = static_cast<float>(conf);
    e.los = los ? 1 : 0;
    out.publish(Event{e});
    ++published_;
  }

  Logger* log_ = nullptr;
  std::string instance_, device_, detector_;
  double c_ = 343.2, z_ = 1.2, height_std_ = 0.25, range_std_ = 0.08, max_range_ = 40.0, slack_s_ = 0.002;
  double nlos_bias_m_ = 0.0, nlos_excess_max_m_ = 8.0, decay_evidence_scale_ = 0.3;
  double los_thr_ = 0.5, init_window_s_ = 1.5, std_scale_ = 1.42, std_floor_ = 0.05;
  int reinit_after_ = 3;
  std::vector<double> region_;
  TrackerConfig tcfg_;
  PdrConfig pcfg_;
  bool dead_reckoning_ = true, publish_steps_ = true;
  double stride_scale_max_std_ = 0.08;
  struct Hypothesis {
    PdrTracker tracker;
    double loglik = 0.0;
  };
  std::vector<Hypothesis> hyps_;
  int n_hyp_ = 12, rejected_run_ = 0;
  std::uint32_t rejected_beacons_ = 0;  ///< bit per beacon (mod 32) among the current run of rejections
  double prune_loglik_ = 15.0, hold_s_ = 1.5, pdr_std_scale_ = 1.38, pdr_since_s_ = 0.0;
  double latest_t_ = -1e300;
  dsp::DeadReckoning dr_;
  Eigen::Vector2d applied_dr_ = Eigen::Vector2d::Zero();
  std::deque<RangeMeas> queued_;
  std::uint64_t steps_ = 0;
  std::vector<Beacon> beacons_;
  std::deque<PendingBeep> pending_;
  std::deque<InitRange> init_;
  std::deque<InitRange> pool_;  ///< dead reckoning: LoS ranges of the last pdr_fix_window_s (not too long)
  double pdr_fix_window_s_ = 4.0;
  LosClassifier classifier_;
  Tracker tracker_;
  bool ambiguous_ = false;
  bool have_last_ = false;
  std::array<double, 2> last_xy_{};
  std::deque<bool> recent_;  ///< last LoS ranges: gated out?
  std::uint64_t cleared_ = 0, too_long_ = 0;  ///< verdicts the track changed (docs/spyloc.md "LoS/NLoS verdict")
  std::uint64_t beeps_ = 0, no_sync_ = 0, nlos_ = 0, gated_ = 0, inits_ = 0, published_ = 0, unknown_ = 0;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema s = {
      string_param("device", std::string(""), "The walker's device (default: the replay device)."),
      string_param("detector", std::string(""), "Instance name of the multitone detector to use (\"\" = any)."),
      float_list_param("tones_hz",
                       std::vector<double>{18000, 18250, 18500, 18750, 19000, 19250, 19500, 19750, 20000, 20250},
                       1.0, 100000.0, "Hz", "The detector's tone grid: a beacon's identity = its tones as bits of this list.", 1, 16),
      float_param("speed_of_sound_mps", 0.0, 0.0, 400.0, "m/s", "Speed of sound; 0 = from temperature_c."),
      float_param("temperature_c", 20.0, -30.0, 50.0, "degC", "Air temperature (speed of sound when not given)."),
      float_param("device_height_m", 1.2, 0.0, 3.0, "m", "Height of the phone's mic above the floor (z of the world frame)."),
      float_param("height_std_m", 0.25, 0.0, 2.0, "m", "Uncertainty of that height (widens the ranges of high beacons)."),
      float_param("range_std_m", 0.08, 0.001, 5.0, "m", "1-sigma range error of an LoS beep (sync jitter, first-path timing)."),
      float_param("max_range_m", 40.0, 1.0, 500.0, "m", "Longest range (pairs a beep with a sync)."),
      float_param("sync_slack_s", 0.002, 0.0, 0.1, "s", "A beep may come this much before sync + delay (radio latency, jitter)."),
      string_param("los_model", std::string(""), "LoS/NLoS model: builtin (config/spyloc-los.yaml as built), a file written by locus train spyloc (a relative path is looked up from the working directory, then its parents), or \"\" = every beep LoS, gate only."),
      float_param("los_threshold", 0.5, 0.0, 1.0, "", "P(LoS) at or above which a beep's range is used."),
      float_param("nlos_bias_m", 0.0, 0.0, 50.0, "m", "Typical excess of an NLoS range: a used range's variance grows by (1 - P(LoS))·this²."),
      float_param("nlos_excess_max_m", 8.0, 0.0, 100.0, "m",
                  "The verdict weighs the decay's P(LoS) by the range's innovation against the track: an NLoS range is "
                  "longer than predicted by up to this (uniform); 0 = the decay's verdict alone (docs/spyloc.md)."),
      float_param("decay_evidence_scale", 0.3, 0.05, 1.0, "",
                  "In that weighing, the decay's log-odds are scaled by this (its six decay times are correlated: the "
                  "naive-Bayes product overstates them)."),
      float_param("init_window_s", 1.5, 0.1, 30.0, "s", "LoS ranges of >= 3 beacons within this make the first fix."),
      int_param("reinit_after", std::int64_t{3}, 1, 1000, "", "Gated-out LoS ranges among the last 2x this many after which a new fix replaces the track."),
      float_param("accel_std_mps2", 0.6, 0.01, 50.0, "m/s^2", "White acceleration of the constant-velocity tracker."),
      float_param("max_speed_mps", 2.5, 0.1, 20.0, "m/s", "Speed cap of the tracker."),
      float_param("gate_sigma", 4.0, 1.0, 100.0, "", "Innovation gate (sigmas) of an LoS range shorter than predicted."),
      float_param("gate_long_sigma", 2.5, 0.5, 100.0, "", "Innovation gate (sigmas) of a range longer than predicted (NLoS paths are longer)."),
      float_list_param("region_m", std::vector<double>{}, -1e6, 1e6, "m",
                       "[x_min, y_min, x_max, y_max] where the walker can be (resolves the mirror fix of beacons in a line); [] = unknown.", 0, 4),
      float_param("std_scale", 1.42, 0.01, 100.0, "", "Scale of the filter's std (before dead reckoning starts); with pdr_std_scale, docs/spyloc.md \"Uncertainty\"."),
      float_param("std_floor_m", 0.05, 0.0, 10.0, "m", "Smallest reported std_m."),
      bool_param("dead_reckoning", true,
                 "Carry the track with the walker's steps (`step` events) and heading (`attitude` events) once they can be "
                 "aligned with the ranged track (the paper's PDR); without step events the constant-velocity tracker stays."),
      int_param("heading_hypotheses", std::int64_t{12}, 1, 72, "",
                "Dead reckoning: heading offsets tried at once (the phone's heading vs the world is unknown); the ranges weigh them."),
      bool_param("publish_steps", true,
                 "Dead reckoning: publish each step again (detector = this instance) with its stride scaled by the stride "
                 "scale ranging has learnt so far (unscaled before the first fix)."),
      float_param("stride_scale_max_std", 0.08, 0.0, 1.0, "",
                  "Dead reckoning: a published step's stride is scaled by the learnt stride scale k only once k's std is at most "
                  "this and the heading hypotheses agree (within 1 m); before, the step detector's stride (k = 1, the prior)."),
      float_param("prune_loglik", 15.0, 1.0, 1000.0, "", "Dead reckoning: a hypothesis this far (log-likelihood) below the best is dropped."),
      float_param("step_wait_s", 1.5, 0.0, 10.0, "s",
                  "Dead reckoning: a range waits until the steps up to its time are known, at most this long (a standing walker makes none)."),
      float_param("stride_std", 0.15, 0.0, 1.0, "", "Dead reckoning: per-step stride error (fraction of the stride)."),
      float_param("range_huber_sigma", 2.0, 0.0, 100.0, "",
                  "Dead reckoning: a LoS range more than this many sigmas off (inside the gate) is taken with the variance "
                  "that puts it this many sigmas out (a robust, Huber-like update; docs/spyloc.md); 0 = plain EKF update."),
      float_param("step_heading_std_rad", 0.12, 0.0, 1.0, "rad", "Dead reckoning: per-step direction error."),
      float_param("pdr_std_scale", 1.38, 0.01, 100.0, "", "Scale of the dead-reckoning filter's std (std_m = this x its position std): 2 std_m cover 95 % of the simulator's errors (docs/spyloc.md \"Uncertainty\")."),
  };
  return s;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "spyloc", "1",
      "SpyLoc: beacon ranging from radio sync + multitone beep, LoS/NLoS by decay, tracking (paper 001)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new SpyLocLocalizer); }};
  return &d;
}

}  // namespace locus::plugins::spyloc
