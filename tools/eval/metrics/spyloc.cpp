// SpyLoc (paper 001): position error CDF (median, 80th, 90th percentile) and the LoS / NLoS split,
// from the estimate's own `los` flag or else the scene's truth_los.csv, and the stride error of the
// localizer's step events (its instance name as their `detector`) against truth_steps.csv (docs/eval.md).
#include "locus/eval/metric.hpp"

#include <algorithm>
#include <optional>

namespace locus::eval::registered_metrics {

namespace spyloc_metric {  // named, not anonymous: the metric files share a unity build

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_audio && !o.anchor_m && !q.is_reference;
}

void los_split(GroupContext& g, std::vector<double> sorted) {
  std::sort(sorted.begin(), sorted.end());
  ojson cdf = ojson::array();
  for (int k = 1; k <= 20; ++k) {
    const double q = k / 20.0;
    cdf.push_back({{"fraction", q}, {"error_m", num(percentile_sorted(sorted, q))}});
  }
  g.result().details["cdf"] = cdf;
  // LoS/NLoS: the estimate's own `los` flag, else the truth of the most recent beep before it.
  std::vector<double> los, nlos;
  std::size_t flagged = 0, from_truth = 0;
  for (const auto& s : g.scored()) {
    if (!s.positioned) continue;
    std::optional<bool> flag = s.e->los;
    if (!flag && g.truth().los && !g.truth().los->empty()) {
      const auto& beeps = *g.truth().los;
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
    g.result().details["los_nlos"] = "no estimate carries a `los` flag and the scene has no truth_los.csv";
    return;
  }
  g.result().details["los_source"] = from_truth == 0 ? "estimates" : from_truth == flagged ? "truth_los.csv (most recent beep)" : "mixed";
  auto& sum = g.result().summary;
  for (auto [name, v] : {std::pair<const char*, std::vector<double>*>{"los", &los}, {"nlos", &nlos}}) {
    const Stats st = stats_of(*v);
    sum[std::string(name) + "_estimates"] = st.n;
    sum[std::string(name) + "_median_error_m"] = num(st.median);
    sum[std::string(name) + "_p80_error_m"] = num(st.p80);
    sum[std::string(name) + "_p90_error_m"] = num(st.p90);
  }
}

void score(GroupContext& g) {
  los_split(g, score_positions(g, /*final_only=*/false));
  // The localizer's own step events (stride calibrated by ranging), not the steps detector's.
  if (!g.scored().empty()) score_strides(g, g.scored().front().e->plugin);
}

}  // namespace spyloc_metric

const Metric& spyloc() {
  static const Metric metric{"spyloc", "SpyLoc: position error CDF (median, p80, p90) and the LoS/NLoS split", spyloc_metric::expects, false, spyloc_metric::score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
