// Montage (paper 002): trace deviation (relative_trace estimates aligned over the whole walk, error
// as a percentage of the path walked) and stride error: step events matched to truth_steps.csv in
// true time (docs/eval.md).
#include "locus/eval/metric.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

namespace locus::eval::registered_metrics {

namespace {

using ojson = nlohmann::ordered_json;

bool expects(const TargetQuery& q) {
  const TruthObject& o = q.object;
  return o.is_device && o.has_imu;
}

void stride_errors(GroupContext& g) {
  auto& sum = g.result().summary;
  if (!g.truth().steps) {
    g.result().warnings.push_back("the scene has no truth_steps.csv: stride error not scored");
    sum["mean_stride_error_m"] = nullptr;
    return;
  }
  std::map<std::string, std::vector<double>> true_t;  // per device, sorted
  std::map<std::string, std::vector<double>> true_stride;
  {
    std::map<std::string, std::vector<std::pair<double, double>>> by;
    for (const TruthStep& s : *g.truth().steps) by[s.id].emplace_back(s.t_true_s, s.stride_m);
    for (auto& [id, v] : by) {
      std::sort(v.begin(), v.end());
      for (auto& [t, l] : v) {
        true_t[id].push_back(t);
        true_stride[id].push_back(l);
      }
    }
  }
  std::map<std::string, std::vector<const StepRecord*>> detected;
  for (const StepRecord& s : g.file().steps) detected[s.device].push_back(&s);
  std::size_t n_true = 0, n_detected = g.file().steps.size(), n_matched = 0, n_unknown = 0;
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
    if (!g.truth().find(dev) && !g.truth().tracks.count(dev)) n_unknown += det.size();
    const ClockModel clock = g.truth().clock(dev);
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
      double best_dt = g.options().step_match_tolerance_s;
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
    for (auto& row : g.result().targets) {
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
  g.result().details["steps"] = per_device;
  if (n_unknown) g.result().warnings.push_back(std::to_string(n_unknown) + " step events come from devices the scene does not have");
}

void score(GroupContext& g) {
  score_positions(g, /*final_only=*/false, /*path_pct=*/true);
  stride_errors(g);
}

}  // namespace

const Metric& montage() {
  static const Metric metric{"montage", "Montage: trace deviation (% of the path) and stride error against truth_steps.csv", expects, false, score};
  return metric;
}

}  // namespace locus::eval::registered_metrics
