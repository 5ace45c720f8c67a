// truth.csv and the trajectories in memory (truth.hpp); the interpolation itself is pose.hpp's.
#include "locus/scene/truth.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "locus/scene/pose.hpp"
#include "stream_detail.hpp"

namespace locus::scene {

using detail::trim;

TruthCsvReader::TruthCsvReader(const std::string& path) : csv_(path) {
  t_ = csv_.require_column("t");
  id_ = csv_.require_column("id");
  const char* pn[3] = {"x", "y", "z"};
  const char* qn[4] = {"qw", "qx", "qy", "qz"};
  for (int i = 0; i < 3; ++i) p_[i] = csv_.require_column(pn[i]);
  for (int i = 0; i < 4; ++i) q_[i] = csv_.require_column(qn[i]);
}

bool TruthCsvReader::next(TruthRow& out) {
  if (!csv_.next_row()) return false;
  out.t_s = csv_.number(t_);
  if (out.t_s < last_t_)
    csv_.fail(t_, "time " + format_double(out.t_s) + " is before " + format_double(last_t_) + " on line " +
                      std::to_string(last_line_) + " (rows must be sorted by t)");
  const std::string_view id = trim(csv_.field(id_));
  if (id.empty()) csv_.fail(id_, "expected an id, got an empty field");
  out.id.assign(id.data(), id.size());
  for (int i = 0; i < 3; ++i) out.position_m[i] = csv_.number(p_[i]);
  double n2 = 0.0;
  for (int i = 0; i < 4; ++i) {
    out.q_wxyz[i] = csv_.number(q_[i]);
    n2 += out.q_wxyz[i] * out.q_wxyz[i];
  }
  const double n = std::sqrt(n2);
  if (std::fabs(n - 1.0) > 1e-3)
    csv_.fail(q_[0], "quaternion (qw,qx,qy,qz) has norm " + format_double(n) + ", expected 1 (within 1e-3)");
  for (double& q : out.q_wxyz) q /= n;
  last_t_ = out.t_s;
  last_line_ = csv_.row_line();
  return true;
}

TruthCsvWriter::TruthCsvWriter(const std::string& path)
    : CsvWriter(path, {"t", "id", "x", "y", "z", "qw", "qx", "qy", "qz"}) {}

void TruthCsvWriter::write(const TruthRow& r) {
  std::vector<std::string> f;
  f.reserve(9);
  f.push_back(format_double(r.t_s));
  f.push_back(r.id);
  for (double v : r.position_m) f.push_back(format_double(v));
  for (double v : r.q_wxyz) f.push_back(format_double(v));
  row(f);
}

namespace {

Eigen::Quaterniond quaternion(const std::array<double, 4>& q_wxyz) {
  return Eigen::Quaterniond(q_wxyz[0], q_wxyz[1], q_wxyz[2], q_wxyz[3]);
}

}  // namespace

std::array<double, 4> slerp(const std::array<double, 4>& a, const std::array<double, 4>& b, double u) noexcept {
  const Eigen::Quaterniond q = interpolate_attitude(quaternion(a), quaternion(b), u);
  return {q.w(), q.x(), q.y(), q.z()};
}
TruthTrajectories TruthTrajectories::load(const std::string& path) {
  TruthTrajectories tt;
  TruthCsvReader rd(path);
  TruthRow row;
  while (rd.next(row)) tt.add(row);
  return tt;
}

void TruthTrajectories::add(const TruthRow& row) {
  Track& tr = tracks_[row.id];
  if (!tr.t.empty() && row.t_s < tr.t.back())
    throw std::invalid_argument("truth row for '" + row.id + "' at t=" + format_double(row.t_s) +
                                " is before the previous one (" + format_double(tr.t.back()) + ")");
  tr.t.push_back(row.t_s);
  tr.pose.push_back(Pose{row.position_m, row.q_wxyz});
  if (tracks_.size() == 1 && tr.t.size() == 1) {
    t_begin_ = t_end_ = row.t_s;
  } else {
    t_begin_ = std::min(t_begin_, row.t_s);
    t_end_ = std::max(t_end_, row.t_s);
  }
}

bool TruthTrajectories::has(const std::string& id) const { return tracks_.count(id) != 0; }

std::vector<std::string> TruthTrajectories::ids() const {
  std::vector<std::string> v;
  v.reserve(tracks_.size());
  for (const auto& [k, _] : tracks_) v.push_back(k);
  return v;
}

std::pair<double, double> TruthTrajectories::time_range(const std::string& id) const {
  const auto it = tracks_.find(id);
  if (it == tracks_.end()) throw std::out_of_range("truth: unknown id '" + id + "'");
  return {it->second.t.front(), it->second.t.back()};
}

Pose TruthTrajectories::pose_at(const std::string& id, double t) const {
  const auto it = tracks_.find(id);
  if (it == tracks_.end()) throw std::out_of_range("truth: unknown id '" + id + "'");
  const Track& tr = it->second;
  const TimeBracket at = bracket(tr.t.size(), t, [&tr](std::size_t i) { return tr.t[i]; });
  if (at.hi == at.lo) return tr.pose[at.lo];
  const Pose& a = tr.pose[at.lo];
  const Pose& b = tr.pose[at.hi];
  const Eigen::Vector3d position = interpolate_position(Eigen::Vector3d(a.position_m[0], a.position_m[1], a.position_m[2]),
                                                        Eigen::Vector3d(b.position_m[0], b.position_m[1], b.position_m[2]), at.u);
  Pose p;
  for (int i = 0; i < 3; ++i) p.position_m[static_cast<std::size_t>(i)] = position[i];
  p.q_wxyz = slerp(a.q_wxyz, b.q_wxyz, at.u);
  return p;
}

}  // namespace locus::scene
