// AMIL positioning (paper 004, Sec. II-E and IV "Sampling drift"): pure maths, no threads, no plugin
// API. The `amil` localizer (plugins/amil) collects, for one gesture (or several), the player's beep
// positions (IMU-tracked, in the player's start frame) and the beep arrival times in the player's own
// recording, plus every listener's arrival times, and calls solve() once per listener.
//
// Why this file exists separately from the plugin: the positioning is the part of AMIL whose accuracy
// can be reasoned about in closed form (Cramér-Rao bound, Monte-Carlo of the exact solver) and compared
// across methods on the same inputs; keeping it free of the plugin API lets the unit tests, the bound
// tool and the benchmark drive it directly.
//
// Measurement model (all methods). Beep k is emitted at true time T_k from the player's speaker at
// p_k (2D, start frame). The player hears itself at e_k (player clock; a constant speaker-to-mic path
// and any constant latency cancel; a per-beep random speaker latency is *measured* by the
// self-recording, which is why e_k comes from the recording, never from software timestamps). A
// listener at x hears it at a_k (listener clock). With c the speed of sound and s the listener's
// clock skew relative to the player ((1 + s) = listener rate / player rate), up to terms of order
// s·d/c (< 1e-9 s):
//
//     a_k = tau + (1 + s) · (e_k + |x − p_k| / c)            tau: unknown clock offset
//
// so the paper's "delta distance" of beep k against beep 0 is
//
//     dd_k = |x − p_k| − |x − p_0| = c · ((a_k − a_0) / (1 + s) − (e_k − e_0)).
//
// Methods (SolverConfig::method):
//  - Paper: the paper's closed form for every 3-beep subset (two linear equations in (x, y, r0) plus
//    the circle r0 = |x − p_i|: zero, one or two solutions), all candidates' directions filtered by the
//    10° majority window, centroid of the kept candidates. The skew is *given* (SolverConfig::
//    known_skew: the paper's per-model calibration table; 0 = no calibration). Subsets that break the
//    triangle inequality vote only for a direction (along ∓ the movement); when no subset yields a
//    point, the result is direction-only. A lone subset with two solutions reports both (alternatives).
//  - PaperJointSkew: the Paper method with the skew taken from the Joint solution (isolates the
//    effect of the skew estimate from that of the estimator).
//  - Joint: Gauss-Newton / Levenberg-Marquardt least squares over (x, y, s, tau) on all beeps (needs
//    >= 4 beeps heard; with 3 it falls back to Paper with the given skew), initialised by a far-field
//    linearisation (direction) and a 1-D search along it (distance). Covariance from the Jacobian at
//    the solution with the residual variance sigma_k² = timing_std² + (position_std/c)².
//  - Robust (default): Joint with a Huber loss (IRLS) and rejection of a single gross outlier
//    (missed/cycle-slipped beep) when enough beeps remain, so one bad arrival does not move the answer.
//
// Weak geometry: the distance rests on the wavefront curvature (~b²/2r for a gesture of size b), so it
// is poorly determined far away. Every result carries std_m / distance_std_m; when the distance is not
// determined (relative distance std above SolverConfig::max_relative_distance_std, or the solution
// runs to max_range_m) the result is direction-only (located = false, direction_valid = true).
//
// Units: SI (m, s, rad); skew is dimensionless (1e-6 = 1 ppm). Angles: direction_rad = atan2(y, x) in
// the start frame (x right, y ahead: the eval's `player_start` frame).
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locus::plugins::amil {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Speed of sound in dry air from the temperature (same law as the scene format: 331.3 + 0.606·T).
inline double speed_of_sound_mps(double temperature_c) { return 331.3 + 0.606 * temperature_c; }

enum class Method { Paper, PaperJointSkew, Joint, Robust, Network };
/// "paper", "paper_joint_skew", "joint", "robust", "network". Network is a multi-listener method
/// (solve_network); solve() treats it as Robust (a lone listener has no network).
const char* to_string(Method m) noexcept;
std::optional<Method> parse_method(std::string_view name) noexcept;

/// One beep of the player (all gestures of one localisation, in emission order).
struct Beep {
  Eigen::Vector2d position_m{kNaN, kNaN};  ///< emission point (the speaker) in the player's start frame
  double player_time_s = kNaN;             ///< arrival in the player's own recording, player clock; NaN = not found (beep unusable)
  double position_std_m = kNaN;            ///< 1-sigma per axis of position_m (IMU tracking); NaN = SolverConfig::position_std_m
};

/// One listener's arrivals, one per beep (same order and length as the beeps).
struct ListenerArrivals {
  std::vector<double> arrival_s;           ///< listener clock; NaN = missed
  double timing_std_s = kNaN;              ///< 1-sigma error of a_k − (1+s)·e_k (listener and player ends combined); NaN = SolverConfig::timing_std_s
  double known_skew = kNaN;                ///< calibration for Paper (listener vs player); NaN = SolverConfig::known_skew
  /// Optional per-arrival 1-sigma timing error (same length as arrival_s; empty = timing_std_s for all),
  /// e.g. inflated where the detector was unsure of the carrier cycle.
  std::vector<double> arrival_std_s;
  /// Per-axis 1-sigma offset between the point the arrivals measure (the listening mic) and the point
  /// reported (the listener device); added to the position covariance by calibrate_session().
  double reference_offset_std_m = 0.0;
  /// Carrier timing (optional, resolve_cycles()): the carrier period (s; 0 = arrivals not carrier-timed)
  /// and per arrival its frame − envelope_frame (s), the offset of the phase zero chosen from the
  /// envelope maximum (AudioDetection::envelope_frame).
  double carrier_period_s = 0.0;
  std::vector<double> cycle_offset_s;
  /// Optional per-arrival doubt (s) that the arrival is the direct path at all (the detector's
  /// multipath fit disagreed with the envelope: an obstructed listener's reflection looks like that).
  /// It does not weight the fit (resolve_cycles() settles the cycle) but an arrival whose doubt, added
  /// to its std, passes 5x the base timing std is not reliable, and fewer than 4 reliable arrivals mark
  /// the solution `weak`.
  std::vector<double> path_doubt_s;
};

struct SolverConfig {
  Method method = Method::Robust;
  double speed_of_sound_mps = 343.2;       ///< 20 °C
  double timing_std_s = 1.5e-6;            ///< default error of a_k − (1+s)·e_k (both ends, ~0.07 samples at 44.1 kHz)
  double position_std_m = 0.01;            ///< default beep position error per axis (IMU)
  double direction_window_rad = 10.0 * M_PI / 180.0;  ///< Paper: majority window (10°)
  double known_skew = 0.0;                 ///< Paper: skew of every listener (calibration); 0 = none
  double max_abs_skew = 500e-6;            ///< Joint/Robust: skews beyond this are rejected (clock model broken)
  double huber_k = 2.0;                    ///< Robust: Huber threshold in residual sigmas
  double outlier_sigma = 5.0;              ///< Robust: a residual beyond this many sigmas is dropped (one per pass)
  double min_range_m = 0.05;               ///< solutions closer than this are rejected
  double max_range_m = 30.0;               ///< solutions farther than this: distance not determined
  double max_relative_distance_std = 1.0;  ///< distance_std / distance above this: direction-only result
  double min_session_factor = 1.0;         ///< calibrate_session(): lowest variance factor (< 1: the noise model may shrink)
  int max_iterations = 50;
};

enum class Status {
  Located,        ///< position (and direction, distance) valid
  DirectionOnly,  ///< direction valid, distance not determined (no subset solution / weak geometry)
  Ambiguous,      ///< two candidate positions, nothing to choose: position_m = one, alternatives = other
  Failed          ///< too few beeps heard or no direction either (note says why)
};
const char* to_string(Status s) noexcept;

struct Solution {
  Status status = Status::Failed;
  Method method = Method::Robust;
  Eigen::Vector2d position_m{kNaN, kNaN};  ///< start frame; NaN unless Located / Ambiguous
  double direction_rad = kNaN;             ///< atan2(y, x); valid unless Failed
  double distance_m = kNaN;                ///< |position|; NaN when DirectionOnly / Failed
  double std_m = kNaN;                     ///< 1-sigma position error (sqrt of the covariance trace)
  double direction_std_rad = kNaN;
  double distance_std_m = kNaN;
  double confidence = 0.0;                 ///< 0..1: geometry (relative distance std) × fit (residuals vs sigma)
  double skew = kNaN;                      ///< skew used (Paper) or estimated (Joint/Robust)
  double skew_std = kNaN;
  int beeps_heard = 0;                     ///< beeps with both a player time and an arrival
  int beeps_used = 0;                      ///< after outlier rejection (Robust) / in kept candidates' subsets (Paper)
  double rms_residual_s = kNaN;            ///< RMS timing residual of the used beeps (Joint/Robust)
  std::vector<Eigen::Vector2d> alternatives;  ///< other candidate positions (Ambiguous)
  std::vector<Eigen::Vector2d> candidates;    ///< Paper: the kept subset solutions (for maps/debugging)
  std::string note;                        ///< why DirectionOnly/Ambiguous/Failed, or which beep was dropped
  // Fit statistics (Joint/Robust), for calibrate_session(): the fitted point even when the result is
  // direction-only, its a-priori covariance (before any inflation), chi² and degrees of freedom.
  Eigen::Vector2d fit_position_m{kNaN, kNaN};
  Eigen::Matrix2d fit_covariance_m2 = Eigen::Matrix2d::Constant(kNaN);
  double chi2 = kNaN;
  int dof = 0;
  bool inconsistent = false;               ///< residuals far beyond their noise (calibrate_session()), impossible skew
  int reliable_beeps = 0;                  ///< used arrivals whose timing std is near the base (no doubtful cycle)
  bool weak = false;                       ///< reliable_beeps < 4: the answer may be a mirror or far off
  double reference_offset_std_m = 0.0;     ///< ListenerArrivals::reference_offset_std_m (calibrate_session())
  bool located() const { return status == Status::Located || status == Status::Ambiguous; }
};

/// [main] Positions one listener. Never throws on bad measurements (they give Status::Failed and a
/// note); throws std::invalid_argument when arrivals.arrival_s.size() != beeps.size() or the config is
/// out of range (c <= 0, negative stds, window <= 0, ...).
Solution solve(const std::vector<Beep>& beeps, const ListenerArrivals& arrivals, const SolverConfig& cfg);

/// Several listeners of the same gesture(s) at once ("network"): the listeners share the beep
/// positions, so the IMU's beep position errors (prior: Beep::position_std_m / SolverConfig::
/// position_std_m per axis) are estimated jointly with every listener's (x, y, skew, offset) from all
/// arrivals (Gauss-Newton, Huber IRLS); each listener's residual sigma is then the timing error alone.
/// Starts from the per-listener Robust solutions; listeners without one (fewer than 4 beeps heard, no
/// convergence) keep their per-listener solution, and with fewer than 3 usable listeners every
/// listener gets its per-listener solution. Listeners whose residuals disagree with the network (an
/// obstructed listener: its first path is a reflection) are left out and the network re-solved.
/// Same errors as solve().
struct NetworkSolution {
  std::vector<Solution> listeners;                ///< one per ListenerArrivals, same order
  std::vector<Eigen::Vector2d> beep_correction_m; ///< estimated error of each Beep::position_m (add to correct)
  int listeners_in_network = 0;
  std::vector<int> excluded;                      ///< listeners left out as inconsistent (RMS residual > max(5σ, 3× median)); they keep their own solution
  int iterations = 0;
  std::string note;
};
NetworkSolution solve_network(const std::vector<Beep>& beeps, const std::vector<ListenerArrivals>& arrivals,
                              const SolverConfig& cfg);

/// [main] Session-level calibration of the uncertainty of all listeners of one gesture (Joint/Robust
/// solutions; others are left as they are). One listener's fit has few degrees of freedom (one with
/// 5 beeps), so its own chi² is too noisy to scale its covariance; the listeners of a session share the
/// player's track and detector, so their pooled residuals (robust mean of chi²/dof over the listeners)
/// say how optimistic the a-priori sigmas were. Every covariance is scaled by max(1, that factor) and
/// std_m / direction / distance stds, the direction-only decision and the confidence are recomputed.
/// A listener whose chi² exceeds the 99.9 % quantile of chi²(dof) times the session factor is marked
/// `inconsistent` (its confidence divided by 10): an arrival that is not the direct path, a cycle slip.
/// Returns the session factor (1 when nothing could be pooled).
double calibrate_session(std::vector<Solution>& listeners, const SolverConfig& cfg);

/// For a listener its data doubt (`weak`: few reliable arrivals, `inconsistent`: residuals beyond the
/// noise), the Gaussian direction std stands on arrivals that may be reflections or slipped cycles. The
/// leave-one-out fits (each heard beep dropped in turn; 4 beeps still fix x, y, skew and offset) show
/// how far one arrival moves the direction: when their jackknife spread exceeds direction_std_rad, it
/// becomes the direction std (and a located listener's std_m takes it across range). Returns the
/// jackknife direction std (NaN when fewer than 3 leave-one-out fits solve).
double widen_by_jackknife(const std::vector<Beep>& beeps, const ListenerArrivals& arrivals, const SolverConfig& cfg,
                          Solution& s);

/// [main] Carrier-cycle ambiguity of one listener's arrivals (needs ListenerArrivals::carrier_period_s
/// and cycle_offset_s, >= 5 arrivals heard). A carrier-timed arrival is exact within its carrier
/// cycle but the cycle comes from the envelope maximum, which multipath within a few envelope widths
/// and transducer responses move by a sample or two from beep to beep: a one-cycle slip (~2.2 samples,
/// 17 mm at 20 kHz) wrecks the distance and shows as a confident wrong answer. Integer least squares:
/// every combination of whole-cycle shifts n_k in [-max_shift, max_shift] (the first heard arrival fixed: a common
/// shift is the clock offset's; beyond 2e5 combinations, e.g. three gestures' 13 beeps, a coordinate
/// descent from no shift, whose runner-up is the best single change) is scored by
///     chi²_geometry(n)  the residual of the measurement model linearised at the best fit
///                       (position, skew, offset free), with the arrivals' sigmas, plus
///     chi²_envelope(n)  sum_k (offset_k + n_k·P − mean)² / envelope_std²: the envelope-to-phase
///                       offset is the channel's, the same for every beep up to its jitter;
/// the best one is applied (arrival_s moved by n_k·P) and the fit re-linearised until n is stable.
/// When a combination with other shifts scores within `decisive_chi2` of the best, the arrivals where
/// they differ keep a doubtful cycle: their arrival_std_s is raised to at least half a period (they
/// then do not count as reliable). Returns the number of arrivals moved (0 when not applicable).
/// With `alternative` given, the doubtful arrivals keep their std instead and the runner-up is returned
/// there, for the caller to solve both and widen the answer by their spread (cycle_mixture()): a
/// discrete ambiguity of whole cycles is not a Gaussian half-cycle error, and treating it as one threw
/// away distances that both hypotheses agree on.
struct CycleAlternative {
  bool valid = false;              ///< a runner-up within decisive_chi2 exists
  std::vector<double> shift_s;     ///< per arrival (caller index): add to arrival_s for the runner-up
  double delta_chi2 = 0.0;         ///< its score minus the best's (>= 0), linearised at the best fit
  double delta_envelope_chi2 = 0.0;  ///< the envelope prior's part of delta_chi2
};
struct CycleOptions {
  double envelope_std_periods = 0.35;  ///< beep-to-beep jitter of the envelope-to-phase offset (periods)
  double decisive_chi2 = 4.0;          ///< a runner-up closer than this leaves the differing cycles doubtful
  int max_shift = 2;                   ///< n_k in [-max_shift, max_shift] (relative to the first heard arrival)
  int max_rounds = 3;
};
int resolve_cycles(const std::vector<Beep>& beeps, ListenerArrivals& arrivals, const SolverConfig& cfg,
                   const CycleOptions& opt = {}, CycleAlternative* alternative = nullptr);

/// The runner-up of resolve_cycles() solved too, and `best`'s fit covariance replaced by the two
/// hypotheses' mixture about the best point: (1 − w)·P_best + w·(P_alt + d·dᵀ), d = alt − best,
/// w = 1 / (1 + exp(Δχ²/2)) with Δχ² from the two refits (their residual chi² plus the envelope
/// prior's difference). A no-op when the alternative is not valid, does not solve, or solves beyond
/// max_range_m (a flat wavefront: no listener of the session can be there).
void cycle_mixture(const std::vector<Beep>& beeps, const ListenerArrivals& arrivals, const CycleAlternative& alternative,
                   const SolverConfig& cfg, Solution& best);

/// The closed form of one 3-beep subset (Sec. II-E, Eq. 1): listener x with |x − p_j| − |x − p_i| =
/// dd_j and |x − p_k| − |x − p_i| = dd_k. Returns 0, 1 or 2 points (any frame). Exposed for tests.
std::vector<Eigen::Vector2d> solve_three(const Eigen::Vector2d& p_i, const Eigen::Vector2d& p_j,
                                         const Eigen::Vector2d& p_k, double dd_j, double dd_k);

/// Cramér-Rao bound of (x, y, s, tau) for a listener at `listener_m` with skew `skew`, beeps at
/// `positions_m` emitted at player times `player_times_s`, independent Gaussian timing errors
/// timing_std_s on every arrival and position errors position_std_m per axis on every beep position.
struct Bound {
  double std_x_m = kNaN, std_y_m = kNaN, std_m = kNaN;   ///< std_m = sqrt(var x + var y)
  double direction_std_rad = kNaN, distance_std_m = kNaN, skew_std = kNaN;
};
Bound cramer_rao(const std::vector<Eigen::Vector2d>& positions_m, const std::vector<double>& player_times_s,
                 const Eigen::Vector2d& listener_m, double skew, double timing_std_s, double position_std_m,
                 double speed_of_sound_mps);

/// Synthesises exact arrivals (no noise) for a listener at x with skew s and offset tau (tests, bound
/// tool): a_k = tau + (1 + s)(e_k + |x − p_k| / c).
std::vector<double> exact_arrivals(const std::vector<Beep>& beeps, const Eigen::Vector2d& listener_m, double skew,
                                   double tau_s, double speed_of_sound_mps);

}  // namespace locus::plugins::amil

// CHANGELOG (interface between amil-solver and amil-plugin; keep old signatures working)
// - v1 (amil-solver): first version.
// - v2 (amil-solver): solve_network() + NetworkSolution (all listeners at once, beep positions refined);
//   additive, solve() unchanged. Method::Network ("network"): the plugin calls solve_network() with
//   all listeners of the session when cfg.method == Method::Network (solve() = Robust for it). Measured
//   (locus_amil_bound, 1 cm IMU error): distance error roughly 0.7x of Robust's, more listeners with a
//   position; with 3 gestures and 3 mm, 3-6x better.
