// AMIL (paper 004): per-listener direction, distance and position error in the player's start
// frame, and the listeners located (docs/eval.md). An estimate with a direction but no position counts.
#include "locus/eval/metric.hpp"

#include "locus/angles.hpp"

#include <cmath>
#include <numbers>

namespace locus::eval::registered_metrics {

namespace amil_metric {  // named, not anonymous: the metric files share a unity build

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_audio && !q.is_reference;
}

constexpr double kNearRangeM = 2.5;  // the "within 2.5 m" (docs/eval.md)

/// Fraction of |error| / std within 1 and 2 (a calibrated std: about 0.68 and 0.95).
void coverage(ojson& sum, const std::string& name, const std::vector<double>& z) {
  double in1 = 0, in2 = 0;
  for (double v : z) {
    in1 += v <= 1.0;
    in2 += v <= 2.0;
  }
  const double n = static_cast<double>(z.size());
  sum[name + "_std_coverage_1sigma"] = num(z.empty() ? kNaN : in1 / n);
  sum[name + "_std_coverage_2sigma"] = num(z.empty() ? kNaN : in2 / n);
}

bool flagged(const EstimateRecord& e) {
  for (const std::string& f : e.flags)
    if (f == "inconsistent" || f == "weak") return true;
  return false;
}

void listeners(GroupContext& g) {
  std::vector<double> dir_all, dist_all, pct_all, pos_all;
  std::vector<double> near_pct, z_pos, z_dist, z_dir, dir_flagged, dir_unflagged;
  int near_targets = 0, near_with_distance = 0, flagged_targets = 0;
  for (const std::string& id : g.row_order()) {
    auto members = g.of_target(id);
    std::vector<double> dir, dist, pct, pos;
    double true_dist = kNaN, true_dir = kNaN;
    for (const Scored* s : members) {
      if (!g.counts(*s)) continue;
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
      if (std::isfinite(edir)) {
        const double derr = std::abs(wrap_pi(edir - tdir));
        dir.push_back(derr * 180.0 / std::numbers::pi);
        (flagged(*s->e) ? dir_flagged : dir_unflagged).push_back(derr * 180.0 / std::numbers::pi);
        if (std::isfinite(s->e->direction_std_rad) && s->e->direction_std_rad > 0) z_dir.push_back(derr / s->e->direction_std_rad);
      }
      if (std::isfinite(edist)) {
        dist.push_back(std::abs(edist - td));
        if (td > 0) pct.push_back(100.0 * std::abs(edist - td) / td);
        if (std::isfinite(s->e->distance_std_m) && s->e->distance_std_m > 0) z_dist.push_back(std::abs(edist - td) / s->e->distance_std_m);
      }
      if (s->positioned) {
        pos.push_back(s->error_m);
        if (std::isfinite(s->e->std_m) && s->e->std_m > 0) z_pos.push_back(s->error_m / s->e->std_m);
      }
    }
    if (std::isfinite(true_dist) && true_dist <= kNearRangeM) {
      ++near_targets;
      if (!pct.empty()) {
        ++near_with_distance;
        near_pct.push_back(mean_of(pct));
      }
    }
    for (const Scored* s : members)
      if (g.counts(*s) && flagged(*s->e)) {
        ++flagged_targets;
        break;
      }
    ojson row = g.row_start(id, members, !dir.empty() || !pos.empty());
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
    g.result().targets.push_back(std::move(row));
  }
  auto& sum = g.result().summary;
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
  // The near-range bars and the honesty of the stds (docs/eval.md "AMIL").
  sum["near_targets"] = near_targets;
  sum["near_with_distance_fraction"] = num(near_targets > 0 ? static_cast<double>(near_with_distance) / near_targets : kNaN);
  sum["near_median_distance_error_pct"] = num(median_of(near_pct));
  coverage(sum, "position", z_pos);
  coverage(sum, "distance", z_dist);
  coverage(sum, "direction", z_dir);
  sum["flagged_targets"] = flagged_targets;
  sum["flagged_mean_direction_error_deg"] = num(mean_of(dir_flagged));
  sum["unflagged_mean_direction_error_deg"] = num(mean_of(dir_unflagged));
}

void score(GroupContext& g) {
  listeners(g);
}

}  // namespace amil_metric

const Metric& amil() {
  static const Metric metric{"amil", "AMIL: per-listener direction / distance / position error in the player frame, listeners located", amil_metric::expects, true, amil_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
