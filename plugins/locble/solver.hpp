// LocBLE maths (paper 003, Sec. 5-6), free of the plugin API so that the unit tests and the benchmark
// drive it directly.
//
// Why this file: the location of a tag from RSS readings taken along the observer's own path is the
// part of LocBLE that can be checked against known answers (noise-free synthetic walks) and timed;
// the plugin (locble.cpp) only collects events and publishes.
//
// Frame: the observer's start frame (`observer_start` in docs/eval.md): origin = the observer at the
// first heading it reports, y = the direction its phone points then (projected on the horizontal),
// x = y × up (to the right). Headings are counter-clockwise (a left turn increases the heading), so a
// step of length s at relative heading h moves the observer by s·(−sin h, cos h).
//
// Pieces:
//  - DeadReckoning (core/dsp/dead_reckoning.hpp): the observer's path from step events and headings.
//  - make_bins(): the tag's RSS readings grouped by the observer's position along the path (every
//    `bin_m` of walked distance is one bin; standing still keeps adding to one bin). Shadowing is
//    correlated in space, fading is not, so a bin of k readings has variance
//    shadowing_sd² + fading_sd² / k.
//  - elliptical_regression(): the paper's Eq. 2-4 (a linear least-squares fit of
//    |o_i|² − 2 x·o_i + |x|² = ε·η^RSS_i for a given fading coefficient n) with n searched on a grid
//    (Eq. 5: the n whose fit leaves the smallest residual), reweighted so that every reading counts by
//    its relative (not absolute) error.
//  - l_shape(): the paper's disambiguation (Sec. 5.1): each straight leg alone gives a pair of
//    positions mirrored about the leg's line; the pair members of the two legs that agree (overlap)
//    are the answer.
//  - PositionPosterior: the estimate we publish. The same log-distance model
//    RSS = Γ − 10·n·log10(d) + e, with Gaussian priors on Γ (the advertised 1 m power plus an offset)
//    and n, is marginalised in closed form over (Γ, n) on every cell of a grid of candidate positions
//    (a 2x2 linear-Gaussian problem per cell). The posterior mean is the position, its covariance the
//    std (so ~68 % of errors fall within it when the model holds), the posterior mass across the first
//    leg's line tells whether the mirror is still open. Why not the regression alone: with a few
//    metres of walk and several dB of shadowing, Eq. 2-5 often has no positive ε (no solution) or
//    lands on the mirror; the posterior uses the same model and degrades gracefully to "a ring at the
//    distance the level says" with a std that says so.
//  - cluster_members() / fuse(): Sec. 6, Algo. 2 (DTW with LB_Keogh pre-test, segment voting) and the
//    confidence-weighted fusion of a cluster's estimates.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "locus/dsp/dead_reckoning.hpp"

namespace locus::plugins::locble {

using Vec2 = Eigen::Vector2d;

/// The observer's dead-reckoned path (shared with SpyLoc: core/dsp/dead_reckoning.hpp).
using DeadReckoning = dsp::DeadReckoning;

/// One RSS reading of a tag.
struct Reading {
  double t_s = 0.0;
  double rssi_dbm = 0.0;
};

/// Readings grouped by where the observer was.
struct Bin {
  Vec2 observer_m{0.0, 0.0};  ///< mean observer position of the bin's readings
  double rssi_dbm = 0.0;      ///< mean RSS (dB)
  int count = 0;
  double t_s = 0.0;           ///< mean time
};

/// [main] Groups readings by walked distance (bins of bin_m); `positions` are the observer positions
/// and `path_m` the walked distances at each reading's time. Sizes must match (std::invalid_argument).
std::vector<Bin> make_bins(std::span<const Reading> readings, std::span<const Vec2> positions,
                           std::span<const double> path_m, double bin_m);

/// Result of Eq. 2-5.
struct RegressionFit {
  bool ok = false;       ///< false: no n gave a positive ε (the data do not fit the model)
  Vec2 position_m{0.0, 0.0};
  double n = 0.0;        ///< fading coefficient chosen by Eq. 5
  double gamma_dbm = 0.0;
  double cost = 0.0;     ///< mean squared relative residual of the chosen fit
  std::string why;       ///< when !ok
};

struct RegressionOptions {
  double n_min = 1.5, n_max = 5.0, n_step = 0.05;
  int reweight_iterations = 3;
  /// Straight walk: y (across the walk) only enters through |x|², fit as a free term: the result is
  /// the side given by `side` (+1 left of the walk, −1 right) — the mirror is l_shape()'s business.
  bool straight = false;
};

/// [main] Eq. 2-5 on observer positions `o` (relative to the target's own motion when it moves) and
/// RSS `rss` (equal sizes, at least 4 points; std::invalid_argument otherwise). For a straight walk,
/// pass positions rotated so that the walk runs along x and set `straight`: `position_m.y()` is then
/// |h| >= 0 (the pair is ±h).
RegressionFit elliptical_regression(std::span<const Vec2> o, std::span<const double> rss,
                                    const RegressionOptions& opt = {});

/// [main] Sec. 5.1: each leg's regression (leg-local frame, pair ±h) mapped back to the frame; the
/// two pair members (one per leg) that lie closest together, averaged. nullopt when a leg has no
/// fit. `leg1`, `leg2`: indices of bins of each leg.
std::optional<Vec2> l_shape(std::span<const Bin> bins, std::span<const std::size_t> leg1,
                            std::span<const std::size_t> leg2, const RegressionOptions& opt = {});

/// Priors and noise of the posterior.
struct PosteriorOptions {
  double gamma_mean_dbm = -59.0;  ///< prior mean of Γ (RSS at 1 m)
  double gamma_sd_db = 6.0;
  double n_mean = 2.3;            ///< prior of the fading coefficient
  double n_sd = 0.5;
  double shadowing_sd_db = 3.0;   ///< per bin (spatially correlated part)
  double fading_sd_db = 6.0;      ///< per reading (independent part)
  double search_radius_m = 20.0;  ///< grid half size around the path's centre
  double grid_step_m = 0.5;
  double min_distance_m = 0.5;    ///< distances below this count as this (near field)
};

/// A posterior over cells of a square grid (probabilities summing to 1), kept for the co-location test
/// of the clustering (colocation_bayes_factor()).
struct PosteriorGrid {
  double x0_m = 0.0, y0_m = 0.0;  ///< centre of cell (0, 0)
  double step_m = 0.0;
  int n = 0;                      ///< n x n cells, row-major (y rows)
  std::vector<float> p;
  bool empty() const noexcept { return p.empty(); }
  /// Probability of the cell containing (x, y); 0 outside the grid.
  double at(double x_m, double y_m) const noexcept;
};

struct TagEstimate {
  bool ok = false;
  std::string why;
  Vec2 position_m{0.0, 0.0};      ///< posterior mean
  Eigen::Matrix2d cov_m2 = Eigen::Matrix2d::Zero();
  double std_m = 0.0;             ///< sqrt(trace(cov))
  Vec2 map_m{0.0, 0.0};           ///< most probable cell
  double gamma_dbm = 0.0, n = 0.0;  ///< (Γ, n) posterior mean at the estimate's cell
  double residual_mean_db = 0.0, residual_sd_db = 0.0;  ///< δ_RS at the estimate (paper's confidence)
  double confidence = 0.0;        ///< P(μ) with P ~ N(0, σ), scaled to 1 at μ = 0
  double mirror_mass = 0.0;       ///< posterior mass on the other side of the first leg's line
  /// sqrt of the residuals' chi² per degree of freedom at the estimate under the noise model: < 1 =
  /// the readings are cleaner than shadowing_sd_db / fading_sd_db assume.
  double noise_ratio = 1.0;
  int bins = 0;
  PosteriorGrid grid;             ///< the whole-square posterior (first solve of solve_coarse_to_fine())
};

/// [main] Sec. 6 gate: how much more probable two tags' readings are if the tags sit at one place than
/// if each is anywhere on its own: the Bayes factor N·Σ_c p_a(c)·p_b(c) over a's N cells (b's
/// posterior looked up at a's cell centres; the grid's uniform prior). > 1: the data favour one place;
/// ≪ 1: the posteriors exclude each other. 0 when either grid is empty.
double colocation_bayes_factor(const PosteriorGrid& a, const PosteriorGrid& b);

/// The grid posterior (see the file comment). Holds its workspace: one object per thread.
class PositionPosterior {
 public:
  /// [main] Throws std::invalid_argument on non-positive sizes or sds.
  explicit PositionPosterior(const PosteriorOptions& opt);
  /// [main] Allocation-free once the grid is sized (first call). `leg_axis`: unit direction of the
  /// first leg (the mirror line through the origin); zero = no mirror statistic. Needs >= 2 bins.
  /// `wider`: a solve of the same bins with more noise (adaptive noise): this posterior is narrower,
  /// so the grid only spans `wider`'s mean ± 3 of its std (when that is inside the search square).
  TagEstimate solve(std::span<const Bin> bins, const Vec2& leg_axis, const TagEstimate* wider = nullptr);
  /// [main] What the plugin runs: a first solve on a grid twice as coarse over the whole square, then
  /// the solve at grid_step_m over its mean ± 3 std — with the noise scaled down to what the first
  /// solve's residuals show when they are cleaner than the model (sqrt(χ²/dof) < 0.9; not below
  /// `min_noise_ratio`) if `adaptive_noise`. The mirror mass is the first solve's (whole square).
  TagEstimate solve_coarse_to_fine(std::span<const Bin> bins, const Vec2& leg_axis, bool adaptive_noise,
                                   double min_noise_ratio);
  const PosteriorOptions& options() const noexcept { return opt_; }
  void set_gamma_mean(double gamma_mean_dbm) noexcept { opt_.gamma_mean_dbm = gamma_mean_dbm; }
  /// [main] Noise of the next solves (both >= 0, not both 0).
  void set_noise(double shadowing_sd_db, double fading_sd_db) noexcept {
    opt_.shadowing_sd_db = shadowing_sd_db;
    opt_.fading_sd_db = fading_sd_db;
  }

 private:
  PosteriorOptions opt_;
  std::vector<float> logml_;
};

/// [main] Sec. 6 (Algo. 2): which of `others` move like `target`. Each trace is a series of RSS values on
/// one common time grid (NaN = no data); traces are differenced (so offsets between tags do not
/// matter), split into segments of `segment` points following the target's, each segment tested by
/// LB_Keogh then DTW (squared cost, band `window`) against `threshold`; a trace whose segments match in
/// more than half of the comparable ones is a member. Returns the members' indices into `others`.
struct ClusterOptions {
  std::size_t segment = 10;
  std::size_t window = 2;
  double threshold = 6.1;
};
std::vector<std::size_t> cluster_members(std::span<const float> target, const std::vector<std::vector<float>>& others,
                                         const ClusterOptions& opt = {});

/// [main] cluster_members() for every trace against every other at once: m[i][j] = trace j is a
/// member of trace i's cluster. DTW is symmetric and LB_Keogh only prunes, so the matrix is symmetric
/// and each pair is compared once (half the work, no copies). All traces on one grid (same length).
std::vector<std::vector<bool>> cluster_matrix(const std::vector<std::vector<float>>& traces, const ClusterOptions& opt = {});

/// [main] Algo. 2, last step: the confidence-weighted mean of the candidate positions (weights p_i / Σ p).
/// Throws std::invalid_argument when the sizes differ or no weight is positive.
Vec2 fuse(std::span<const Vec2> positions, std::span<const double> weights);

}  // namespace locus::plugins::locble
