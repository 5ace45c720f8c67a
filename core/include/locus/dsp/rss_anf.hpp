// LocBLE's adaptive noise filter (ANF, paper 003 Sec. 3.2) for one BLE tag's RSS: a Butterworth
// low-pass on a regular grid, then an adaptive Kalman filter (AKF) that fuses the raw RSS with the
// Butterworth output. Shared by the `ble_rss` detector (one per tag, every advert) and the `locble`
// localizer (the smoothed traces its DTW clustering compares, paper Sec. 6).
//
// Sampling: adverts arrive irregularly (advertising interval + random delay, lost packets, three
// channels), and an IIR filter is only defined on a regular grid. So the RSS is resampled onto a grid
// of `grid_rate_hz` (linear interpolation between consecutive packets, evaluated when the later packet
// arrives, so it is causal) and the Butterworth filter runs on the grid; each packet reads the filter
// state at the last grid point before it. Running the filter per packet instead would make its cutoff
// scale with the packet rate, which varies per tag and with losses.
//
// AKF (the paper defers its details to its reference [21]; this is our formulation): state x = the
// RSS level (dB), per packet
//   predict   x- = x + (bf_k - bf_{k-1})       (the Butterworth output's change is the motion model:
//             P- = P + Q                        smooth, delayed, but drift-free)
//   update    nu = rssi - x-,  K = P- / (P- + R),  x = x- + K nu,  P = (1 - K) P-
//   adapt     Q <- (1-alpha) Q + alpha max((K nu)^2, q_min)   (Sage-Husa style: corrections the
//             R <- (1-alpha_r) R + alpha_r max(nu^2 - P-, r_min)  motion model missed raise Q)
// A gap longer than restart_gap_s (or time going backwards) restarts both filters at the packet.
#pragma once

#include "locus/dsp/iir.hpp"

namespace locus::dsp {

struct RssAnfOptions {
  double grid_rate_hz = 10.0;
  double lowpass_hz = 0.5;
  int lowpass_order = 6;
  double restart_gap_s = 3.0;
  double akf_alpha = 0.1, akf_alpha_r = 0.02;
  double measurement_var_db2 = 16.0, r_min_db2 = 1.0, q_min_db2 = 0.01;
};

class RssAnf {
 public:
  RssAnf() = default;
  /// [main] Designs the low-pass; throws std::invalid_argument when lowpass_hz is not below half the
  /// grid rate or a rate is not positive.
  explicit RssAnf(const RssAnfOptions& opt);
  /// [RT] One packet (time in s, RSS in dB): the filtered RSS.
  double filter(double t_s, double rssi_db) noexcept;
  /// [RT] The next packet restarts the filters.
  void restart() noexcept { last_t_ = -1e300; }
  /// [RT] Butterworth output at the last grid point processed (the smooth, delayed trace).
  double lowpass_db() const noexcept { return bf_out_; }

 private:
  RssAnfOptions opt_;
  double grid_dt_ = 0.1;
  SosFilter bf_;
  double last_t_ = -1e300, last_rssi_ = 0.0, next_grid_t_ = 0.0, bf_out_ = 0.0, bf_prev_ = 0.0;
  double x_ = 0.0, p_ = 0.0, q_ = 0.0, r_ = 0.0;
};

}  // namespace locus::dsp
