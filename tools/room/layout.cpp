// Reading a layout from a scene directory (layout.hpp).
#include "locus/room/layout.hpp"

#include <algorithm>
#include <map>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "locus/scene/truth.hpp"

namespace locus::room {

const LayoutDevice* Layout::find(const std::string& id) const {
  for (const auto& d : devices)
    if (d.id == id) return &d;
  return nullptr;
}

std::optional<Eigen::Vector3d> room_size_from_environment(const std::string& environment_yaml, const std::string& file) {
  if (environment_yaml.empty()) return std::nullopt;
  YAML::Node env;
  try {
    env = YAML::Load(environment_yaml);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(file + ": environment: " + e.what());
  }
  if (!env.IsMap() || !env["room"]) return std::nullopt;
  const YAML::Node room = env["room"];
  const std::string where = file + ":" + std::to_string(room.Mark().line + 1) + ":" + std::to_string(room.Mark().column + 1) +
                            ": environment.room";
  if (!room.IsSequence() || room.size() != 3) throw std::runtime_error(where + ": expected [x, y, z] in metres (three numbers)");
  Eigen::Vector3d size;
  for (int i = 0; i < 3; ++i) {
    try {
      size[i] = room[i].as<double>();
    } catch (const YAML::Exception&) {
      throw std::runtime_error(where + "[" + std::to_string(i) + "]: expected a number (metres), got '" +
                               room[i].as<std::string>("?") + "'");
    }
    if (!(size[i] > 0.0)) throw std::runtime_error(where + "[" + std::to_string(i) + "]: expected a positive size (m)");
  }
  return size;
}

EasedTrajectory::EasedTrajectory(std::shared_ptr<const sim::Trajectory> inner, double t_begin_s, double ease_s)
    : inner_(std::move(inner)), t0_(t_begin_s), ease_s_(ease_s), first_(inner_->pose(t_begin_s)) {}

sim::Pose EasedTrajectory::pose(double t_s) const {
  const sim::Pose p = inner_->pose(t_s);
  if (!(ease_s_ > 0.0) || t_s >= t0_ + ease_s_) return p;
  if (!(t_s > t0_)) return first_;
  const double w = sim::min_jerk((t_s - t0_) / ease_s_);
  sim::Pose out;
  out.position_m = first_.position_m + w * (p.position_m - first_.position_m);
  out.attitude = first_.attitude.slerp(w, p.attitude);
  return out;
}

Layout load_layout(const std::string& dir, double ease_s) {
  Layout l;
  l.dir = dir;
  l.scene = scene::load_scene(dir);
  const std::string yaml = dir + "/scene.yaml";
  l.sample_rate_hz = l.scene.sample_rate_hz;
  l.speed_of_sound_mps = l.scene.speed_of_sound_mps;
  l.room_size_m = room_size_from_environment(l.scene.environment_yaml, yaml);
  if (l.scene.devices.empty()) throw std::runtime_error(yaml + ": the layout has no devices (expected at least one under devices:)");

  // Trajectories: truth.csv rows per device (every row read by the scene's strict reader).
  std::map<std::string, std::pair<std::vector<double>, std::vector<sim::Pose>>> rows;
  if (l.scene.truth && !l.scene.truth->trajectories.empty()) {
    scene::TruthCsvReader reader(l.scene.path(l.scene.truth->trajectories));
    scene::TruthRow r;
    bool first = true;
    while (reader.next(r)) {
      auto& [t, poses] = rows[r.id];
      if (!t.empty() && !(r.t_s > t.back())) continue;  // repeated time: keep the first pose
      sim::Pose p;
      p.position_m = Eigen::Vector3d(r.position_m[0], r.position_m[1], r.position_m[2]);
      p.attitude = Eigen::Quaterniond(r.q_wxyz[0], r.q_wxyz[1], r.q_wxyz[2], r.q_wxyz[3]).normalized();
      t.push_back(r.t_s);
      poses.push_back(p);
      if (first) l.t_begin_s = l.t_end_s = r.t_s;
      first = false;
      l.t_begin_s = std::min(l.t_begin_s, r.t_s);
      l.t_end_s = std::max(l.t_end_s, r.t_s);
    }
  }
  // A device's trajectory: its truth rows (eased in when it moves), else its anchor; an emitter's anchor
  // wins over a single truth row (a simulator writes one row per beacon). False: no position.
  auto place = [&](LayoutDevice& d, const std::optional<scene::Vec3>& anchor, bool anchor_over_one_row) {
    const auto it = rows.find(d.id);
    if (it != rows.end() && !(anchor_over_one_row && anchor && it->second.first.size() == 1)) {
      auto sampled = std::make_shared<sim::SampledTrajectory>(it->second.first, it->second.second);
      d.times_s = it->second.first;
      d.trajectory = sampled->is_static() ? std::shared_ptr<const sim::Trajectory>(sampled)
                                          : std::make_shared<EasedTrajectory>(sampled, l.t_begin_s, ease_s);
    } else if (anchor) {
      d.trajectory = std::make_shared<sim::StaticTrajectory>(Eigen::Vector3d((*anchor)[0], (*anchor)[1], (*anchor)[2]));
      d.times_s = {l.t_begin_s};
    } else {
      return false;
    }
    return true;
  };
  for (const auto& spec : l.scene.devices) {
    LayoutDevice d;
    d.id = spec.id;
    for (const auto& m : spec.mics_m) d.mics_body_m.emplace_back(m[0], m[1], m[2]);
    if (spec.speaker_m) d.speaker_body_m = Eigen::Vector3d((*spec.speaker_m)[0], (*spec.speaker_m)[1], (*spec.speaker_m)[2]);
    d.emits = spec.emits;
    if (l.scene.truth) {
      const auto c = l.scene.truth->clocks.find(spec.id);
      if (c != l.scene.truth->clocks.end()) d.clock = c->second;
    }
    if (!place(d, spec.anchor_position_m, false))
      throw std::runtime_error(yaml + ":" + std::to_string(spec.line) + ": device '" + spec.id +
                               "': no position (expected rows of it in the scene's truth.csv, or an anchor)");
    l.devices.push_back(std::move(d));
  }
  // Emitters that make a sound (beacons): a speaker port, no microphones; static at their anchor, or
  // moving along their truth rows.
  for (const auto& spec : l.scene.emitters) {
    if (std::none_of(spec.emits.begin(), spec.emits.end(), [](const dsp::SignalSpec& s) { return s.acoustic(); })) continue;
    LayoutDevice d;
    d.id = spec.id;
    d.emits = spec.emits;
    d.emitter = true;
    if (!place(d, spec.anchor_position_m, true))
      throw std::runtime_error(yaml + ":" + std::to_string(spec.line) + ": emitter '" + spec.id +
                               "': no position (expected an anchor, or rows of it in the scene's truth.csv)");
    l.devices.push_back(std::move(d));
  }
  if (l.room_size_m) {
    const Eigen::Vector3d& box = *l.room_size_m;
    for (const auto& d : l.devices) {
      std::vector<Eigen::Vector3d> points;
      for (double t : d.times_s) points.push_back(d.trajectory->pose(t).position_m);
      for (const auto& p : points) {
        if ((p.array() < 0.0).any() || (p.array() > box.array()).any()) {
          std::ostringstream msg;
          msg << yaml << ": device '" << d.id << "' at (" << p.x() << ", " << p.y() << ", " << p.z()
              << ") m lies outside environment.room [0, " << box.x() << "] x [0, " << box.y() << "] x [0, " << box.z()
              << "] (the room's walls are the box from the origin to that corner)";
          throw std::runtime_error(msg.str());
        }
      }
    }
  }
  return l;
}

}  // namespace locus::room
