// A metric: how `locus eval` aggregates one plugin's estimates (TUM's pairwise distances, AMIL's
// direction and distance per listener, ...). Each metric is one file, tools/eval/metrics/<name>.cpp,
// that defines `const Metric& locus::eval::registered_metrics::<name>()`; tools/eval/CMakeLists.txt
// globs that folder and generates the table metrics() from the file names (cmake/LocusTable.cmake:
// an explicit list, so no linker drops a metric the way it drops an unreferenced self-registering
// object from a static library).
// The metric's name is the file name, and it is the name a scene's `environment.family` and
// `locus eval --metric` use.
//
// Every estimate is first scored the same way by the core (tools/eval/metrics.cpp): its target
// resolved, its time converted to true time through the truth clock, truth mapped into its frame (or
// the estimate aligned to truth for relative frames). A metric then sees the scored estimates
// through GroupContext and writes rows, summary and details into GroupResult; the core adds the
// counts every metric shares (targets expected / located, unscored estimates, warnings).
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/eval/frames.hpp"
#include "locus/eval/metrics.hpp"

namespace locus::eval {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A JSON number, or null when not finite (NaN columns print as "-").
inline nlohmann::ordered_json num(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }
/// Mean (NaN when empty) and median (NaN when empty).
double mean_of(const std::vector<double>& v);
double median_of(std::vector<double> v);
/// |v| in 3D, or in the horizontal plane when dims < 3.
inline double norm_dims(const Vec3& v, int dims) { return dims >= 3 ? v.norm() : v.head<2>().norm(); }

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

/// What a metric knows about a scene object when deciding whether it expects it to be located.
struct TargetQuery {
  const TruthObject& object;  ///< has truth (truth.csv or an anchor)
  bool is_reference;          ///< some estimate of the group uses it as its reference
  bool is_estimated;          ///< some estimate of the group targets it
  bool has_track;             ///< it has a truth.csv track (not only an anchor)
};

class GroupContext;

struct Metric {
  std::string_view name;     ///< = the file name; what environment.family and --metric use
  std::string_view summary;  ///< one line: what it measures (`locus eval --help`, docs/eval.md)
  /// Whether the metric expects `object` to be located (targets_expected, located_fraction).
  bool (*expects)(const TargetQuery& q) = nullptr;
  /// An estimate with a direction but no position, in a placed frame, counts as scored (AMIL).
  bool direction_only_counts = false;
  /// Aggregates the group: rows (GroupContext::row_start), summary and details of result().
  void (*score)(GroupContext& g) = nullptr;
};

/// Every registered metric, in name order (generated from tools/eval/metrics/*.cpp).
const std::vector<const Metric*>& metrics();
/// nullptr when no metric has that name.
const Metric* find_metric(std::string_view name);
/// The registered names, in order (for --metric checks and messages).
std::vector<std::string> metric_names();

/// One plugin's scored estimates, as a metric sees them.
class GroupContext {
 public:
  virtual ~GroupContext() = default;
  virtual const TruthData& truth() const = 0;
  virtual const EstimatesFile& file() const = 0;
  virtual const EvalOptions& options() const = 0;
  virtual const Metric& metric() const = 0;
  /// Every estimate of the group, scored (unknown targets and unscorable ones included, flagged).
  virtual const std::vector<Scored>& scored() const = 0;
  /// The result being built: the metric fills targets (rows), summary and details, adds warnings.
  virtual GroupResult& result() = 0;
  /// Rows in order: expected targets (scene order), then other estimated targets.
  virtual std::vector<std::string> row_order() = 0;
  /// The scored estimates of one target.
  virtual std::vector<const Scored*> of_target(const std::string& id) const = 0;
  /// Scored: a position error exists, or (Metric::direction_only_counts) a direction in a placed frame.
  virtual bool counts(const Scored& s) const = 0;
  /// Starts a row {"target", "status", "estimates", "scored"}; `located` marks the target located.
  virtual nlohmann::ordered_json row_start(const std::string& id, const std::vector<const Scored*>& members, bool located) = 0;
};

/// The position metrics' common part: per-target mean / median / p90 / max / final error rows and
/// the summary statistics, over every estimate or (final_only) each target's last one. With
/// path_pct (Montage) each row also gets the path length walked and the error as a percentage of it.
/// Returns every position error (for metrics that split them further).
std::vector<double> score_positions(GroupContext& g, bool final_only, bool path_pct = false);

/// Stride error: step events (of `detector` only, when given) matched to truth_steps.csv in true
/// time (nearest unused true step within options().step_match_tolerance_s); summary steps_true /
/// detected / matched / missed / extra and the mean, median, p90 and max stride error; a warning
/// (and a null mean) when the scene has no truth_steps.csv. Montage and SpyLoc use it.
void score_strides(GroupContext& g, std::string_view detector = {});

}  // namespace locus::eval
