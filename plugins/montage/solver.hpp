// The maths of `montage` (paper 002), free of the plugin API: ETOA ranging (Sec. 3), rounds, and the
// formation (Sec. 2) from ranges and movement vectors.
//
// Formation, in the translation frame of one user (the first localized: its position at the first
// solved round is the origin) with world-aligned axes (its movement vectors' frame):
//  1. Difference vectors (Eq. 1-2), over every ranged round: the distance vector of a pair,
//     R_ij(f) = P_j − P_i at its first ranged round f, has the measured length r_ij(f) and an unknown
//     orientation θ; every later ranged round k predicts |R_ij(f) + D_ij(k)| = r_ij(k), with the
//     difference vector D_ij(k) = M_j(f→k) − M_i(f→k) from the two users' movement vectors. θ is searched
//     over the circle (the paper solves Eq. 2 for two rounds: one or two solutions; over more rounds
//     the wrong one of the two stops fitting, which is the paper's single-neighbour disambiguation
//     "using new movement vectors"). A pair whose second-best θ (≥ 20° away) fits nearly as well is
//     ambiguous (two candidates kept); one whose users moved alike has no solution yet.
//  2. Ranging triangles (Eq. 3): of the start triangle's 2x2x2 candidate combinations the one with
//     the smallest |R_ij + R_jk − R_ik|; growth of the localized set breadth-first: first every user
//     with two localized neighbours (the candidate pair with the smallest closure), then users with one
//     neighbour whose pair is unambiguous.
//  3. Global fine-tuning: a robust (Huber) least-squares adjustment of every localized user's
//     positions at every round of a sliding window, with the ranges, the movement vectors between
//     rounds, and per user a heading offset δ_i (prior: the acceleration estimate) and a stride scale
//     k_i (the paper's k, calibrated online from ranging). This generalises the paper's fine-tuning of
//     distance-vector orientations (minimal rotations that close every ranging triangle): the ranges
//     are kept as measured and the orientations follow from the positions.
//     Gauge: the origin's first position (translation) and the origin's δ, set once at its first
//     localization (rotation), so every solve publishes in one frame. The offset priors are
//     world-aligned; the frame's rotation from the world, ψ, is one more unknown that every prior
//     shares (δ_u − ψ ~ prior_u). Ranges fix the formation's shape at each round, but not the group's
//     common motion (its translation and rotation from round to round): only the movement vectors do,
//     through k_u and δ_u. Holding the origin's δ at its own prior (before) made that prior's error a
//     bias of every other δ (the others' priors, absolute, disagreed with the frame by that error),
//     and the group's common motion turned with it (docs/montage.md, "The maths").
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "messages.hpp"

namespace locus::plugins::montage {

/// ETOA (paper Sec. 3, ref. [17]): device i measured dt_i = t_j^i − t_i^i (j's arrival minus its own
/// emission, its clock), device j measured dt_j = t_i^j − t_j^j. Then
///   d_ij = c/2 · (dt_i + dt_j) + (self_i + self_j)/2,
/// where self_* is each device's own speaker-to-mic distance (its own emission reaches its mic after
/// self/c, the other's after d/c). No clock sync is needed: only differences on one clock enter.
double etoa_distance_m(double dt_i_s, double dt_j_s, double self_i_m, double self_j_m, double c_mps);

/// One ranging round: every device's report (own emission at tau_own since its start signal, the
/// others' arrivals), grouped by tau.
struct Round {
  double tau_s = 0.0;  ///< mean tau_own of its reports
  std::map<std::string, RoundMessage> reports;
};

/// Groups round reports: a report joins the round whose tau is within `match_s` and that holds no
/// report of its device yet, else starts a new one. Rounds stay in tau order.
class RoundBook {
 public:
  explicit RoundBook(double match_s = 0.3) : match_s_(match_s) {}
  /// Index of the round the report went to.
  std::size_t add(const RoundMessage& m);
  const std::vector<Round>& rounds() const noexcept { return rounds_; }

 private:
  double match_s_;
  std::vector<Round> rounds_;
};

struct RangeObs {
  std::size_t i = 0, j = 0;  ///< user indices, i < j
  double distance_m = 0.0;
  double extra_std_m = 0.0;  ///< added (in quadrature) to FormationConfig::range_std_m: a one-way range's clock model
};

/// The ETOA ranges of one round between users (indices into `users`), each checked: both devices
/// reported each other, 0 < d <= max_range_m.
std::vector<RangeObs> round_ranges(const Round& round, const std::vector<std::string>& users, double c_mps,
                                   double max_range_m);

/// One-way ranges (ours, beyond the paper): a pair's round where only ONE device heard the other is
/// lost to ETOA, which needs both arrivals. But the two devices' clocks are related by a line: with
///   rho_i(j) = c·(tau_own_i + dt_i(j) − tau_own_j) + self_j      (i heard j)
/// (tau since each device's own reception of the one radio start signal), rho_i(j) = d − c·eps and
/// rho_j(i) = d + c·eps, where eps(tau) = a + b·tau is the pair's clock difference since the start
/// (a: the two radio reception latencies; b: the clocks' skew difference, < 80 ppm). Each two-way
/// round measures eps = (rho_j(i) − rho_i(j)) / 2c; a Bayesian line through them (priors on a and b)
/// predicts eps at a one-way round, which then gives d = rho_i(j) + c·eps with the prediction's std.
/// Wrong detections are the risk (a one-way range has no second arrival to average with; on
/// montage-103 one device took a code ~80 ms late for four rounds running): a two-way round whose eps
/// is far off the pair's line has a wrong arrival and is dropped (learn_clocks), and a one-way range
/// must lie within max_speed_mps · Δtau of the pair's last accepted range.
struct PairClockOptions {
  double offset_prior_s = 2e-3;  ///< prior sd of a (radio reception latencies: < 1 ms apart in the foreign scenes)
  double skew_prior = 6e-5;      ///< prior sd of b (skews up to ±40 ppm each)
  double obs_std_s = 1e-4;       ///< sd of one two-way eps (detection timing, conservative)
  double outlier_sigma = 5.0;    ///< a two-way eps this many sds off the others' line is not used
  double max_extra_std_m = 0.3;  ///< a one-way range whose clock prediction is less certain is not made
  int min_two_way = 2;           ///< two-way rounds of the pair before one-way ranges are made
  double max_speed_mps = 3.0;    ///< how fast a pair's distance can change (two walkers)
  double max_gap_s = 2.0;        ///< a one-way range needs an accepted range of the pair this recent
  std::size_t max_rounds = 30;   ///< the line is fitted to the pair's latest rounds only (cost O(n³); clocks drift)
};
class PairClocks {
 public:
  explicit PairClocks(PairClockOptions opt = {}) : opt_(opt) {}
  /// A two-way round of pair (i, j), i < j: its eps (s) at tau (s).
  void add(std::size_t i, std::size_t j, double tau_s, double eps_s);
  /// eps at tau and its sd, from the pair's two-way rounds (nullopt before the first): a Bayesian line
  /// through the rounds that agree with each other (with 3 or more, the pair of rounds whose line most
  /// others lie on, slope within 4 sd of the skew prior, decides which).
  std::optional<std::pair<double, double>> predict(std::size_t i, std::size_t j, double tau_s) const;
  /// Two-way rounds of the pair held (the latest max_rounds, those found off the line included).
  std::size_t count(std::size_t i, std::size_t j) const;
  /// The pair's latest accepted range (tau, d), for the one-way gate.
  void accept(std::size_t i, std::size_t j, double tau_s, double d_m) { last_[{std::min(i, j), std::max(i, j)}] = {tau_s, d_m}; }
  std::optional<std::pair<double, double>> last(std::size_t i, std::size_t j) const;
  const PairClockOptions& options() const noexcept { return opt_; }

 private:
  PairClockOptions opt_;
  std::map<std::pair<std::size_t, std::size_t>, std::vector<std::pair<double, double>>> obs_;
  std::map<std::pair<std::size_t, std::size_t>, std::pair<double, double>> last_;
};

/// The one-way ranges of one round: pairs that round_ranges() could not range (one arrival missing)
/// but whose clocks `clocks` predicts, each with its extra std; 0 < d <= max_range_m.
std::vector<RangeObs> one_way_ranges(const Round& round, const std::vector<std::string>& users, double c_mps,
                                     double max_range_m, const PairClocks& clocks);
/// Feeds `clocks` with the two-way ranges of a round (their eps, all of them) and removes from `two_way`
/// those whose eps is off the pair's line (predict(): the consensus of its earlier rounds) by more
/// than outlier_sigma, once the pair has min_two_way rounds.
void learn_clocks(const Round& round, const std::vector<std::string>& users, double c_mps,
                  std::vector<RangeObs>& two_way, PairClocks& clocks);

struct FormationConfig {
  double range_std_m = 0.15;         ///< 1-sigma of an ETOA range
  double step_std_m = 0.08;          ///< per step, isotropic (stride and direction noise)
  double drift_std_m_per_m = 0.05;   ///< movement error growing with the distance walked (heading bias)
  double offset_prior_std_rad = 0.35;///< heading offset δ_i around the acceleration estimate
  double scale_prior_std = 0.2;      ///< stride scale k_i around 1
  double huber_k = 2.0;              ///< Huber threshold (sigmas) of range residuals
  double outlier_sigma = 6.0;        ///< a range this many sigmas off the adjusted formation is dropped
  double ambiguity_chi2 = 6.0;       ///< a second orientation within this of the best keeps a pair ambiguous
  double max_closure_m = 1.5;        ///< a triangle / two-neighbour placement closing worse is refused
  int window_rounds = 30;            ///< rounds adjusted together (older ones are fixed)
  int iterations = 8;                ///< Gauss-Newton iterations per solve
  /// The frame's rotation from the world (ψ) estimated from every user's offset prior (true), or
  /// taken from the origin's prior alone (false: ψ = 0, the origin's prior error biases every other
  /// δ). Off by default: better on the synthetic walks and the held-out simulator seeds 21-30, worse
  /// on the foreign montage-103 (docs/montage.md, "The maths": the gauge).
  bool shared_frame_rotation = false;
  /// Widen the position covariance by the adjustment's reduced chi-square when it exceeds 1 (ranges
  /// and movements fitting worse than their stds say).
  bool chi2_std_inflation = true;
};

/// Where one user is at one round.
struct UserFix {
  bool localized = false;
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  double std_m = 0.0;
};

class Formation {
 public:
  Formation(std::vector<std::string> users, FormationConfig cfg = {});

  /// A step of user u ending at tau_s (raw stride, phone heading; offset = the user's current
  /// acceleration estimate of walking direction − heading, when known). Steps in tau order per user.
  void add_step(std::size_t u, double tau_s, double stride_m, double heading_rad, std::optional<double> offset_rad);
  /// A round at tau_s with its checked ranges; returns its index. Rounds in tau order.
  std::size_t add_round(double tau_s, std::vector<RangeObs> ranges);
  /// Solves the formation at round k (every round up to k is used, nothing after it) and returns a fix
  /// per user (users not localized yet: localized = false).
  std::vector<UserFix> solve(std::size_t k);

  std::size_t users() const noexcept { return users_.size(); }
  std::size_t rounds() const noexcept { return rounds_.size(); }
  /// The user whose translation frame the positions are in (nullopt before the first localization).
  std::optional<std::size_t> origin_user() const noexcept { return origin_; }
  /// Stride scale k_u (1 before it is calibrated).
  double stride_scale(std::size_t u) const { return scale_.at(u); }
  double heading_offset_rad(std::size_t u) const { return delta_.at(u); }
  std::size_t dropped_ranges() const noexcept { return dropped_; }
  /// Whether user u has been placed in the formation (by any solve so far).
  bool is_localized(std::size_t u) const { return localized_.at(u) != 0; }

  /// Raw (unscaled, offset 0) displacement of user u from tau a to tau b, and the steps between.
  Eigen::Vector2d raw_move(std::size_t u, double a_s, double b_s, double* steps = nullptr) const;
  /// Movement of user u between the taus with its current offset and scale.
  Eigen::Vector2d move(std::size_t u, double a_s, double b_s) const;

 private:
  struct Track {
    std::vector<double> t, stride, heading;
    std::vector<Eigen::Vector2d> cum;  ///< raw position at each step end
    std::vector<double> offset;        ///< the device's offset estimate at each step (NaN: none yet)
  };
  struct RoundData {
    double tau_s = 0.0;
    std::vector<RangeObs> ranges;
    std::vector<char> dropped;  ///< per range
  };
  struct Candidate {
    Eigen::Vector2d r;  ///< P_j − P_i at the base round
    double cost;
  };

  Eigen::Vector2d raw_at(std::size_t u, double t) const;
  /// The device's latest offset estimate sent with a step up to tau (so a solve depends only on the
  /// data up to its round, not on when messages arrived).
  std::optional<double> prior_offset(std::size_t u, double tau_s) const;
  void try_localize(std::size_t k);
  std::vector<Candidate> pair_candidates(std::size_t i, std::size_t j, std::size_t base, std::size_t k) const;
  void adjust(std::size_t k);
  double range_sigma(const RangeObs& ro) const { return std::hypot(cfg_.range_std_m, ro.extra_std_m); }

  std::vector<std::string> users_;
  FormationConfig cfg_;
  std::vector<Track> tracks_;
  std::vector<RoundData> rounds_;
  std::vector<double> delta_, scale_;
  /// The positions' frame rotation from the world-aligned frame of the movement vectors (rad): the
  /// frame's rotation is fixed by the origin's δ (set once, so successive solves share one frame);
  /// the offset priors (world-aligned) constrain δ_u − ψ.
  double psi_ = 0.0;
  std::vector<char> localized_;
  std::optional<std::size_t> origin_;
  std::size_t base_ = 0;  ///< round of the first localization
  /// positions_[k][u]: user u at round k (valid when localized_[u] and k >= base_)
  std::vector<std::vector<Eigen::Vector2d>> positions_;
  std::vector<std::vector<double>> stds_;
  std::size_t solved_ = 0;  ///< rounds < solved_ have positions
  std::size_t dropped_ = 0;
};

}  // namespace locus::plugins::montage
