// SpyLoc position fix from ranges to anchored beacons (paper 001, §VI: trilateration to start).
//
// Why 2-D with a height: the beacons hang at known heights, the phone is carried at a roughly known
// height (device_height_m); with 3 beacons a 3-D fix is a circle's worth of ambiguity, a 2-D fix at an
// assumed height is well posed (its error from the height is (Δz·δh / r), small at room ranges).
// Beacons mounted along one wall are (nearly) collinear: the fix then has a mirror image across
// their line that fits equally well. Both are returned; the caller chooses (region prior).
#pragma once

#include <array>
#include <optional>
#include <vector>

namespace locus::plugins::spyloc {

struct RangeObs {
  std::array<double, 3> beacon_m{};  ///< anchor, world frame
  double range_m = 0.0;              ///< slant range
  double std_m = 0.1;
};

struct Fix {
  std::array<double, 2> xy_m{};
  double rms_residual_m = 0.0;  ///< weighted RMS of the range residuals
  std::array<double, 3> cov{};  ///< xx, xy, yy of the least-squares covariance
};

/// Gauss-Newton on the horizontal position at height `z_m`, from several starts (the beacons'
/// centroid and points around it); returns the distinct local minima, best first (at most 2).
/// Empty when fewer than 3 observations or no start converges. [main]
std::vector<Fix> trilaterate(const std::vector<RangeObs>& obs, double z_m);

/// Horizontal range from a slant range and the height difference (0 when the slant is shorter).
double horizontal_range(double slant_m, double dz_m);

}  // namespace locus::plugins::spyloc
