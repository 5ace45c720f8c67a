// truth.csv of a scene (docs/scene-format.md): the ground-truth poses of every object, read and
// written, and TruthTrajectories, the whole file in memory with poses interpolated between rows
// (pose.hpp: position linearly, attitude by Eigen's slerp). Evaluation only; not real-time.
#pragma once

#include <array>
#include <cstddef>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "locus/events.hpp"
#include "locus/scene/csv.hpp"

namespace locus::scene {

/// One row of truth.csv: true time, object id, world position, attitude (unit quaternion w,x,y,z).
struct TruthRow {
  double t_s = 0.0;
  std::string id;
  Vec3 position_m{};
  std::array<double, 4> q_wxyz{1.0, 0.0, 0.0, 0.0};
};

/// truth.csv: t, id, x, y, z, qw, qx, qy, qz; rows sorted by t. The quaternion must have a norm within
/// 1e-3 of 1 (it is returned normalised).
class TruthCsvReader {
 public:
  explicit TruthCsvReader(const std::string& path);
  bool next(TruthRow& out);

 private:
  CsvReader csv_;
  std::size_t t_, id_, p_[3], q_[4];
  double last_t_ = -1e300;
  int last_line_ = 0;
};

/// Writes truth.csv (t, id, x, y, z, qw, qx, qy, qz). Rows must be written in non-decreasing t.
class TruthCsvWriter : public CsvWriter {
 public:
  explicit TruthCsvWriter(const std::string& path);
  void write(const TruthRow& r);
};

/// A pose of truth.csv: world position (m) and attitude (unit quaternion w, x, y, z, body to world).
struct Pose {
  Vec3 position_m{};
  std::array<double, 4> q_wxyz{1.0, 0.0, 0.0, 0.0};
};

/// All trajectories of a truth.csv, in memory (evaluation only; ~100 bytes per row).
/// pose_at() interpolates position linearly and attitude by slerp (shortest arc), and holds the first
/// or last pose outside the recorded time range; an object with one row is static.
class TruthTrajectories {
 public:
  TruthTrajectories() = default;
  /// Loads truth.csv. Throws SceneError.
  static TruthTrajectories load(const std::string& path);
  /// Adds a row (rows of one id must come in non-decreasing t; throws std::invalid_argument otherwise).
  void add(const TruthRow& row);

  bool has(const std::string& id) const;
  std::vector<std::string> ids() const;
  /// Pose of `id` at true time `t_true_s`. Throws std::out_of_range for an unknown id.
  Pose pose_at(const std::string& id, double t_true_s) const;
  /// Time range over all ids ({0,0} when empty).
  double t_begin_s() const noexcept { return t_begin_; }
  double t_end_s() const noexcept { return t_end_; }
  /// Time range of one id. Throws std::out_of_range for an unknown id.
  std::pair<double, double> time_range(const std::string& id) const;

 private:
  struct Track {
    std::vector<double> t;
    std::vector<Pose> pose;
  };
  std::map<std::string, Track> tracks_;
  double t_begin_ = 0.0, t_end_ = 0.0;
};

/// Spherical linear interpolation of unit quaternions (w,x,y,z), shortest arc, u in [0,1]: pose.hpp's
/// interpolate_attitude for (w, x, y, z) arrays.
std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u) noexcept;

}  // namespace locus::scene
