// The generic metric: per-estimate position error in any frame the scorer understands, with
// per-target and overall statistics (docs/eval.md, "position"). Any localizer can be scored with it.
#include "locus/eval/metric.hpp"

namespace locus::eval::registered_metrics {

namespace position_metric {  // named, not anonymous: the metric files share a unity build

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return !o.anchor_m && q.has_track && (!q.is_reference || q.is_estimated);
}

void score(GroupContext& g) {
  score_positions(g, /*final_only=*/false);
}

}  // namespace position_metric

const Metric& position() {
  static const Metric metric{"position", "generic: per-estimate position error in any frame (mean, median, p80, p90, max, rms)", position_metric::expects, false, position_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
