// Helpers shared by the walking families (see walking.hpp).
#include "locus/sim/motion/walking.hpp"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "locus/scene/streams.hpp"

namespace locus::sim::motion {

using Eigen::Vector2d;

std::vector<Vector2d> offset_polyline(const std::vector<Vector2d>& path, double lateral_m) {
  if (path.size() < 2) throw std::invalid_argument("offset_polyline: need at least 2 points");
  std::vector<Vector2d> normals;  // left normal of each segment
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const Vector2d d = path[i + 1] - path[i];
    if (d.norm() < 1e-9) throw std::invalid_argument("offset_polyline: zero-length segment");
    normals.push_back(Vector2d(-d.y(), d.x()) / d.norm());
  }
  std::vector<Vector2d> out;
  out.push_back(path.front() + lateral_m * normals.front());
  for (std::size_t i = 1; i + 1 < path.size(); ++i) {
    // Mitre: the point at distance lateral from both segments' lines.
    const Vector2d bis = normals[i - 1] + normals[i];
    const double c = bis.norm() > 1e-9 ? normals[i].dot(bis / bis.norm()) : 1.0;
    out.push_back(path[i] + (c > 0.1 ? lateral_m / c : lateral_m) * (bis.norm() > 1e-9 ? bis / bis.norm() : normals[i]));
  }
  out.push_back(path.back() + lateral_m * normals.back());
  return out;
}

std::string truth_steps_csv(const std::vector<std::pair<std::string, const PedestrianTrajectory*>>& walkers,
                            double until_s) {
  std::vector<std::tuple<double, std::string, double, double>> rows;
  for (const auto& [id, w] : walkers)
    for (const auto& s : w->true_steps())
      if (s.t_s <= until_s) rows.emplace_back(s.t_s, id, s.stride_m, s.frequency_hz);
  std::stable_sort(rows.begin(), rows.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  std::ostringstream out;
  out << "t_true,id,stride_m,frequency_hz\n";
  for (const auto& [t, id, len, f] : rows)
    out << scene::format_double(t) << ',' << id << ',' << scene::format_double(len) << ','
        << scene::format_double(f) << '\n';
  return out.str();
}

PhoneImuConfig phone_imu_config(double rate_hz, double noise_scale, bool magnetometer) {
  PhoneImuConfig c;
  c.rate_hz = rate_hz;
  c.magnetometer = magnetometer;
  c.scale_errors(noise_scale);  // every error term, the ADC stays
  return c;
}

}  // namespace locus::sim::motion
