// SpyLoc trilateration: weighted Gauss-Newton from several starts. See solver.hpp.
#include "solver.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace locus::plugins::spyloc {

double horizontal_range(double slant_m, double dz_m) {
  const double h2 = slant_m * slant_m - dz_m * dz_m;
  return h2 > 0.0 ? std::sqrt(h2) : 0.0;
}

namespace {

std::optional<Fix> gauss_newton(const std::vector<RangeObs>& obs, double z, Eigen::Vector2d p) {
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix2d H = Eigen::Matrix2d::Zero();
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    for (const RangeObs& o : obs) {
      const Eigen::Vector3d d(p.x() - o.beacon_m[0], p.y() - o.beacon_m[1], z - o.beacon_m[2]);
      const double r = std::max(d.norm(), 1e-6);
      const Eigen::Vector2d J(d.x() / r, d.y() / r);
      const double w = 1.0 / (o.std_m * o.std_m);
      H += w * J * J.transpose();
      g += w * J * (o.range_m - r);
    }
    H += 1e-9 * Eigen::Matrix2d::Identity();
    const Eigen::Vector2d step = H.ldlt().solve(g);
    p += step.cwiseMax(Eigen::Vector2d(-5, -5)).cwiseMin(Eigen::Vector2d(5, 5));
    if (step.norm() < 1e-6) break;
  }
  Eigen::Matrix2d H = Eigen::Matrix2d::Zero();
  double ss = 0.0, ws = 0.0;
  for (const RangeObs& o : obs) {
    const Eigen::Vector3d d(p.x() - o.beacon_m[0], p.y() - o.beacon_m[1], z - o.beacon_m[2]);
    const double r = std::max(d.norm(), 1e-6);
    const Eigen::Vector2d J(d.x() / r, d.y() / r);
    const double w = 1.0 / (o.std_m * o.std_m);
    H += w * J * J.transpose();
    ss += w * (o.range_m - r) * (o.range_m - r);
    ws += w;
  }
  if (!std::isfinite(p.x()) || !std::isfinite(p.y())) return std::nullopt;
  Fix f;
  f.xy_m = {p.x(), p.y()};
  f.rms_residual_m = std::sqrt(ss / ws);
  // Covariance of the fix; a degenerate direction (collinear beacons, fix on their line) gets a
  // large but finite variance.
  const Eigen::Matrix2d C = (H + 1e-6 * Eigen::Matrix2d::Identity()).inverse();
  f.cov = {C(0, 0), C(0, 1), C(1, 1)};
  return f;
}

}  // namespace

std::vector<Fix> trilaterate(const std::vector<RangeObs>& obs, double z_m) {
  std::vector<Fix> out;
  if (obs.size() < 3) return out;
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  double spread = 0.0;
  for (const RangeObs& o : obs) c += Eigen::Vector2d(o.beacon_m[0], o.beacon_m[1]);
  c /= static_cast<double>(obs.size());
  for (const RangeObs& o : obs) spread = std::max(spread, (Eigen::Vector2d(o.beacon_m[0], o.beacon_m[1]) - c).norm());
  spread = std::max(spread, 1.0);
  std::vector<Eigen::Vector2d> starts = {c};
  for (int k = 0; k < 8; ++k) {
    const double a = k * 3.14159265358979 / 4.0;
    starts.emplace_back(c + spread * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
  std::vector<Fix> all;
  for (const auto& s : starts)
    if (auto f = gauss_newton(obs, z_m, s)) all.push_back(*f);
  std::sort(all.begin(), all.end(), [](const Fix& a, const Fix& b) { return a.rms_residual_m < b.rms_residual_m; });
  for (const Fix& f : all) {
    bool dup = false;
    for (const Fix& o : out) dup |= std::hypot(f.xy_m[0] - o.xy_m[0], f.xy_m[1] - o.xy_m[1]) < 0.3;
    if (!dup) out.push_back(f);
    if (out.size() == 2) break;
  }
  return out;
}

}  // namespace locus::plugins::spyloc
