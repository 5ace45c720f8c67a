// AMIL movement tracking (paper 004, Sec. II-C): where the player's speaker was at every beep, in the
// player's start frame, from its accelerometer and gyroscope alone.
//
// Why a class of its own: the tracker is the part of the player that can be checked against the
// simulator's truth (truth.csv, truth_emissions.csv) without audio, links or solver; the plugin feeds
// it ImuSamples and asks where a beep was.
//
// Algorithm (streaming; the paper's three steps, with the deviations noted):
//  1. Motion detection on bins. Samples are grouped into bins of `bin_s` (device-local time). A bin's
//     statistic is the RMS deviation of its accelerometer vectors from the current rest reference (the
//     mean accelerometer vector of the last rest), i.e. sqrt(trace(cov) + |mean − rest|²). The paper
//     uses the std of each bin; the std about the bin's OWN mean drops near the acceleration peak of a
//     smooth stroke (the acceleration is flat there) and misses the magnitude of a horizontal move on a
//     table (|g + a| barely changes), so the deviation from rest is used: it is the std whenever the
//     bin is at rest and grows with any acceleration or tilt change. A bin above
//     `motion_threshold_mps2` starts a movement; as the paper, its start is taken conservatively, here
//     one whole bin earlier (min-jerk strokes accelerate slowly at first; integrating a bin of rest is
//     harmless after step 3). The movement ends after `quiet_bins` consecutive bins below the
//     threshold, at the END of the last of them (the slow tail of the stroke is integrated too; cutting
//     it leaves a velocity that the linear de-drift would smear over the whole stroke).
//  2. Rotation into the start frame. The gyroscope, minus its bias (the mean rate over the session's rests so far), is
//     integrated (quaternion, mid-point rate) from the session start T; accelerometer vectors are
//     rotated into the body frame at T and then into the level start frame (below). The paper's
//     roll-pitch-yaw matrix product is the same rotation for small steps; the quaternion does not
//     degrade for large ones.
//  3. Gravity removal and velocity compensation. The rest reference, rotated into the start frame,
//     is subtracted (gravity plus the accelerometer bias in that frame); the remainder is integrated
//     (trapezoid) to velocity; at the end of the movement the velocity must be zero, so, as Sec. II-C,
//     v'(t) = v(t) − v(t_end)·(t − t_start)/(t_end − t_start) (any constant acceleration error goes);
//     v' is integrated to the displacement. During a pause the position holds.
//     Deviation: a hand holding a phone on a table trembles (8-12 Hz, tens of µm, a few mm/s), so the
//     velocity at the instant a movement is taken to start or end is not zero, only its mean over a
//     rest is; pinning instants leaves the boundary velocities' ~v·T per movement (7 mm over one
//     triangle in the simulator, 0.4 mm without the tremor). The integration therefore spans up to
//     `rest_window_s` of the rest before the movement and the quiet bins after it, the linear
//     velocity error v(t) = α + β t is fitted so that the velocity has zero mean over both rests
//     (least squares over their samples), and a pause's position is the mean position over its
//     samples; with fewer than 3 rest samples on a side, the two-instant rule above applies. A
//     movement's quiet bins are also the next movement's rest before: with 0.3 s pauses the confirmed
//     rest between two strokes is often empty, and the two-instant rule left 3-6 mm per stroke.
//
// Uncertainty: every pause carries a 1-sigma per-axis error of its position, from three terms that the
// de-drift does not remove: (a) white accelerometer noise, double-integrated over each movement and
// pinned at both ends (a Brownian bridge: sigma_a·sqrt(dt·T³/12) per movement, sigma_a measured at rest),
// accumulating over the movements; (b) accelerometer scale and cross-axis errors, proportional to the
// displacement from the session start (they cancel when the gesture returns to its start); (c) the
// non-constant part of the acceleration error (tilt from gyro bias, bias random walk), which the linear
// de-drift leaves behind: a fraction of the drift it removed (v_end·T), accumulating; plus a floor.
//
// Sessions: a session (one localisation: one or several gestures) opens at the first movement after a
// rest of at least `min_rest_s` and closes after a rest of `session_gap_s`, when its
// `session_movements`-th movement ends (when set), or by close_session().
// Its start frame ("player_start@T", docs/eval.md): origin = the device body origin at T (the start
// of the first movement), z = up (the rest gravity before T), y = the body y axis at T projected on
// the horizontal plane (body −z when body y is within 11.5° of vertical: an upright phone), x = y × z.
// A gap in the IMU stream longer than `max_gap_s` or time going backwards abandons an open session
// (counted; the plugin warns).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

namespace locus::plugins::amil {

struct TrackerConfig {
  double bin_s = 0.1;                   ///< motion-detection bin length (s, device-local)
  double motion_threshold_mps2 = 0.5;   ///< RMS deviation from rest that marks a moving bin (m/s²)
  int quiet_bins = 2;                   ///< consecutive quiet bins that end a movement
  double min_rest_s = 0.3;              ///< rest needed before a session can start (gravity, gyro bias)
  double session_gap_s = 2.0;           ///< a rest this long closes the session
  int session_movements = 0;            ///< > 0: the session also closes when its Nth movement ends (a
                                        ///< gesture of known strokes, e.g. 4 for one triangle from its base: live, the
                                        ///< estimate need not wait session_gap_s); 0 = by session_gap_s only
  double max_gap_s = 0.25;              ///< longer IMU gaps abandon the open session
  Eigen::Vector3d speaker_body_m = Eigen::Vector3d::Zero();  ///< speaker in the body frame (geometry)
  // Uncertainty model of the tracked positions (see "Uncertainty" above).
  double accel_scale_error = 0.003;     ///< relative scale + cross-axis error of the accelerometer (1 sigma)
  double drift_shape_factor = 0.01;     ///< residual of the linear de-drift, as a fraction of v_end·T (1 sigma)
  double position_floor_m = 0.0005;     ///< error of a pause position that no term models (hand wiggle), per axis
  double rest_window_s = 0.3;           ///< rest integrated on each side of a movement (zero-mean velocity, below)
};

/// One rest of the player inside a session (the first one ends at the session start T).
struct Pause {
  double t_start_s = 0.0;       ///< device-local
  double t_end_s = 0.0;         ///< the next movement's start; +inf while the pause lasts
  Eigen::Vector3d body_m = Eigen::Vector3d::Zero();     ///< body origin in the start frame
  Eigen::Vector3d speaker_m = Eigen::Vector3d::Zero();  ///< speaker in the start frame
  double position_std_m = 0.0;  ///< 1-sigma error per horizontal axis of body_m / speaker_m ("Uncertainty")
};

/// One movement between two pauses.
struct Movement {
  double t_start_s = 0.0, t_end_s = 0.0;  ///< integration span (with the margins)
  double t_active_start_s = 0.0, t_active_end_s = 0.0;  ///< first to last moving bin: outside it the phone rests
  Eigen::Vector3d displacement_m = Eigen::Vector3d::Zero();  ///< start frame
  double end_speed_mps = 0.0;   ///< |v(t_end)| before de-drift (size of the drift removed)
  double accumulated_var_m2 = 0.0;  ///< variance this movement adds to every later pause (noise + drift terms)
  std::vector<double> t_s;      ///< sample times of the integrated trajectory
  std::vector<Eigen::Vector3d> body_m;  ///< body origin in the start frame at t_s (after de-drift)
};

struct Session {
  std::uint64_t id = 0;         ///< 1, 2, ... in order
  double t_start_s = 0.0;       ///< T: start of the first movement (device-local), the frame's time
  double t_end_s = std::numeric_limits<double>::infinity();  ///< end of the last movement once closed
  bool closed = false;
  Eigen::Matrix3d level = Eigen::Matrix3d::Identity();  ///< body frame at T -> start frame
  std::vector<Pause> pauses;    ///< pauses[k] precedes movements[k]
  std::vector<Movement> movements;

  /// Where the speaker was at device-local time t: the pause holding t, or inside a movement the
  /// interpolated trajectory (plus the speaker offset at the movement's end attitude). `in_pause`:
  /// false when t lies between the movement's first and last moving bin (the margins are rest).
  /// t before the first pause or after the end returns false. `std_m` (when given): the position's 1-sigma
  /// error per horizontal axis (the pause's; inside a movement the larger of the two pauses around it).
  bool speaker_at(double t_s, Eigen::Vector3d& out_m, bool* in_pause = nullptr, double* std_m = nullptr) const;
};

struct TrackerCounters {
  std::uint64_t samples = 0;
  std::uint64_t non_finite = 0;         ///< samples ignored
  std::uint64_t gaps = 0;               ///< IMU gaps / time going back (state reset)
  std::uint64_t abandoned_sessions = 0; ///< open sessions lost to a gap
  std::uint64_t sessions = 0;           ///< sessions opened
};

class GestureTracker {
 public:
  /// Called when a movement ends (a pause starts: where a live player beeps) and when a session closes.
  using PauseHandler = std::function<void(const Session&, double t_s)>;

  explicit GestureTracker(TrackerConfig cfg = {});

  /// [main] One IMU sample (body frame, specific force with gravity, rad/s; device-local t_s).
  void add(double t_s, const Eigen::Vector3d& accel_mps2, const Eigen::Vector3d& gyro_radps);
  /// [main] Ends the open movement (at the last sample) and closes the open session (end of stream).
  void close_session();

  void on_pause(PauseHandler h) { on_pause_ = std::move(h); }
  void on_session_closed(PauseHandler h) { on_closed_ = std::move(h); }

  /// Every session so far (closed ones and the open one last).
  const std::vector<Session>& sessions() const noexcept { return sessions_; }
  bool moving() const noexcept { return moving_; }
  /// Time the device has been at rest (0 while moving or before any sample).
  double rest_s() const noexcept;
  double last_t_s() const noexcept { return last_t_; }
  const TrackerCounters& counters() const noexcept { return counters_; }
  const TrackerConfig& config() const noexcept { return cfg_; }

 private:
  struct Sample {
    double t;
    Eigen::Vector3d a, w;
  };
  void end_bin();
  void start_movement(double t_start);
  void end_movement(double t_end);
  void reset_state();
  Eigen::Matrix3d level_from_gravity(const Eigen::Vector3d& up_body) const;

  TrackerConfig cfg_;
  PauseHandler on_pause_, on_closed_;
  std::vector<Session> sessions_;
  TrackerCounters counters_;

  double last_t_ = std::numeric_limits<double>::quiet_NaN();
  // current bin
  double bin_start_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<Sample> bin_, prev_bin_;
  std::vector<Sample> rest_tail_;  ///< the latest confirmed rest samples (at most rest_window_s)
  // rest statistics (since the last movement ended, or since the start)
  double rest_start_ = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d rest_a_sum_ = Eigen::Vector3d::Zero(), rest_w_sum_ = Eigen::Vector3d::Zero();
  std::uint64_t rest_n_ = 0;
  Eigen::Vector3d rest_a_ = Eigen::Vector3d::Zero();  ///< rest reference (body frame)
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d bias_w_sum_ = Eigen::Vector3d::Zero();  // gyro rates summed over the session's rests
  std::uint64_t bias_n_ = 0;
  Eigen::Vector3d rest_a_sq_sum_ = Eigen::Vector3d::Zero();  ///< per-axis sum of squares at rest (noise level)
  Eigen::Vector3d rest_d2_sum_ = Eigen::Vector3d::Zero();    ///< per-axis sum of squared second differences at rest
  std::uint64_t rest_d2_n_ = 0, rest_prev_n_ = 0;
  Eigen::Vector3d rest_prev_[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};  ///< the last two rest samples
  double accel_noise_mps2_ = 0.0;  ///< white accelerometer noise per sample (per axis), from the last rest
  double session_var_m2_ = 0.0;    ///< accumulated noise + drift variance of the open session
  bool have_rest_ = false;
  // movement in progress
  bool moving_ = false;
  int quiet_run_ = 0;
  double move_start_ = 0.0, active_start_ = 0.0, active_end_ = 0.0;
  std::vector<Sample> move_;
  // attitude of the body relative to the body at T (session open), integrated over every sample
  bool session_open_ = false;
  Eigen::Quaterniond q_ = Eigen::Quaterniond::Identity();
  Sample q_last_{};
  bool q_has_last_ = false;
};

}  // namespace locus::plugins::amil
