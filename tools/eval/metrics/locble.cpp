// LocBLE (paper 003): per-tag position error of the final estimate (the paper reports where the
// tag is once the observer has walked the L), plus the mean over every estimate (docs/eval.md).
#include "locus/eval/metric.hpp"

namespace locus::eval::registered_metrics {

namespace locble_metric {  // named, not anonymous: the metric files share a unity build

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return !o.ble_addresses.empty() && !q.is_reference;
}

void score(GroupContext& g) {
  score_positions(g, /*final_only=*/true);
}

}  // namespace locble_metric

const Metric& locble() {
  static const Metric metric{"locble", "LocBLE: per-tag position error of the final estimate", locble_metric::expects, false, locble_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
