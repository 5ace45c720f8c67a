// Dynamic time warping (DTW) with a Sakoe-Chiba band, the LB_Keogh lower bound and early
// abandoning, plus the open-end search SpyLoc's step detector needs (paper 001, Sec. III: the cell
// d[n, m] of minimum value for m in [m_min, m_max]).
//
// Local cost: squared difference (default) or absolute difference. Cumulative cost with the usual
// steps (i-1, j), (i, j-1), (i-1, j-1), all of weight 1. The object owns two rows of workspace
// sized at construction; every query is allocation-free [RT].
#pragma once

#include <cstddef>
#include <limits>
#include <span>
#include <vector>

namespace locus::dsp {

enum class DtwCost { Squared, Absolute };

/// Result of an open-end match of a whole template against prefixes of a sequence.
struct DtwOpenEndMatch {
  std::size_t length = 0;     ///< prefix length m of the best match (0 = none within the bound)
  double cost = std::numeric_limits<double>::infinity();             ///< cumulative cost d[n, m]
  double normalized_cost = std::numeric_limits<double>::infinity();  ///< cost / (n + m)
};

class Dtw {
 public:
  /// [main] Workspace for sequences of up to `max_length` samples (the longer of the two).
  explicit Dtw(std::size_t max_length, DtwCost cost = DtwCost::Squared);

  /// [RT] DTW distance between `a` and `b` restricted to |i - j·(|a|/|b|)| <= window (a band around
  /// the diagonal, in samples of `a`; window >= max length = unconstrained). Returns +inf when the
  /// sequences cannot be aligned inside the band, when one is empty or longer than max_length, or
  /// as soon as every cell of a row exceeds `abandon_above` (early abandoning: the true distance is
  /// then known to be larger).
  double distance(std::span<const float> a, std::span<const float> b, std::size_t window,
                  double abandon_above = std::numeric_limits<double>::infinity()) noexcept;

  /// [RT] Matches the whole `templ` (n samples) against the prefixes x[0..m) of `x` for every m in
  /// [min_length, max_length] (clipped to |x|) and returns the m with the lowest cost / (n + m), the
  /// normalisation making matches of different lengths comparable. Cells are restricted to the
  /// parallelogram between the warping slopes min_length/n and max_length/n, widened by `window`
  /// samples (the Sakoe-Chiba band generalised to a range of lengths).
  DtwOpenEndMatch open_end(std::span<const float> templ, std::span<const float> x, std::size_t min_length,
                           std::size_t max_length, std::size_t window) noexcept;

  std::size_t max_length() const noexcept { return max_length_; }
  DtwCost cost() const noexcept { return cost_; }

 private:
  double local(float a, float b) const noexcept {
    const double d = static_cast<double>(a) - static_cast<double>(b);
    return cost_ == DtwCost::Squared ? d * d : (d < 0 ? -d : d);
  }

  std::size_t max_length_;
  DtwCost cost_;
  std::vector<double> prev_, cur_;
};

/// [RT] LB_Keogh envelope of `query` for a band of `window` samples: upper[i] = max(query[i-w..i+w]),
/// lower[i] = min(...). `upper` and `lower` must hold query.size() values. O(n·w).
void lb_keogh_envelope(std::span<const float> query, std::size_t window, std::span<float> upper,
                       std::span<float> lower) noexcept;

/// [RT] LB_Keogh lower bound of DTW(query, candidate) (equal lengths, same window and cost as the
/// envelope): the sum of the local costs of the candidate's excursions outside the envelope. Stops
/// early (returning the partial sum, already > abandon_above) once the bound exceeds abandon_above.
/// Returns +inf if the lengths differ.
double lb_keogh(std::span<const float> candidate, std::span<const float> upper, std::span<const float> lower,
                DtwCost cost = DtwCost::Squared,
                double abandon_above = std::numeric_limits<double>::infinity()) noexcept;

}  // namespace locus::dsp
