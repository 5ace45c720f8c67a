// TUM (paper 000), Eq. 23: the mean absolute error of every pairwise distance in a snapshot (the
// estimates of one reference and frame within --snapshot-tolerance-s), which no rotation or
// translation of the formation changes (docs/eval.md).
#include "locus/eval/metric.hpp"

#include <algorithm>
#include <map>

namespace locus::eval::registered_metrics {

namespace tum_metric {  // named, not anonymous: the metric files share a unity build

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_audio && (!q.is_reference || q.is_estimated);
}

void pair_distances(GroupContext& g) {
  // Snapshots: same reference and frame, t_s within the tolerance of the previous member.
  std::map<std::string, std::vector<const Scored*>> by_rf;
  for (const auto& s : g.scored())
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
      if (i < members.size() && members[i]->e->t_s - members[i - 1]->e->t_s <= g.options().snapshot_tolerance_s) continue;
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
  for (const std::string& id : g.row_order()) {
    auto members = g.of_target(id);
    const auto& errs = target_errors[id];
    ojson row = g.row_start(id, members, !errs.empty());
    row["pairs"] = errs.size();
    row["mean_pair_error_m"] = num(mean_of(errs));
    g.result().targets.push_back(std::move(row));
  }
  ojson pairs = ojson::array();
  for (const auto& [ab, errs] : pair_errors)
    pairs.push_back({{"a", ab.first}, {"b", ab.second}, {"n", errs.size()}, {"mean_abs_error_m", mean_of(errs)}});
  const Stats st = stats_of(snapshot_errors);
  auto& sum = g.result().summary;
  sum["snapshots"] = n_snapshots;
  sum["snapshots_scored"] = st.n;
  sum["mean_error_m"] = num(st.mean);
  sum["median_error_m"] = num(st.median);
  sum["p90_error_m"] = num(st.p90);
  sum["max_error_m"] = num(st.max);
  g.result().details["pairs"] = pairs;
  g.result().details["snapshots"] = snapshots;
  if (single) g.result().warnings.push_back(std::to_string(single) + " snapshots hold a single target: no pair distance to score");
}

void score(GroupContext& g) {
  pair_distances(g);
}

}  // namespace tum_metric

const Metric& tum() {
  static const Metric metric{"tum", "TUM Eq. 23: mean absolute pairwise distance error per snapshot", tum_metric::expects, false, tum_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
