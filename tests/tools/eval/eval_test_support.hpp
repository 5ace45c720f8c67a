// Hand-built truth and estimates for the scorer tests.
#pragma once

#include <cmath>
#include <initializer_list>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "locus/eval/estimates.hpp"
#include "locus/eval/truth.hpp"

namespace locus::eval::test {

inline Eigen::Quaterniond yaw(double rad) { return Eigen::Quaterniond(Eigen::AngleAxisd(rad, Eigen::Vector3d::UnitZ())); }
inline double deg(double d) { return d * std::numbers::pi / 180.0; }

inline TruthObject device(const std::string& id, bool audio = true, bool imu = false) {
  TruthObject o;
  o.id = id;
  o.is_device = true;
  o.has_audio = audio;
  o.has_imu = imu;
  o.has_speaker = true;
  return o;
}

/// Adds a static object (one truth sample).
inline void place(TruthData& t, const std::string& id, Vec3 p, Eigen::Quaterniond q = Eigen::Quaterniond::Identity()) {
  t.tracks[id].add(TruthPose{0.0, p, q});
}

/// One `estimate` JSON line.
inline std::string estimate_line(const std::string& plugin, const std::string& reference, const std::string& frame,
                                 const std::string& target, double t_s, nlohmann::json position,
                                 nlohmann::json extra = nlohmann::json::object()) {
  nlohmann::ordered_json j;
  j["type"] = "estimate";
  j["plugin"] = plugin;
  j["reference"] = reference;
  j["frame"] = frame;
  j["target"] = target;
  j["t_s"] = t_s;
  j["position_m"] = position;
  j["direction_rad"] = nullptr;
  j["distance_m"] = nullptr;
  j["std_m"] = nullptr;
  j["confidence"] = 1.0;
  for (auto& [k, v] : extra.items()) j[k] = v;
  return j.dump();
}

inline std::string step_line(const std::string& device, double t_s, double stride_m) {
  nlohmann::ordered_json j{{"type", "step"}, {"device", device}, {"detector", "steps"}, {"t_s", t_s}, {"stride_m", stride_m},
                           {"frequency_hz", 1.8}};
  return j.dump();
}

inline EstimatesFile parse_lines(const std::vector<std::string>& lines, const std::string& name = "est.jsonl") {
  std::ostringstream os;
  for (const auto& l : lines) os << l << "\n";
  std::istringstream in(os.str());
  return parse_estimates(in, name);
}

}  // namespace locus::eval::test
