// The metric families. Each estimate is first "scored" the same way (target resolved, its time
// converted to true time through the truth clock, truth mapped into the estimate's frame or the
// estimate aligned to truth for relative frames); the families then aggregate differently.
#include "locus/eval/metrics.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>

#include "locus/angles.hpp"
#include "locus/eval/error.hpp"
#include "locus/eval/frames.hpp"

namespace locus::eval {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
using ojson = nlohmann::ordered_json;

ojson num(double v) { return std::isfinite(v) ? ojson(v) : ojson(nullptr); }

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

double mean_of(const std::vector<double>& v) {
  if (v.empty()) return kNaN;
  double s = 0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return percentile_sorted(v, 0.5);
}

double norm_dims(const Vec3& v, int dims) { return dims >= 3 ? v.norm() : v.head<2>().norm(); }

/// One estimate after target resolution, clock conversion and frame mapping.
struct Scored {
  const EstimateRecord* e = nullptr;
  std::string id;              ///< resolved truth id ("" = unknown target)
  FrameSpec frame;
  double t_true_s = kNaN;
  bool extrapolated = false;
  Vec3 truth_world = Vec3::Zero();
  Vec3 truth_frame = Vec3::Zero();  ///< truth in the estimate's frame (aligned frames: world)
  Vec3 est = Vec3::Zero();          ///< estimate (aligned frames: after alignment, in world)
  bool placed = false;              ///< truth_frame is valid (known frame placed from truth)
  bool positioned = false;          ///< est and truth_frame are comparable
  std::string unscored;             ///< reason it is not scored ("" = scored or pending)
  double error_m = kNaN;
};

struct Group {
  std::string plugin;
  std::vector<const EstimateRecord*> estimates;
};

/// Accumulates "reason → count, first line" so nothing is dropped silently.
struct ReasonLog {
  std::map<std::string, std::pair<std::size_t, int>> reasons;
  void add(const std::string& reason, int line) {
    auto [it, inserted] = reasons.try_emplace(reason, 0, line);
    ++it->second.first;
  }
};

class GroupScorer {
 public:
  GroupScorer(const TruthData& truth, const EstimatesFile& file, const EvalOptions& options, const Group& group, Family family)
      : truth_(truth), file_(file), options_(options), group_(group) {
    result_.family = family;
    result_.plugin = group.plugin;
  }

  GroupResult run() {
    score_all();
    align_relative();
    switch (result_.family) {
      case Family::Tum: tum(); break;
      case Family::Amil: amil(); break;
      case Family::Locble: position_family(/*final_only=*/true); break;
      case Family::Montage: position_family(false); montage_steps(); break;
      case Family::Spyloc: position_family(false); spyloc_extras(); break;
      case Family::Position: position_family(false); break;
    }
    finish();
    return std::move(result_);
  }

 private:
  // ---------------------------------------------------------------------------- common scoring
  void score_all() {
    std::set<std::string> refs, frames;
    for (const EstimateRecord* e : group_.estimates) {
      Scored s;
      s.e = e;
      s.frame = parse_frame(e->frame);  // validated by evaluate()
      if (!e->reference.empty()) refs.insert(e->reference);
      frames.insert(e->frame);
      auto id = truth_.resolve(e->target);
      if (!id) {
        s.unscored = "unknown target";
        unknown_[e->target].add("", e->line);
        scored_.push_back(std::move(s));
        continue;
      }
      s.id = *id;
      if (!truth_.has_truth(s.id)) {
        s.unscored = "no truth for target";
        scored_.push_back(std::move(s));
        continue;
      }
      // Time: estimates are on the reference's clock; world estimates on the target device's clock.
      std::string clock_id = e->reference;
      if (clock_id.empty()) {
        const TruthObject* o = truth_.find(s.id);
        if (o && o->is_device) clock_id = s.id;
      }
      s.t_true_s = clock_id.empty() ? e->t_s : truth_.clock(clock_id).true_from_local(e->t_s);
      auto track = truth_.tracks.find(s.id);
      s.extrapolated = track != truth_.tracks.end() && !track->second.covers(s.t_true_s);
      s.truth_world = truth_.pose(s.id, s.t_true_s)->position_m;
      if (e->has_position()) s.est = Vec3(e->position_m[0], e->position_m[1], e->dims == 3 ? e->position_m[2] : 0.0);
      if (!s.frame.aligned()) {
        try {
          const FramePlacement p = place_frame(s.frame, e->reference, s.t_true_s, truth_);
          s.truth_frame = p.to_frame(s.truth_world);
          s.placed = true;
          s.positioned = e->has_position();
        } catch (const std::runtime_error& err) {
          s.unscored = err.what();
          s.positioned = false;
        }
      }
      if (s.positioned) s.error_m = norm_dims(s.est - s.truth_frame, e->dims);
      scored_.push_back(std::move(s));
    }
    result_.references.assign(refs.begin(), refs.end());
    result_.frames.assign(frames.begin(), frames.end());
  }

  /// Aligns relative (per snapshot) and relative_trace (per plugin, reference and frame) estimates.
  void align_relative() {
    std::map<std::string, std::vector<Scored*>> sets;  // key → members
    std::map<std::string, std::vector<Scored*>> snapshots_by_rf;
    for (auto& s : scored_) {
      if (!s.frame.aligned() || !s.unscored.empty() || !s.e->has_position()) {
        if (s.frame.aligned() && s.unscored.empty()) s.unscored = "no position (relative frame)";
        continue;
      }
      const std::string rf = s.e->reference + "\x1f" + s.e->frame;
      if (s.frame.kind == FrameKind::RelativeTrace) sets[rf].push_back(&s);
      else snapshots_by_rf[rf].push_back(&s);
    }
    for (auto& [rf, members] : snapshots_by_rf) {
      std::stable_sort(members.begin(), members.end(), [](const Scored* a, const Scored* b) { return a->e->t_s < b->e->t_s; });
      std::size_t start = 0;
      for (std::size_t i = 1; i <= members.size(); ++i) {
        if (i == members.size() || members[i]->e->t_s - members[i - 1]->e->t_s > options_.snapshot_tolerance_s) {
          sets[rf + "\x1f" + std::to_string(start)] = std::vector<Scored*>(members.begin() + static_cast<long>(start),
                                                                          members.begin() + static_cast<long>(i));
          start = i;
        }
      }
    }
    for (auto& [key, members] : sets) {
      std::set<std::string> distinct;
      int dims = 3;
      for (const Scored* s : members) {
        distinct.insert(s->id);
        dims = std::min(dims, s->e->dims);
      }
      if (members.size() < 2) {
        for (Scored* s : members) s->unscored = "relative frame with a single point (nothing to align)";
        continue;
      }
      std::vector<Vec3> src, dst;
      for (const Scored* s : members) {
        src.push_back(s->est);
        dst.push_back(s->truth_world);
      }
      const RigidFit fit = fit_rigid(src, dst, dims);
      for (Scored* s : members) {
        s->est = fit.apply(s->est);
        s->truth_frame = s->truth_world;
        s->positioned = true;
        s->error_m = norm_dims(s->est - s->truth_frame, s->e->dims);
      }
    }
  }

  // ---------------------------------------------------------------------------- targets
  /// Targets a family expects to be located (ids with truth), scene order.
  std::vector<std::string> expected_targets() const {
    std::set<std::string> refs(result_.references.begin(), result_.references.end());
    std::set<std::string> estimated;
    for (const auto& s : scored_)
      if (!s.id.empty()) estimated.insert(s.id);
    std::vector<std::string> out;
    for (const TruthObject& o : truth_.objects) {
      if (!truth_.has_truth(o.id)) continue;
      bool want = false;
      switch (result_.family) {
        case Family::Tum: want = o.is_device && o.has_audio && (!refs.count(o.id) || estimated.count(o.id)); break;
        case Family::Amil: want = o.is_device && o.has_audio && !refs.count(o.id); break;
        case Family::Locble: want = !o.ble_addresses.empty() && !refs.count(o.id); break;
        case Family::Spyloc: want = o.is_device && o.has_audio && !o.anchor_m && !refs.count(o.id); break;
        case Family::Montage: want = o.is_device && o.has_imu; break;
        case Family::Position: want = !o.anchor_m && truth_.tracks.count(o.id) && (!refs.count(o.id) || estimated.count(o.id)); break;
      }
      if (want) out.push_back(o.id);
    }
    return out;
  }

  /// Rows in order: expected targets, then other estimated targets, then unknown targets.
  std::vector<std::string> row_order() const {
    std::vector<std::string> order = expected_targets();
    std::set<std::string> seen(order.begin(), order.end());
    for (const auto& s : scored_)
      if (!s.id.empty() && seen.insert(s.id).second) order.push_back(s.id);
    return order;
  }

  std::vector<const Scored*> of_target(const std::string& id) const {
    std::vector<const Scored*> out;
    for (const auto& s : scored_)
      if (s.id == id) out.push_back(&s);
    return out;
  }

  ojson row_start(const std::string& id, const std::vector<const Scored*>& members, bool located) {
    ojson row = ojson::object();
    row["target"] = id;
    const bool expected = expected_set().count(id) > 0;
    std::string status = "ok";
    if (members.empty()) status = "no estimate";
    else if (!located) status = "not scored";
    else if (!expected) status = "not expected";
    row["status"] = status;
    row["estimates"] = members.size();
    std::size_t scored = 0;
    for (const Scored* s : members)
      if (counts(*s)) ++scored;
    row["scored"] = scored;
    if (located) located_.insert(id);
    return row;
  }

  /// Scored: a position error exists, or (AMIL) a direction in a placed frame.
  bool counts(const Scored& s) const {
    if (s.positioned) return true;
    return result_.family == Family::Amil && s.placed && std::isfinite(s.e->direction_rad);
  }

  const std::set<std::string>& expected_set() {
    if (!expected_cache_) {
      auto v = expected_targets();
      expected_cache_ = std::set<std::string>(v.begin(), v.end());
    }
    return *expected_cache_;
  }

  // ---------------------------------------------------------------------------- position families
  void position_family(bool final_only) {
    std::vector<double> all, finals;
    for (const std::string& id : row_order()) {
      auto members = of_target(id);
      std::vector<double> errors;
      const Scored* last = nullptr;
      for (const Scored* s : members) {
        if (!s->positioned) continue;
        errors.push_back(s->error_m);
        if (!last || s->e->t_s >= last->e->t_s) last = s;
      }
      ojson row = row_start(id, members, !errors.empty());
      const Stats st = stats_of(errors);
      row["mean_error_m"] = num(st.mean);
      row["median_error_m"] = num(st.median);
      row["p90_error_m"] = num(st.p90);
      row["max_error_m"] = num(st.max);
      row["final_error_m"] = num(last ? last->error_m : kNaN);
      if (result_.family == Family::Montage) {
        double path = kNaN, pct = kNaN;
        auto track = truth_.tracks.find(id);
        if (last && track != truth_.tracks.end()) {
          double t0 = last->t_true_s;
          for (const Scored* s : members)
            if (s->positioned) t0 = std::min(t0, s->t_true_s);
          const auto& tr = track->second;
          path = tr.path_length_m(std::min(t0, tr.t_begin_s()), last->t_true_s, true);
          if (path > 0) pct = 100.0 * st.mean / path;
        }
        row["path_length_m"] = num(path);
        row["mean_error_pct_of_path"] = num(pct);
        if (std::isfinite(pct)) path_pcts_.push_back(pct);
      }
      if (last) finals.push_back(last->error_m);
      all.insert(all.end(), errors.begin(), errors.end());
      result_.targets.push_back(std::move(row));
    }
    const Stats st = stats_of(final_only ? finals : all);
    auto& sum = result_.summary;
    if (final_only) sum["all_estimates_mean_error_m"] = num(mean_of(all));
    sum["mean_error_m"] = num(st.mean);
    sum["median_error_m"] = num(st.median);
    sum["p80_error_m"] = num(st.p80);
    sum["p90_error_m"] = num(st.p90);
    sum["max_error_m"] = num(st.max);
    sum["rms_error_m"] = num(st.rms);
    if (result_.family == Family::Montage) sum["mean_error_pct_of_path"] = num(mean_of(path_pcts_));
    position_errors_ = std::move(all);
  }

  void spyloc_extras() {
    std::vector<double> sorted = position_errors_;
    std::sort(sorted.begin(), sorted.end());
    ojson cdf = ojson::array();
    for (int k = 1; k <= 20; ++k) {
      const double q = k / 20.0;
      cdf.push_back({{"fraction", q}, {"error_m", num(percentile_sorted(sorted, q))}});
    }
    result_.details["cdf"] = cdf;
    // LoS/NLoS: the estimate's own `los` flag, else the truth of the most recent beep before it.
    std::vector<double> los, nlos;
    std::size_t flagged = 0, from_truth = 0;
    for (const auto& s : scored_) {
      if (!s.positioned) continue;
      std::optional<bool> flag = s.e->los;
      if (!flag && truth_.los && !truth_.los->empty()) {
        const auto& beeps = *truth_.los;
        auto it = std::upper_bound(beeps.begin(), beeps.end(), s.t_true_s,
                                   [](double t, const TruthLos& b) { return t < b.t_true_s; });
        if (it != beeps.begin()) {
          flag = std::prev(it)->los;
          ++from_truth;
        }
      }
      if (!flag) continue;
      ++flagged;
      (*flag ? los : nlos).push_back(s.error_m);
    }
    if (flagged == 0) {
      result_.details["los_nlos"] = "no estimate carries a `los` flag and the scene has no truth_los.csv";
      return;
    }
    result_.details["los_source"] = from_truth == 0 ? "estimates" : from_truth == flagged ? "truth_los.csv (most recent beep)" : "mixed";
    auto& sum = result_.summary;
    for (auto [name, v] : {std::pair<const char*, std::vector<double>*>{"los", &los}, {"nlos", &nlos}}) {
      const Stats st = stats_of(*v);
      sum[std::string(name) + "_estimates"] = st.n;
      sum[std::string(name) + "_median_error_m"] = num(st.median);
      sum[std::string(name) + "_p80_error_m"] = num(st.p80);
      sum[std::string(name) + "_p90_error_m"] = num(st.p90);
    }
  }

  // ---------------------------------------------------------------------------- Montage strides
  void montage_steps() {
    auto& sum = result_.summary;
    if (!truth_.steps) {
      result_.warnings.push_back("the scene has no truth_steps.csv: stride error not scored");
      sum["mean_stride_error_m"] = nullptr;
      return;
    }
    std::map<std::string, std::vector<double>> true_t;  // per device, sorted
    std::map<std::string, std::vector<double>> true_stride;
    {
      std::map<std::string, std::vector<std::pair<double, double>>> by;
      for (const TruthStep& s : *truth_.steps) by[s.id].emplace_back(s.t_true_s, s.stride_m);
      for (auto& [id, v] : by) {
        std::sort(v.begin(), v.end());
        for (auto& [t, l] : v) {
          true_t[id].push_back(t);
          true_stride[id].push_back(l);
        }
      }
    }
    std::map<std::string, std::vector<const StepRecord*>> detected;
    for (const StepRecord& s : file_.steps) detected[s.device].push_back(&s);
    std::size_t n_true = 0, n_detected = file_.steps.size(), n_matched = 0, n_unknown = 0;
    for (const auto& [id, v] : true_t) n_true += v.size();
    std::vector<double> all_errors;
    ojson per_device = ojson::array();
    std::set<std::string> devices;
    for (const auto& [id, v] : true_t) devices.insert(id);
    for (const auto& [id, v] : detected) devices.insert(id);
    for (const std::string& dev : devices) {
      auto det = detected[dev];
      const auto& tt = true_t[dev];
      const auto& ts = true_stride[dev];
      if (!truth_.find(dev) && !truth_.tracks.count(dev)) n_unknown += det.size();
      const ClockModel clock = truth_.clock(dev);
      std::vector<std::pair<double, const StepRecord*>> d;
      for (const StepRecord* s : det) d.emplace_back(clock.true_from_local(s->t_s), s);
      std::sort(d.begin(), d.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      std::vector<bool> used(tt.size(), false);
      std::vector<double> errors;
      std::size_t matched = 0;
      for (const auto& [t, s] : d) {
        // nearest unused true step within the tolerance
        auto it = std::lower_bound(tt.begin(), tt.end(), t);
        long best = -1;
        double best_dt = options_.step_match_tolerance_s;
        for (long k = static_cast<long>(it - tt.begin()) - 2; k <= static_cast<long>(it - tt.begin()) + 1; ++k) {
          if (k < 0 || k >= static_cast<long>(tt.size()) || used[static_cast<std::size_t>(k)]) continue;
          const double dt = std::abs(tt[static_cast<std::size_t>(k)] - t);
          if (dt <= best_dt) {
            best_dt = dt;
            best = k;
          }
        }
        if (best < 0) continue;
        used[static_cast<std::size_t>(best)] = true;
        ++matched;
        if (std::isfinite(s->stride_m)) errors.push_back(std::abs(s->stride_m - ts[static_cast<std::size_t>(best)]));
      }
      n_matched += matched;
      const Stats st = stats_of(errors);
      all_errors.insert(all_errors.end(), errors.begin(), errors.end());
      per_device.push_back({{"device", dev}, {"steps_true", tt.size()}, {"steps_detected", d.size()}, {"steps_matched", matched},
                            {"strides_scored", errors.size()}, {"mean_stride_error_m", num(st.mean)}, {"max_stride_error_m", num(st.max)}});
      for (auto& row : result_.targets) {
        if (row["target"] == dev) {
          row["steps_matched"] = matched;
          row["mean_stride_error_m"] = num(st.mean);
        }
      }
    }
    const Stats st = stats_of(all_errors);
    sum["steps_true"] = n_true;
    sum["steps_detected"] = n_detected;
    sum["steps_matched"] = n_matched;
    sum["steps_missed"] = n_true - n_matched;
    sum["steps_extra"] = n_detected - n_matched;
    sum["strides_scored"] = st.n;
    sum["mean_stride_error_m"] = num(st.mean);
    sum["median_stride_error_m"] = num(st.median);
    sum["max_stride_error_m"] = num(st.max);
    result_.details["steps"] = per_device;
    if (n_unknown) result_.warnings.push_back(std::to_string(n_unknown) + " step events come from devices the scene does not have");
  }

  // ---------------------------------------------------------------------------- AMIL
  void amil() {
    std::vector<double> dir_all, dist_all, pct_all, pos_all;
    for (const std::string& id : row_order()) {
      auto members = of_target(id);
      std::vector<double> dir, dist, pct, pos;
      double true_dist = kNaN, true_dir = kNaN;
      for (const Scored* s : members) {
        if (!counts(*s)) continue;
        const Vec3 truth_v = s->truth_frame;
        const double td = truth_v.head<2>().norm();
        const double tdir = std::atan2(truth_v.y(), truth_v.x());
        double edir = kNaN, edist = kNaN;
        if (std::isfinite(s->e->direction_rad) && !s->frame.aligned()) edir = s->e->direction_rad;
        else if (s->e->has_position()) edir = std::atan2(s->est.y(), s->est.x());
        if (std::isfinite(s->e->distance_m) && !s->frame.aligned()) edist = s->e->distance_m;
        else if (s->e->has_position()) edist = s->est.head<2>().norm();
        true_dist = td;
        true_dir = tdir;
        if (std::isfinite(edir)) dir.push_back(std::abs(wrap_pi(edir - tdir)) * 180.0 / std::numbers::pi);
        if (std::isfinite(edist)) {
          dist.push_back(std::abs(edist - td));
          if (td > 0) pct.push_back(100.0 * std::abs(edist - td) / td);
        }
        if (s->positioned) pos.push_back(s->error_m);
      }
      ojson row = row_start(id, members, !dir.empty() || !pos.empty());
      row["true_distance_m"] = num(true_dist);
      row["true_direction_deg"] = num(true_dir * 180.0 / std::numbers::pi);
      row["direction_error_deg"] = num(mean_of(dir));
      row["distance_error_m"] = num(mean_of(dist));
      row["distance_error_pct"] = num(mean_of(pct));
      row["position_error_m"] = num(mean_of(pos));
      dir_all.insert(dir_all.end(), dir.begin(), dir.end());
      dist_all.insert(dist_all.end(), dist.begin(), dist.end());
      pct_all.insert(pct_all.end(), pct.begin(), pct.end());
      pos_all.insert(pos_all.end(), pos.begin(), pos.end());
      result_.targets.push_back(std::move(row));
    }
    auto& sum = result_.summary;
    const Stats d = stats_of(dir_all), p = stats_of(pos_all);
    sum["mean_direction_error_deg"] = num(d.mean);
    sum["median_direction_error_deg"] = num(d.median);
    sum["max_direction_error_deg"] = num(d.max);
    sum["mean_distance_error_m"] = num(mean_of(dist_all));
    sum["mean_distance_error_pct"] = num(mean_of(pct_all));
    sum["median_distance_error_pct"] = num(median_of(pct_all));
    sum["mean_error_m"] = num(p.mean);
    sum["median_error_m"] = num(p.median);
    sum["p90_error_m"] = num(p.p90);
    sum["max_error_m"] = num(p.max);
  }

  // ---------------------------------------------------------------------------- TUM
  void tum() {
    // Snapshots: same reference and frame, t_s within the tolerance of the previous member.
    std::map<std::string, std::vector<const Scored*>> by_rf;
    for (const auto& s : scored_)
      if (s.positioned) by_rf[s.e->reference + "\x1f" + s.e->frame].push_back(&s);
    std::vector<double> snapshot_errors;
    std::map<std::pair<std::string, std::string>, std::vector<double>> pair_errors;
    std::map<std::string, std::vector<double>> target_errors;
    ojson snapshots = ojson::array();
    std::size_t n_snapshots = 0, single = 0;
    for (auto& [rf, members] : by_rf) {
      std::stable_sort(members.begin(), members.end(), [](const Scored* a, const Scored* b) { return a->e->t_s < b->e->t_s; });
      std::size_t start = 0;
      for (std::size_t i = 1; i <= members.size(); ++i) {
        if (i < members.size() && members[i]->e->t_s - members[i - 1]->e->t_s <= options_.snapshot_tolerance_s) continue;
        ++n_snapshots;
        std::map<std::string, const Scored*> snap;  // last estimate per target
        for (std::size_t k = start; k < i; ++k) snap[members[k]->id] = members[k];
        start = i;
        if (snap.size() < 2) {
          ++single;
          continue;
        }
        std::vector<double> errs;
        for (auto a = snap.begin(); a != snap.end(); ++a) {
          for (auto b = std::next(a); b != snap.end(); ++b) {
            const int dims = std::min(a->second->e->dims, b->second->e->dims);
            // Distances are frame-invariant: estimated in the estimate frame, true in the world.
            const double d_est = norm_dims(a->second->est - b->second->est, dims);
            const double d_true = norm_dims(a->second->truth_world - b->second->truth_world, dims);
            const double err = std::abs(d_est - d_true);
            errs.push_back(err);
            pair_errors[{a->first, b->first}].push_back(err);
            target_errors[a->first].push_back(err);
            target_errors[b->first].push_back(err);
          }
        }
        const double e = mean_of(errs);
        snapshot_errors.push_back(e);
        ojson ids = ojson::array();
        for (const auto& [id, s] : snap) ids.push_back(id);
        snapshots.push_back({{"t_s", snap.begin()->second->e->t_s}, {"reference", snap.begin()->second->e->reference},
                             {"targets", ids}, {"pairs", errs.size()}, {"error_m", e}});
      }
    }
    for (const std::string& id : row_order()) {
      auto members = of_target(id);
      const auto& errs = target_errors[id];
      ojson row = row_start(id, members, !errs.empty());
      row["pairs"] = errs.size();
      row["mean_pair_error_m"] = num(mean_of(errs));
      result_.targets.push_back(std::move(row));
    }
    ojson pairs = ojson::array();
    for (const auto& [ab, errs] : pair_errors)
      pairs.push_back({{"a", ab.first}, {"b", ab.second}, {"n", errs.size()}, {"mean_abs_error_m", mean_of(errs)}});
    const Stats st = stats_of(snapshot_errors);
    auto& sum = result_.summary;
    sum["snapshots"] = n_snapshots;
    sum["snapshots_scored"] = st.n;
    sum["mean_error_m"] = num(st.mean);
    sum["median_error_m"] = num(st.median);
    sum["p90_error_m"] = num(st.p90);
    sum["max_error_m"] = num(st.max);
    result_.details["pairs"] = pairs;
    result_.details["snapshots"] = snapshots;
    if (single) result_.warnings.push_back(std::to_string(single) + " snapshots hold a single target: no pair distance to score");
  }

  // ---------------------------------------------------------------------------- counts
  void finish() {
    auto& sum = result_.summary;
    ojson totals = ojson::object();
    std::size_t scored = 0, unknown = 0, extrapolated = 0;
    ReasonLog unscored;
    for (const auto& s : scored_) {
      if (counts(s)) ++scored;
      else unscored.add(s.unscored.empty() ? "no position (position_m has nulls)" : s.unscored, s.e->line);
      if (s.id.empty()) ++unknown;
      if (s.extrapolated) ++extrapolated;
    }
    const auto& expected = expected_set();
    std::size_t located = 0;
    for (const auto& id : expected) located += located_.count(id);
    totals["estimates"] = scored_.size();
    totals["scored_estimates"] = scored;
    totals["unscored_estimates"] = scored_.size() - scored;
    totals["unknown_target_estimates"] = unknown;
    totals["extrapolated_estimates"] = extrapolated;
    totals["targets_expected"] = expected.size();
    totals["targets_located"] = located;
    totals["targets_missing"] = expected.size() - located;
    totals["located_fraction"] = expected.empty() ? ojson(nullptr) : ojson(static_cast<double>(located) / static_cast<double>(expected.size()));
    totals.update(sum);
    sum = std::move(totals);

    for (const auto& [target, log] : unknown_) {
      const auto& [count, line] = log.reasons.begin()->second;
      result_.warnings.push_back("target '" + target + "' (" + std::to_string(count) + " estimates, first at " + file_.path + ":" +
                                 std::to_string(line) + ") is no device, emitter or BLE address of the scene: not scored");
      ojson row = ojson::object();
      row["target"] = target;
      row["status"] = "unknown target";
      row["estimates"] = count;
      row["scored"] = 0;
      result_.targets.push_back(std::move(row));
    }
    for (const auto& [reason, entry] : unscored.reasons) {
      if (reason == "unknown target") continue;
      result_.warnings.push_back(std::to_string(entry.first) + " estimates not scored: " + reason + " (first at " + file_.path + ":" +
                                 std::to_string(entry.second) + ")");
    }
    for (const auto& id : expected)
      if (!located_.count(id)) result_.warnings.push_back("target '" + id + "' was not located (no scorable estimate)");
    if (extrapolated)
      result_.warnings.push_back(std::to_string(extrapolated) +
                                 " estimates lie outside their target's truth time span (truth held at the nearest end)");
    if (expected.empty()) result_.warnings.push_back("the scene has no target this metric expects (located_fraction undefined)");
  }

  const TruthData& truth_;
  const EstimatesFile& file_;
  const EvalOptions& options_;
  const Group& group_;
  GroupResult result_;
  std::vector<Scored> scored_;
  std::map<std::string, ReasonLog> unknown_;
  std::set<std::string> located_;
  std::optional<std::set<std::string>> expected_cache_;
  std::vector<double> position_errors_;
  std::vector<double> path_pcts_;
};

}  // namespace

std::string_view family_name(Family f) noexcept {
  switch (f) {
    case Family::Position: return "position";
    case Family::Tum: return "tum";
    case Family::Amil: return "amil";
    case Family::Montage: return "montage";
    case Family::Spyloc: return "spyloc";
    case Family::Locble: return "locble";
  }
  return "position";
}

std::optional<Family> family_from_name(std::string_view name) noexcept {
  for (Family f : {Family::Position, Family::Tum, Family::Amil, Family::Montage, Family::Spyloc, Family::Locble})
    if (family_name(f) == name) return f;
  return std::nullopt;
}

Family detect_family(std::string_view plugin, std::string_view frame) noexcept {
  const std::string p = lower(plugin);
  for (Family f : {Family::Spyloc, Family::Montage, Family::Locble, Family::Amil, Family::Tum})
    if (p.find(family_name(f)) != std::string::npos) return f;
  const auto at = frame.find('@');
  const std::string_view base = frame.substr(0, at);
  if (base == "player_start") return Family::Amil;
  if (base == "observer_start") return Family::Locble;
  return Family::Position;
}

double percentile_sorted(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return kNaN;
  const double pos = std::clamp(q, 0.0, 1.0) * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

Stats stats_of(std::vector<double> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) {
    s.mean = s.median = s.p80 = s.p90 = s.max = s.rms = kNaN;
    return s;
  }
  std::sort(v.begin(), v.end());
  double sum = 0, sq = 0;
  for (double x : v) {
    sum += x;
    sq += x * x;
  }
  s.mean = sum / static_cast<double>(v.size());
  s.rms = std::sqrt(sq / static_cast<double>(v.size()));
  s.median = percentile_sorted(v, 0.5);
  s.p80 = percentile_sorted(v, 0.8);
  s.p90 = percentile_sorted(v, 0.9);
  s.max = v.back();
  return s;
}

EvalResult evaluate(const TruthData& truth, const EstimatesFile& file, const EvalOptions& options) {
  EvalResult result;
  result.scene_dir = truth.scene_dir;
  result.estimates_path = file.path;
  result.estimate_lines = file.estimates.size();
  result.step_lines = file.steps.size();
  result.other_events = file.other_events;

  // Interpretability of every estimate first: frames and references (bad input, exit 2).
  std::vector<std::string> errors;
  for (const EstimateRecord& e : file.estimates) {
    const std::string where = file.path + ":" + std::to_string(e.line) + ": ";
    try {
      const FrameSpec f = parse_frame(e.frame);
      if (f.needs_reference() && e.reference.empty())
        errors.push_back(where + "frame '" + e.frame + "' is tied to a device but 'reference' is empty");
    } catch (const std::invalid_argument& err) {
      errors.push_back(where + err.what());
    }
    if (errors.size() >= 50) break;
  }
  if (!errors.empty()) throw InputError(std::move(errors));

  std::vector<Group> groups;
  std::map<std::string, std::size_t> index;
  for (const EstimateRecord& e : file.estimates) {
    if (!options.plugins.empty() && std::find(options.plugins.begin(), options.plugins.end(), e.plugin) == options.plugins.end())
      continue;
    auto [it, inserted] = index.try_emplace(e.plugin, groups.size());
    if (inserted) groups.push_back(Group{e.plugin, {}});
    groups[it->second].estimates.push_back(&e);
  }
  for (const std::string& p : options.plugins)
    if (!index.count(p)) result.warnings.push_back("plugin '" + p + "' (--plugin) has no estimate in " + file.path);
  if (groups.empty()) result.warnings.push_back("no estimate to score in " + file.path);
  // Steps without any Montage estimates are still scored when --metric montage is given.
  if (groups.empty() && options.metric == Family::Montage && !file.steps.empty()) groups.push_back(Group{"(steps)", {}});

  for (const Group& g : groups) {
    const Family f = options.metric ? *options.metric
                                    : detect_family(g.plugin, g.estimates.empty() ? std::string_view{} : g.estimates.front()->frame);
    result.groups.push_back(GroupScorer(truth, file, options, g, f).run());
  }
  return result;
}

}  // namespace locus::eval
