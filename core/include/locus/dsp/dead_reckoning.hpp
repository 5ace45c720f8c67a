// Pedestrian dead reckoning: a walker's path from step events (time, stride) and heading samples.
//
// Why here: LocBLE places tags along the observer's walked path and SpyLoc carries its track between
// beacon ranges with the same steps; both get steps from the `steps` detector and headings from
// `attitude` (relative: its yaw, any branch), so the path lives in one place.
//
// Frame: the walker's start frame: origin = the walker at the first heading sample, y = the heading
// then (the phone's pointing direction projected on the horizontal), x = y × up (to the right).
// Headings are counter-clockwise (a left turn increases them), so a step of length s at relative
// heading h moves the walker by s·(−sin h, cos h) (step_direction()).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

namespace locus::dsp {

/// a wrapped into [−π, π).
double wrap_pi(double a);

/// Unit displacement of a step at relative heading h (see the file comment for the frame).
inline Eigen::Vector2d step_direction(double heading_rad) { return {-std::sin(heading_rad), std::cos(heading_rad)}; }

/// The observer's path from its steps and headings (see the file comment for the frame). Every
/// method is [main] (the localizer's dispatcher thread; adding allocates).
class DeadReckoning {
 public:
  /// [main] A heading sample (rad, counter-clockwise; any branch: samples are unwrapped). The first
  /// one fixes the frame's y axis. Samples must come in time order (older ones are ignored).
  void add_heading(double t_s, double heading_rad);
  /// [main] A step ending at t_s of length stride_m. The step's direction is the mean relative heading
  /// over the step (from the previous step, or 1/frequency_hz before t_s for the first one).
  /// Returns false (and ignores it) when the step is not after the previous one or its values are
  /// not finite / not positive.
  bool add_step(double t_s, double stride_m, double frequency_hz);

  bool has_frame() const noexcept { return has_ref_; }
  double frame_time_s() const noexcept { return ref_t_s_; }
  std::size_t steps() const noexcept { return step_t_.size(); }
  /// Position at t_s (linear between step ends; 0 before the first step, the last position after).
  Eigen::Vector2d position_at(double t_s) const;
  /// Walked distance at t_s (same interpolation).
  double path_length_at(double t_s) const;
  /// Relative heading (rad) of the latest step (0 before any).
  double current_heading_rad() const noexcept { return step_heading_.empty() ? 0.0 : step_heading_.back(); }
  /// Index of the first step of the second leg: the first step whose heading differs from the first
  /// step's by more than `turn_rad`; nullopt while the walk is straight.
  std::optional<std::size_t> turn_step(double turn_rad) const;
  /// Time at which step i ends / begins.
  double step_end_s(std::size_t i) const { return step_t_.at(i); }
  double step_begin_s(std::size_t i) const { return i == 0 ? first_begin_s_ : step_t_.at(i - 1); }
  double step_heading_rad(std::size_t i) const { return step_heading_.at(i); }

 private:
  double mean_heading(double t0, double t1) const;

  bool has_ref_ = false;
  double ref_t_s_ = 0.0, ref_heading_ = 0.0, last_raw_ = 0.0, unwrapped_ = 0.0;
  std::vector<double> head_t_, head_rel_;  ///< unwrapped heading relative to the first sample
  double first_begin_s_ = 0.0;
  std::vector<double> step_t_, step_heading_, cum_len_;
  std::vector<Eigen::Vector2d> step_pos_;  ///< position at each step end
};

}  // namespace locus::dsp
