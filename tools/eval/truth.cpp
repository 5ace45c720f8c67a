// Ground truth for the scorer: scene.yaml (locus::scene::load_scene), truth.csv through the scene
// library's TruthCsvReader, truth_steps.csv through its CsvReader.
#include "locus/eval/truth.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "locus/eval/error.hpp"
#include "locus/scene/pose.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"

namespace locus::eval {

namespace {

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

/// environment.family of scene.yaml ("" when absent); load_scene has already parsed the file.
std::string scene_family(const std::string& yaml_path) {
  const YAML::Node root = YAML::LoadFile(yaml_path);
  const YAML::Node env = root["environment"];
  if (!env || !env.IsMap() || !env["family"]) return "";
  const YAML::Node f = env["family"];
  if (!f.IsScalar() || f.Scalar().empty())
    throw InputError(yaml_path + ":" + std::to_string(f.Mark().line + 1) + ":" + std::to_string(f.Mark().column + 1) +
                     ": environment.family: expected the name of a system (e.g. amil)");
  return f.Scalar();
}

/// True when the scene is a live run's truth whose devices each had the room's IMU (`locus room` writes
/// environment.room_imu: true): their samples stayed on the nodes, as their recordings did.
bool room_imu(const std::string& yaml_path) {
  const YAML::Node env = YAML::LoadFile(yaml_path)["environment"];
  return env && env.IsMap() && env["room_imu"] && env["room_imu"].IsScalar() && env["room_imu"].Scalar() == "true";
}

std::vector<std::string> issues_of(const scene::SceneError& e) {
  std::vector<std::string> out;
  for (const auto& issue : e.issues()) out.push_back(issue.format());
  if (out.empty()) out.emplace_back(e.what());
  return out;
}

}  // namespace

InputError::InputError(std::vector<std::string> messages)
    : std::runtime_error([&] {
        std::string s;
        for (std::size_t i = 0; i < messages.size(); ++i) s += (i ? "\n" : "") + messages[i];
        return s;
      }()),
      messages_(std::move(messages)) {}

void TruthTrack::add(const TruthPose& pose) {
  if (!samples_.empty() && pose.t_s < samples_.back().t_s)
    throw std::invalid_argument("truth samples must come in non-decreasing time");
  samples_.push_back(pose);
}

bool TruthTrack::covers(double t) const {
  if (samples_.size() <= 1) return true;
  return t >= samples_.front().t_s && t <= samples_.back().t_s;
}

TruthPose TruthTrack::at(double t) const {
  if (samples_.empty()) throw std::logic_error("TruthTrack::at on an empty track");
  const scene::TimeBracket at = scene::bracket(samples_.size(), t, [this](std::size_t i) { return samples_[i].t_s; });
  TruthPose out = samples_[at.lo];
  if (at.hi != at.lo) {
    const TruthPose& a = samples_[at.lo];
    const TruthPose& b = samples_[at.hi];
    out.position_m = scene::interpolate_position(a.position_m, b.position_m, at.u);
    out.attitude = scene::interpolate_attitude(a.attitude, b.attitude, at.u);
  }
  out.t_s = t;
  return out;
}

double TruthTrack::path_length_m(double t0, double t1, bool horizontal) const {
  if (samples_.size() < 2 || t1 <= t0) return 0.0;
  auto measure = [&](const Vec3& a, const Vec3& b) {
    Vec3 d = b - a;
    if (horizontal) d.z() = 0;
    return d.norm();
  };
  double length = 0.0;
  Vec3 prev = at(t0).position_m;
  for (const TruthPose& p : samples_) {
    if (p.t_s <= t0) continue;
    if (p.t_s >= t1) break;
    length += measure(prev, p.position_m);
    prev = p.position_m;
  }
  return length + measure(prev, at(t1).position_m);
}

const TruthObject* TruthData::find(const std::string& id) const {
  for (const auto& o : objects)
    if (o.id == id) return &o;
  return nullptr;
}

std::optional<std::string> TruthData::resolve(const std::string& target) const {
  if (find(target) || tracks.count(target)) return target;
  const std::string u = upper(target);
  for (const auto& o : objects)
    for (const auto& a : o.ble_addresses)
      if (a == u) return o.id;
  return std::nullopt;
}

ClockModel TruthData::clock(const std::string& id) const {
  auto it = clocks.find(id);
  return it == clocks.end() ? ClockModel{} : it->second;
}

bool TruthData::has_truth(const std::string& id) const {
  if (tracks.count(id)) return true;
  const TruthObject* o = find(id);
  return o && o->anchor_m;
}

std::optional<TruthPose> TruthData::pose(const std::string& id, double t) const {
  auto it = tracks.find(id);
  if (it != tracks.end() && !it->second.empty()) return it->second.at(t);
  const TruthObject* o = find(id);
  if (o && o->anchor_m) {
    TruthPose p;
    p.t_s = t;
    p.position_m = *o->anchor_m;
    return p;
  }
  return std::nullopt;
}

TruthData load_truth(const std::string& scene_dir) {
  scene::Scene sc;
  try {
    sc = scene::load_scene(scene_dir);
  } catch (const scene::SceneError& e) {
    throw InputError(issues_of(e));
  }
  const std::string yaml = (std::filesystem::path(scene_dir) / "scene.yaml").string();
  if (!sc.truth) throw InputError(yaml + ": the scene has no `truth` section: nothing to score against");
  if (sc.truth->trajectories.empty())
    throw InputError(yaml + ": truth.trajectories is absent: nothing to score against");

  TruthData out;
  out.scene_dir = scene_dir;
  out.scene_name = sc.name;
  out.family = scene_family(yaml);
  const bool imu_in_room = room_imu(yaml);
  for (const auto& d : sc.devices) {
    TruthObject o;
    o.id = d.id;
    o.is_device = true;
    // A device listens when it has a recording, or microphones: the scene of a live run (`locus room`)
    // declares the devices' microphones, their recordings stayed on the nodes.
    o.has_audio = !d.audio.empty() || !d.mics_m.empty();
    o.has_imu = !d.imu.empty() || imu_in_room;
    o.has_speaker = d.speaker_m.has_value();
    if (d.anchor_position_m) o.anchor_m = Vec3((*d.anchor_position_m)[0], (*d.anchor_position_m)[1], (*d.anchor_position_m)[2]);
    for (const auto& s : d.emits)
      if (s.type == "ble") o.ble_addresses.push_back(upper(s.address));
    out.objects.push_back(std::move(o));
  }
  for (const auto& e : sc.emitters) {
    TruthObject o;
    o.id = e.id;
    if (e.anchor_position_m) o.anchor_m = Vec3((*e.anchor_position_m)[0], (*e.anchor_position_m)[1], (*e.anchor_position_m)[2]);
    for (const auto& s : e.emits)
      if (s.type == "ble") o.ble_addresses.push_back(upper(s.address));
    out.objects.push_back(std::move(o));
  }
  for (const auto& [id, c] : sc.truth->clocks) out.clocks[id] = ClockModel{c.offset_s, c.skew_ppm};
  if (sc.truth->magnetic_field_world_ut) {
    const auto& m = *sc.truth->magnetic_field_world_ut;
    out.magnetic_field_world_ut = Vec3(m[0], m[1], m[2]);
  }

  const std::string truth_csv = sc.path(sc.truth->trajectories);
  try {
    scene::TruthCsvReader reader(truth_csv);
    scene::TruthRow row;
    while (reader.next(row)) {
      TruthPose p;
      p.t_s = row.t_s;
      p.position_m = Vec3(row.position_m[0], row.position_m[1], row.position_m[2]);
      p.attitude = Eigen::Quaterniond(row.q_wxyz[0], row.q_wxyz[1], row.q_wxyz[2], row.q_wxyz[3]).normalized();
      out.tracks[row.id].add(p);  // the reader enforces non-decreasing t
    }
  } catch (const scene::SceneError& e) {
    throw InputError(issues_of(e));
  }

  // truth_steps.csv (written by the simulator next to truth.csv): t_true, id, stride_m.
  const std::string steps_csv = sc.path("truth_steps.csv");
  if (std::filesystem::exists(steps_csv)) {
    try {
      scene::CsvReader csv(steps_csv);
      const std::size_t t = csv.require_column("t_true");
      const std::size_t id = csv.require_column("id");
      const std::size_t stride = csv.require_column("stride_m");
      std::vector<TruthStep> steps;
      while (csv.next_row()) {
        TruthStep s;
        s.t_true_s = csv.number(t);
        s.id = std::string(csv.field(id));
        if (s.id.empty()) csv.fail(id, "expected a device id, got an empty field");
        s.stride_m = csv.number(stride);
        if (s.stride_m < 0) csv.fail(stride, "expected a stride length >= 0 m");
        steps.push_back(std::move(s));
      }
      out.steps = std::move(steps);
    } catch (const scene::SceneError& e) {
      throw InputError(issues_of(e));
    }
  }
  // truth_los.csv (SpyLoc simulator): t_true, beacon, los (1 = line of sight, 0 = blocked).
  const std::string los_csv = sc.path("truth_los.csv");
  if (std::filesystem::exists(los_csv)) {
    try {
      scene::CsvReader csv(los_csv);
      const std::size_t t = csv.require_column("t_true");
      const std::size_t beacon = csv.require_column("beacon");
      const std::size_t los = csv.require_column("los");
      std::vector<TruthLos> rows;
      while (csv.next_row()) {
        TruthLos r;
        r.t_true_s = csv.number(t);
        r.beacon = std::string(csv.field(beacon));
        r.los = csv.integer(los, 0, 1) == 1;
        rows.push_back(std::move(r));
      }
      std::stable_sort(rows.begin(), rows.end(), [](const TruthLos& a, const TruthLos& b) { return a.t_true_s < b.t_true_s; });
      out.los = std::move(rows);
    } catch (const scene::SceneError& e) {
      throw InputError(issues_of(e));
    }
  }
  return out;
}

}  // namespace locus::eval
