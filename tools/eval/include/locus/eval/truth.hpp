// Ground truth as the scorer sees it: every device and emitter of the scene, their true trajectories
// (truth.csv), their clocks (scene.yaml truth.clocks) and the optional extra truth files the
// simulator writes (truth_steps.csv). Evaluation only: no plugin may read any of this.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace locus::eval {

using Vec3 = Eigen::Vector3d;

/// One true pose: world position (m) and attitude (rotates body vectors into the world frame).
struct TruthPose {
  double t_s = 0.0;  ///< true time
  Vec3 position_m = Vec3::Zero();
  Eigen::Quaterniond attitude = Eigen::Quaterniond::Identity();
};

/// A piecewise-linear trajectory: positions interpolate linearly, attitudes by slerp; outside its
/// time span the first/last pose holds (a single-sample track is a static object).
class TruthTrack {
 public:
  /// Appends a sample; samples must come in non-decreasing time (throws std::invalid_argument).
  void add(const TruthPose& pose);
  bool empty() const noexcept { return samples_.empty(); }
  double t_begin_s() const { return samples_.front().t_s; }
  double t_end_s() const { return samples_.back().t_s; }
  /// True when `t_true_s` lies inside the recorded span, or the object is static (one sample).
  bool covers(double t_true_s) const;
  TruthPose at(double t_true_s) const;
  /// Length of the path between two true times (horizontal only when `horizontal`).
  double path_length_m(double t0_s, double t1_s, bool horizontal) const;
  const std::vector<TruthPose>& samples() const noexcept { return samples_; }

 private:
  std::vector<TruthPose> samples_;
};

/// local = true·(1 + skew_ppm·1e-6) + offset_s (scene-format.md, truth.clocks).
struct ClockModel {
  double offset_s = 0.0;
  double skew_ppm = 0.0;
  double local_from_true(double true_s) const noexcept { return true_s * (1.0 + skew_ppm * 1e-6) + offset_s; }
  double true_from_local(double local_s) const noexcept { return (local_s - offset_s) / (1.0 + skew_ppm * 1e-6); }
};

/// A device or emitter of the scene, with what the metric families need to know about it.
struct TruthObject {
  std::string id;
  bool is_device = false;               ///< false: emitter (records nothing)
  bool has_audio = false;               ///< device records sound (listener): an audio.wav or microphones
  bool has_imu = false;
  bool has_speaker = false;
  std::optional<Vec3> anchor_m;         ///< position known to the system (infrastructure)
  std::vector<std::string> ble_addresses;  ///< upper case, from `emits` entries of type ble
};

/// One true step of a walker (truth_steps.csv: t_true,id,stride_m).
struct TruthStep {
  double t_true_s = 0.0;
  std::string id;
  double stride_m = 0.0;
};

/// One beep's geometric line of sight (truth_los.csv: t_true,beacon,los with los 1/0; SpyLoc scenes).
struct TruthLos {
  double t_true_s = 0.0;  ///< emission time of the beep
  std::string beacon;
  bool los = true;
};

struct TruthData {
  std::string scene_dir;
  std::string scene_name;
  /// The scene's `environment.family` (scene.yaml): which system's experiment it is, and so which
  /// metric scores it when `--metric` is not given ("" = the scene names none). `locus simulate`
  /// writes it; so does any generator that follows docs/scene-format.md.
  std::string family;
  std::vector<TruthObject> objects;           ///< devices, then emitters, in scene order
  std::map<std::string, TruthTrack> tracks;   ///< by object id (truth.csv)
  std::map<std::string, ClockModel> clocks;   ///< by device id; absent = ideal clock
  std::optional<Vec3> magnetic_field_world_ut;
  std::optional<std::vector<TruthStep>> steps;  ///< truth_steps.csv when the scene has one
  std::optional<std::vector<TruthLos>> los;     ///< truth_los.csv when the scene has one (sorted by time)

  const TruthObject* find(const std::string& id) const;
  /// Object id for an estimate's `target`: an object id, or (case-insensitive) the BLE address an
  /// emitter advertises with. nullopt when nothing matches.
  std::optional<std::string> resolve(const std::string& target) const;
  /// Clock of `id` (identity when the scene gives none).
  ClockModel clock(const std::string& id) const;
  /// True pose at true time: from truth.csv, else the anchor position (static, identity attitude).
  std::optional<TruthPose> pose(const std::string& id, double t_true_s) const;
  /// True when truth.csv or an anchor gives a position for `id`.
  bool has_truth(const std::string& id) const;
};

/// Loads scene.yaml, truth.csv and (when present) truth_steps.csv and truth_los.csv of a scene directory.
/// Throws InputError with "file:line:column: ..." messages; a scene without truth is an InputError.
TruthData load_truth(const std::string& scene_dir);

}  // namespace locus::eval
