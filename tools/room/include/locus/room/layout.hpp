// The layout of a hardware-in-the-loop room (`locus room`, docs/room.md): which devices exist, where
// their microphones and speaker are on their bodies, how they move, and the room around them — read
// from a scene directory (docs/scene-format.md: scene.yaml's devices, truth.csv's trajectories,
// `environment.room`), typically one `locus simulate FAMILY` wrote.
//
// Why a scene: the scene format is the project's exchange format, so any family's simulated scene (or a
// hand-written one) is a layout; the trajectories are the simulator's (sim::SampledTrajectory: the
// same Catmull-Rom/slerp evaluation the simulator's motion models and IMU synthesis use), and the
// room writes its ground truth back in the same format, so `locus eval` scores a live run as a replay.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "locus/dsp/signals.hpp"
#include "locus/scene/scene.hpp"
#include "locus/sim/trajectory.hpp"

namespace locus::room {

struct LayoutDevice {
  std::string id;
  std::vector<Eigen::Vector3d> mics_body_m;          ///< body frame, channel order (may be empty)
  std::optional<Eigen::Vector3d> speaker_body_m;     ///< body frame; absent: the room plays the device's
                                                     ///< speaker port from its body origin
  std::vector<dsp::SignalSpec> emits;                ///< as declared (copied to the run's scene.yaml)
  std::shared_ptr<const sim::Trajectory> trajectory; ///< layout time (truth.csv's t), eased in (below)
  std::vector<double> times_s;                       ///< truth.csv's times of this device (the truth the room writes)
  std::optional<scene::ClockTruth> clock;            ///< the layout's truth clock (its skew is `--skew scene`)
  /// A scene emitter (a SpyLoc beacon: it plays and records nothing): a speaker port at its body origin,
  /// no microphones; written back under the run's `emitters:`. Its node's frame clock is the room's.
  bool emitter = false;

  /// Where the sound of this device's speaker port comes from (body frame).
  Eigen::Vector3d speaker_or_origin_m() const { return speaker_body_m.value_or(Eigen::Vector3d::Zero()); }
};

struct Layout {
  std::string dir;                        ///< "" for a layout built in code
  scene::Scene scene;                     ///< scene.yaml as loaded (name, environment, emitters...)
  double sample_rate_hz = 44100.0;
  double speed_of_sound_mps = 343.2;
  std::vector<LayoutDevice> devices;
  std::optional<Eigen::Vector3d> room_size_m;  ///< `environment.room: [x, y, z]`: the box [0,x]×[0,y]×[0,z]
  double t_begin_s = 0.0, t_end_s = 0.0;  ///< time range of truth.csv (layout time)

  const LayoutDevice* find(const std::string& id) const;
};

/// A trajectory that starts from rest: over [t_begin, t_begin + ease_s] it blends from the first pose
/// into `inner` with a minimum-jerk weight (after it, `inner` itself). Why: before a layout starts every
/// device holds its first pose, perfectly still; a layout whose first seconds hold a hand's tremor
/// would otherwise start it with a jolt that a gesture tracker takes for a movement.
class EasedTrajectory final : public sim::Trajectory {
 public:
  EasedTrajectory(std::shared_ptr<const sim::Trajectory> inner, double t_begin_s, double ease_s);
  sim::Pose pose(double t_s) const override;
  bool is_static() const override { return inner_->is_static(); }
  double max_speed_mps() const override { return inner_->max_speed_mps(); }

 private:
  std::shared_ptr<const sim::Trajectory> inner_;
  double t0_, ease_s_;
  sim::Pose first_;
};

/// Reads DIR/scene.yaml and its truth.csv. The layout's devices are the scene's devices, then its
/// emitters that emit sound (an acoustic `emits` entry; BLE tags are not the room's). Every device
/// and such emitter needs a trajectory (truth rows, or an anchor);
/// a layout without devices, a device without one, or positions outside `environment.room` are errors
/// (std::runtime_error naming the file and what was expected; scene::SceneError for format errors).
/// Every moving device's trajectory is eased in over the first `ease_s` seconds (EasedTrajectory).
Layout load_layout(const std::string& dir, double ease_s = 1.0);

/// `environment.room` of a scene (the free-form environment YAML), if it is a list of three positive numbers.
/// Throws std::runtime_error when present but malformed.
std::optional<Eigen::Vector3d> room_size_from_environment(const std::string& environment_yaml, const std::string& file);

}  // namespace locus::room
