// LocBLE (paper 003): per-tag position error of the final estimate (the paper reports where the
// tag is once the observer has walked the L), plus the mean over every estimate (docs/eval.md).
#include "locus/eval/metric.hpp"

namespace locus::eval::registered_metrics {

namespace {

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return !o.ble_addresses.empty() && !q.is_reference;
}

void score(GroupContext& g) {
  score_positions(g, /*final_only=*/true);
}

}  // namespace

const Metric& locble() {
  static const Metric metric{"locble", "LocBLE: per-tag position error of the final estimate", expects, false, score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
