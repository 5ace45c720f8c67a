// Synthetic TUM exchanges (tests/plugins/tum, tests/bench/bench_tum.cpp): four two-mic devices of the
// paper's setting (Sec. VIII-B) with known poses and clocks; every device times both tones exactly
// (plus optional Gaussian timing noise).
#pragma once

#include <Eigen/Dense>
#include <functional>
#include <map>
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

/// A device's exchange with its geometry filled in (id, mics, speaker) and nothing heard yet.
inline tum::DeviceExchange geometry_of(const Pose& d) {
  tum::DeviceExchange e;
  e.id = d.id;
  e.mics = d.mics;
  e.speaker = d.speaker;
  return e;
}

/// One exchange: device 0 emits at t1, device 1 at t2 (true time); every device times both tones.
inline std::vector<tum::DeviceExchange> exchange(const std::vector<Pose>& poses, double t1, double t2, double noise_s = 0.0,
                                          std::mt19937_64* rng = nullptr) {
  std::normal_distribution<double> n01(0.0, 1.0);
  const Vector3d m = poses[0].p + poses[0].q * poses[0].speaker;
  const Vector3d n = poses[1].p + poses[1].q * poses[1].speaker;
  std::vector<tum::DeviceExchange> out;
  for (const Pose& d : poses) {
    tum::DeviceExchange e = geometry_of(d);
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

/// A device that moves: `pose(t)` gives its origin and attitude at true time t (mics, speaker and clock
/// as in Pose); `rate(t)` its body-frame angular rate.
struct Mover {
  std::function<std::pair<Vector3d, Quaterniond>(double)> pose;
  std::function<Vector3d(double)> rate;
};

/// One exchange with devices that move while it lasts (docs/tum.md, "Motion within an exchange"):
/// every arrival at its retarded time (t - te = |mic(t) - speaker(te)| / c), timed late by the
/// range-Doppler coupling (rdot / c) * instant of its tone (instant1_s / instant2_s, as a phase-timed
/// chirp detector does: dsp::doppler_timing_instant_s); each device's attitude and gyro rate taken at
/// its hearing of tone 1 (the mean over its mics), as the plugin reports them; `moving` set for movers.
inline std::vector<tum::DeviceExchange> moving_exchange(const std::vector<Pose>& poses, const std::map<std::string, Mover>& movers,
                                                        double t1, double t2, double instant1_s, double instant2_s) {
  auto at = [&](const Pose& d, double t) -> std::pair<Vector3d, Quaterniond> {
    const auto it = movers.find(d.id);
    return it == movers.end() ? std::make_pair(d.p, d.q) : it->second.pose(t);
  };
  auto point = [&](const Pose& d, const Vector3d& body, double t) {
    const auto [p, q] = at(d, t);
    return Vector3d(p + q * body);
  };
  constexpr double h = 1e-4;  // for velocities by central differences
  auto arrival = [&](const Pose& src, double te, const Pose& d, const Vector3d& mic, double instant_s) {
    double t = te;
    for (int it = 0; it < 8; ++it) t = te + (point(d, mic, t) - point(src, src.speaker, te)).norm() / kC;
    const Vector3d w = point(d, mic, t) - point(src, src.speaker, te);
    const Vector3d v = (point(d, mic, t + h) - point(d, mic, t - h)) / (2 * h) -
                       (point(src, src.speaker, te + h) - point(src, src.speaker, te - h)) / (2 * h);
    return t + v.dot(w.normalized()) / kC * instant_s;
  };
  std::vector<tum::DeviceExchange> out;
  for (const Pose& d : poses) {
    tum::DeviceExchange e = geometry_of(d);
    double ref = 0.0;
    for (const Vector3d& mic : d.mics) {
      const double a1 = arrival(poses[0], t1, d, mic, &d == &poses[0] ? 0.0 : instant1_s);
      const double a2 = arrival(poses[1], t2, d, mic, &d == &poses[1] ? 0.0 : instant2_s);
      ref += a1 / static_cast<double>(d.mics.size());
      e.t1_s.push_back(a1 + d.clock_offset_s);
      e.t2_s.push_back(a2 + d.clock_offset_s);
    }
    e.attitude = at(d, ref).second;
    const auto it = movers.find(d.id);
    e.moving = it != movers.end();
    e.gyro_radps = e.moving ? it->second.rate(ref) : Vector3d::Zero();
    out.push_back(e);
  }
  return out;
}

/// Device `d`'s body origin in `ref`'s body frame.
inline Vector3d in_body(const Pose& ref, const Pose& d) { return ref.q.conjugate() * (d.p - ref.p); }

}  // namespace locus::test::tum_synthetic
