// AMIL (paper 004): per-listener direction, distance and position error in the player's start
// frame, and the listeners located (docs/eval.md). An estimate with a direction but no position counts.
#include "locus/eval/metric.hpp"

#include "locus/angles.hpp"

#include <cmath>
#include <numbers>

namespace locus::eval::registered_metrics {

namespace {

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_audio && !q.is_reference;
}

void listeners(GroupContext& g) {
  std::vector<double> dir_all, dist_all, pct_all, pos_all;
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
      if (std::isfinite(edir)) dir.push_back(std::abs(wrap_pi(edir - tdir)) * 180.0 / std::numbers::pi);
      if (std::isfinite(edist)) {
        dist.push_back(std::abs(edist - td));
        if (td > 0) pct.push_back(100.0 * std::abs(edist - td) / td);
      }
      if (s->positioned) pos.push_back(s->error_m);
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
}

void score(GroupContext& g) {
  listeners(g);
}

}  // namespace

const Metric& amil() {
  static const Metric metric{"amil", "AMIL: per-listener direction / distance / position error in the player frame, listeners located", expects, true, score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
