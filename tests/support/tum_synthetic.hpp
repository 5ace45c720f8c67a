// Synthetic TUM exchanges (tests/plugins/tum, tests/bench/bench_tum.cpp): four two-mic devices of the
// paper's setting (Sec. VIII-B) with known poses and clocks; every device times both tones exactly
// (plus optional Gaussian timing noise).
#pragma once

#include <Eigen/Dense>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "tum/solver.hpp"

namespace locus::test::tum_synthetic {

namespace tum = locus::plugins::tum;
using Eigen::Quaterniond;
using Eigen::Vector3d;

inline constexpr double kC = 343.2;

struct Pose {
  std::string id;
  Vector3d p;       ///< world
  Quaterniond q;    ///< body -> world
  std::vector<Vector3d> mics;
  Vector3d speaker;
  double clock_offset_s;
};

inline Quaterniond flat(double heading_rad) { return Quaterniond(Eigen::AngleAxisd(heading_rad, Vector3d::UnitZ())); }

/// The four devices of the paper's setting (Sec. VIII-B), at different heights.
inline std::vector<Pose> layout(double m_height = 1.0, bool table = false) {
  const std::vector<Vector3d> nexus{{0.0, 0.066, 0.0}, {0.0, -0.066, 0.0}};
  return {
      {"N1", {3.45, 2.2, 0.8}, flat(0.785), nexus, {0.02, -0.068, 0.0}, 0.31},
      {"M", {3.0, 3.7, m_height}, flat(2.356), {{-0.12, 0.08, 0.0}, {0.12, 0.08, 0.0}}, {0.0, -0.085, 0.0}, 1.27},
      {"N2", {1.85, 2.2, table ? 0.8 : 1.0}, flat(-0.785), nexus, {0.02, -0.068, 0.0}, 0.77},
      {"N3", {1.85, 3.8, table ? 0.8 : 1.2}, flat(-2.356), {{0.01, 0.07, 0.0}, {-0.01, -0.07, 0.0}}, {0.0, 0.072, 0.0}, 1.9},
  };
}

/// One exchange: device 0 emits at t1, device 1 at t2 (true time); every device times both tones.
inline std::vector<tum::DeviceExchange> exchange(const std::vector<Pose>& poses, double t1, double t2, double noise_s = 0.0,
                                          std::mt19937_64* rng = nullptr) {
  std::normal_distribution<double> n01(0.0, 1.0);
  const Vector3d m = poses[0].p + poses[0].q * poses[0].speaker;
  const Vector3d n = poses[1].p + poses[1].q * poses[1].speaker;
  std::vector<tum::DeviceExchange> out;
  for (const Pose& d : poses) {
    tum::DeviceExchange e;
    e.id = d.id;
    e.mics = d.mics;
    e.speaker = d.speaker;
    e.attitude = d.q;
    for (const Vector3d& mic : d.mics) {
      const Vector3d w = d.p + d.q * mic;
      const double e1 = rng ? noise_s * n01(*rng) : 0.0;
      const double e2 = rng ? noise_s * n01(*rng) : 0.0;
      e.t1_s.push_back(t1 + (w - m).norm() / kC + d.clock_offset_s + e1);
      e.t2_s.push_back(t2 + (w - n).norm() / kC + d.clock_offset_s + e2);
    }
    out.push_back(e);
  }
  return out;
}

/// Device `d`'s body origin in `ref`'s body frame.
inline Vector3d in_body(const Pose& ref, const Pose& d) { return ref.q.conjugate() * (d.p - ref.p); }

}  // namespace locus::test::tum_synthetic
