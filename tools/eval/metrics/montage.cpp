// Montage (paper 002): trace deviation (relative_trace estimates aligned over the whole walk, error
// as a percentage of the path walked) and stride error: step events matched to truth_steps.csv in
// true time (docs/eval.md); when the localizer re-published steps (detector = its instance:
// stride calibrated by ranging), only those.
#include "locus/eval/metric.hpp"

#include <algorithm>
#include <cmath>

namespace locus::eval::registered_metrics {

namespace montage_metric {  // named, not anonymous: the metric files share a unity build

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_imu;
}

void score(GroupContext& g) {
  score_positions(g, /*final_only=*/false, /*path_pct=*/true);
  // A localizer that re-publishes the steps with its calibrated stride (montage: detector = its
  // instance) is scored on those; step events alone (the "(steps)" group) on every step.
  std::string_view plugin;
  if (!g.scored().empty())
    for (const StepRecord& s : g.file().steps)
      if (s.detector == g.scored().front().e->plugin) plugin = g.scored().front().e->plugin;
  score_strides(g, plugin);
}

}  // namespace montage_metric

const Metric& montage() {
  static const Metric metric{"montage", "Montage: trace deviation (% of the path) and stride error against truth_steps.csv", montage_metric::expects, false, montage_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
