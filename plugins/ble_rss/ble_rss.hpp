// `ble_rss`: LocBLE's adaptive noise filter (paper 003, Sec. 3.2) on the RSS of each BLE tag:
// a 6th-order Butterworth low-pass, then an adaptive Kalman filter (AKF) that fuses the raw RSS
// with the Butterworth output. Emits, for each received advertisement, a copy with rssi_dbm
// replaced by the filtered value.
//
// The filter itself is locus/dsp/rss_anf.hpp (shared with the locble localizer).
//
// Sampling: adverts arrive irregularly (advertising interval + random delay, lost packets, three
// channels), and an IIR filter is only defined on a regular grid. So each tag's RSS is resampled
// onto a grid of `grid_rate_hz` (linear interpolation between consecutive packets, evaluated when the
// later packet arrives, so it is causal) and the Butterworth filter runs on the grid; each packet
// reads the filter state at the last grid point before it. Running the filter per packet instead
// would make its cutoff scale with the packet rate, which varies per tag and with losses.
//
// AKF (the paper defers its details to its reference [21]; this is our formulation): state x = the
// RSS level (dB), per packet
//   predict   x- = x + (bf_k - bf_{k-1})       (the Butterworth output's change is the motion model:
//             P- = P + Q                        smooth, delayed, but drift-free)
//   update    nu = rssi - x-,  K = P- / (P- + R),  x = x- + K nu,  P = (1 - K) P-
//   adapt     Q <- (1-alpha) Q + alpha max((K nu)^2, q_min)   (Sage-Husa style: corrections the
//             R <- (1-alpha_r) R + alpha_r max(nu^2 - P-, r_min)  motion model missed raise Q)
// so the output follows the raw RSS quickly when it moves away from the Butterworth prediction (a
// distance change) and settles to a small gain when it does not.
//
// Tags: at most `max_tags` at once in a preallocated table (linear search on 6-byte addresses).
// A tag silent for `tag_timeout_s` frees its slot for a new one; with every slot busy, adverts of
// new tags are dropped and counted (reported at finish()). A tag
// silent for longer than `restart_gap_s` restarts its filters at its next advert.
#pragma once

#include "locus/plugin.hpp"

namespace locus::plugins::ble_rss {

const locus_plugin_descriptor* descriptor();
const ParamSchema& schema();

}  // namespace locus::plugins::ble_rss
