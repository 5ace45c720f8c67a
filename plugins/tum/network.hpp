// TUM over a sliding window of exchanges: every device placed jointly (docs/tum.md, "Network solve").
//
// One exchange alone leaves a monitoring device nearly unobservable (its speaker and microphone TDoA
// cues, Eq. 17-21, constrain it in the devices' plane only to first order: when the devices lie in one
// plane, height trades against position at second order) and the working pair with a mirror pair of
// roots (Sec. IV-B). What the paper resolves with motion (Sec. V) this solver resolves the same way,
// as a least-squares smoother over the last `window` exchanges:
//   unknowns  still device (its IMU saw no motion in the window): one origin X_d and one yaw offset
//             psi_d (the attitude detector's heading error: magnetometer hard iron, indoor anomalies);
//             moving device: one origin per exchange, the same psi_d, tied exchange to exchange by
//             its motion (a random walk of `speed_mps` * dt per axis);
//             one clock offset rho_{d,k} per device and exchange (loose clocks drift).
//   equations every arrival of every exchange (device 1 hears N; every other device hears M; monitors
//             hear N), as in solver.hpp, with a Huber loss (a reflection taken for the first path is
//             down-weighted, Sec. VIII); weak priors: psi_d ~ N(0, yaw_prior_rad), and every device's
//             height relative to device 1 ~ N(0, height_prior_m) along device 1's gravity axis (it
//             only matters where the geometry leaves height unobservable).
//   motion    (exchange_motion) a moving device is placed at its reference instant, its hearing of
//             device 1's tone; its hearing of device 2's tone and device 2's emission are moved by
//             their time from it (velocity: the window's track of origins plus the gyro's spin of the
//             lever arm), and every arrival's chirp range-Doppler coupling is taken out (docs/tum.md,
//             "Motion within an exchange": the paper's Eq. 7-10).
// Levenberg-Marquardt with an analytic Jacobian (a few dozen unknowns), started from the previous
// window's solution; a device seen for the first time starts from every root of its single-exchange
// solution (solver.hpp) and the best is kept. Covariances: (J^T W J)^-1 scaled by the window's
// chi-square per degree of freedom when that exceeds 1, then made honest about what the Gaussian
// around one basin does not know (docs/tum.md, "Uncertainty"):
//   basins    the multi-start's distinct runner-up basins of a still device are kept across exchanges
//             (State::alternatives), and so are whole runner-up formations (device 2's other roots,
//             the monitors placed around each) while every device is still; all are re-solved in every
//             window: one that fits better takes over (the growing window decides), the others widen
//             the covariance by their cost-weighted mixture about the reported point (as AMIL's
//             cycle_mixture) until they fit worse by more than basin_drop_chi2;
//   height    when the data add little to the height prior (posterior vertical std above
//             `unobserved_height_ratio` x the prior's), the height is not observed: the placement says
//             so (height_observed = false), and the horizontal error that an unknown height causes at
//             second order (a range fixes the slant distance, not the horizontal one) enters the
//             covariance from two sigma points, the device's height pinned at +-1 posterior std.
#pragma once

#include <Eigen/Dense>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "solver.hpp"

namespace locus::plugins::tum {

struct NetworkConfig {
  int window = 12;                 ///< exchanges solved together
  double yaw_prior_rad = 0.35;     ///< 1-sigma of a device's heading error relative to device 1
  double still_yaw_prior_rad = 0.35;  ///< ... when no device moved in the window (offsets unobservable)
  double height_prior_m = 0.5;     ///< 1-sigma of a device's height relative to device 1 (0 = none)
  double speed_mps = 0.5;          ///< 1-sigma speed of a moving device between exchanges
  double huber_k = 3.0;            ///< Huber threshold, in sigmas
  int iterations = 20;
  double outlier_m = 0.3;          ///< window vs this exchange's range device 1 - device 2 (restart beyond)
  int alternatives = 2;            ///< runner-up basins kept per still device
  double basin_distinct_m = 0.05;  ///< horizontal distance beyond which two solutions are distinct basins
  double basin_drop_chi2 = 30.0;   ///< a basin worse than the best by more than this (chi2) is dropped
  double unobserved_height_ratio = 0.5;  ///< posterior / prior vertical std above which height is unobserved
  double moving_height_candidates_m = 0.3;  ///< a moving device 2's roots also tried this much higher / lower (0 = off)
  /// Motion within an exchange (docs/tum.md, "Motion within an exchange"): a moving device is placed at
  /// its reference instant (its hearing of device 1's tone); its hearing of device 2's tone and device
  /// 2's emission are moved by their time from it, and every arrival between devices whose range
  /// changes at rdot is taken as timed rdot / c * the tone's instant late (the chirps' range-Doppler
  /// coupling, dsp::doppler_timing_instant_s). Velocities: the window's per-exchange origins
  /// (differences) plus the gyro's rotation of the lever arms.
  bool exchange_motion = false;
  double doppler_instant1_s = 0.0, doppler_instant2_s = 0.0;  ///< device 1's / device 2's tone (s)
};

struct NetworkPlacement {
  std::string id;
  bool ok = false;
  bool still = true;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   ///< device 1 body frame
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double yaw_offset_rad = 0.0;
  bool height_observed = true;     ///< false: the vertical is the height prior's (cov: horizontal part honest)
  double vertical_std_m = 0.0;     ///< posterior 1-sigma along device 1's vertical
  int basins = 1;                  ///< basins in the covariance's mixture (1 = only the reported one)
  double basin_weight = 1.0;       ///< the reported basin's weight in that mixture
  double rms_sigma = 0.0;          ///< RMS whitened residual of its equations in the newest exchange
};

struct NetworkResult {
  bool ok = false;
  double t_ref_s = 0.0;                   ///< newest exchange's time of validity (device 1 clock)
  double chi2_dof = 0.0;
  bool restarted = false;                 ///< the window disagreed with this exchange and was restarted
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  ///< world up in device 1's body frame (newest exchange)
  std::vector<NetworkPlacement> devices;  ///< device 1 first, then the newest exchange's devices
};

class NetworkSolver {
 public:
  NetworkSolver(const SolverConfig& cfg, const NetworkConfig& net) : cfg_(cfg), net_(net) {}
  void set_speed_of_sound(double c) { cfg_.speed_of_sound_mps = c; }
  /// Adds one exchange (devices[0], devices[1] = the working pair) and solves the window.
  NetworkResult add(const std::vector<DeviceExchange>& devices);

 private:
  struct Exchange {
    std::vector<DeviceExchange> devices;
    double t_m1 = 0.0, t_n2 = 0.0;   ///< own emission times (device 1 / device 2 clocks)
    double t_ref = 0.0;
  };
  struct Basin {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    double psi = 0.0;
    double cost = 0.0;
  };
  struct State {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    double psi = 0.0;
    bool known = false;
    int exchanges = 0;  ///< exchanges it was placed in
    double psi_anchor = 0.0;  ///< heading offset learnt while something moved
    std::vector<Basin> alternatives;  ///< distinct runner-up basins (still devices), best first
  };
  SolverConfig cfg_;
  NetworkConfig net_;
  std::deque<Exchange> window_;
  std::map<std::string, State> state_;
  std::map<std::string, std::deque<Eigen::Vector3d>> moving_x_;  ///< per exchange of the window
  /// Runner-up formations while every device is still: the other roots of device 2 with the monitors
  /// placed around each (device id -> its basin), re-solved in every window until they fit clearly worse.
  std::vector<std::map<std::string, Basin>> formations_;
  bool restarting_ = false;
  std::uint64_t restarts_ = 0;
  std::uint64_t basin_switches_ = 0;

 public:
  std::uint64_t restarts() const { return restarts_; }
  /// Times a kept runner-up basin fitted the window better than the reported one and took over.
  std::uint64_t basin_switches() const { return basin_switches_; }
};

}  // namespace locus::plugins::tum
