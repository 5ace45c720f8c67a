// The maths of TUM (paper 000, docs/tum.md), free of the plugin API: one tone exchange -> every
// device's position in working device 1's body frame; pairing of exchanges across unsynchronised
// clocks; the per-device particle filter (tracker.hpp).
//
// Frames: device 1's body frame (Android axes) is the output frame. A device's attitude q (the
// `attitude` detector's body -> reference rotation) enters only as q1^-1 q (Eq. 5), so the common
// reference (magnetic north, gravity) cancels.
//
// Working pair (Sec. IV, Eq. 2-6): device 1 (mics a, speaker M) and device 2 (mics j, speaker N) each
// time both tones on their own clock. With rho = c * (clock of 2 - clock of 1), the unknowns are device
// 2's body origin X and rho:
//   device 1 hears N:  |a - (X + R s2)| - rho = c t2_a - c tN2      (tN2: N's emission, device 2 clock)
//   device 2 hears M:  |X + R m_j - M|   + rho = c t1_j - c tM1     (tM1: M's emission, device 1 clock)
// where the emission times come from each device's own recording of its own tone and its own
// mic-speaker distances (Eq. 3: "d_AM, d_CN known constants"). Summing one equation of each kind
// eliminates rho and gives exactly Eq. 3-4's d1..d4; solving with rho keeps the equations independent
// (each has its own measurement noise) and the same code serves the monitoring devices.
// Monitoring device P (Sec. VI, Eq. 17-21), unknowns its origin X and its own rho_P:
//   |X + R p_k - M| + rho_P = c t1_k - c tM1,   |X + R p_k - N| + rho_P = c t2_k - (c tN2 - rho)
// whose differences are the speaker TDoA cues d5, d6 (Eq. 17-18) and microphone TDoA cues d7, d8
// (Eq. 19-21, with t_N - t_M from Eq. 20).
// Every root of each system is kept (dsp::solve_ranges); the caller (tracker) picks among them.
#pragma once

#include <Eigen/Dense>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "locus/dsp/range_solver.hpp"

namespace locus::plugins::tum {

/// What one device contributes to one exchange (from its ObsMessage).
struct DeviceExchange {
  std::string id;
  std::vector<Eigen::Vector3d> mics;             ///< body frame
  std::optional<Eigen::Vector3d> speaker;        ///< body frame
  std::optional<Eigen::Quaterniond> attitude;    ///< body -> reference
  bool moving = false;
  std::optional<Eigen::Vector3d> gyro_radps;     ///< body-frame angular rate at its hearing of device 1's tone
  std::vector<double> t1_s, t2_s;                ///< per mic, local clock; NaN = not heard
};

struct SolverConfig {
  double speed_of_sound_mps = 343.2;
  double timing_std_s = 5.0e-6;      ///< arrival timing error (1 sigma)
  double attitude_std_rad = 0.02;    ///< relative attitude error (1 sigma), applied to lever arms
  double max_range_m = 10.0;         ///< farther roots are dropped
  int directions = 40;               ///< multi-start directions per radius
};

/// One device placed in device 1's body frame.
struct Placement {
  std::string id;
  bool ok = false;
  std::string why;                            ///< when !ok
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();   ///< body origin (what truth.csv tracks)
  Eigen::Vector3d speaker = Eigen::Vector3d::Zero();  ///< its speaker (the paper's point), when it has one
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();       ///< of origin
  double rms_m = 0.0;                         ///< residual RMS of its equations
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< its body -> device 1 body (Eq. 5)
  std::vector<dsp::RangeRoot> roots;          ///< every root (x = origin), best first
  double rho_m = 0.0;                         ///< clock offset * c of the chosen root
  std::vector<dsp::RangeEquation> equations;  ///< its constraints (x = origin; the filter's likelihood)
};

struct ExchangeResult {
  double t_ref_s = 0.0;          ///< device 1's tone emission, device 1 clock (time of validity)
  double t_n_minus_t_m_s = 0.0;  ///< Eq. 20, device 1 clock
  std::vector<Placement> devices;  ///< device 1 (origin 0), device 2, monitors, in input order
};

/// A device's reference instant in an exchange (its clock): the mean of its arrivals of device 1's
/// tone (`t1_s`, NaN = not heard), where its attitude and gyro rate are taken (messages.hpp) and the
/// window solve places a moving device (network.hpp); NaN when it heard none.
double reference_time_s(const std::vector<double>& t1_s);

/// Mean over mics of (t - |mic - speaker| / c): the device's own emission time on its clock. NaN when
/// it heard none of its own tone or has no speaker.
double own_emission_time(const DeviceExchange& d, const std::vector<double>& t_own, double c);

/// Equations of the working pair (unknowns: device 2's origin in device 1's frame, rho).
std::vector<dsp::RangeEquation> pair_equations(const DeviceExchange& d1, const DeviceExchange& d2,
                                               const Eigen::Matrix3d& r12, const SolverConfig& cfg);
/// Equations of a monitoring device given both speakers' positions (device 1 frame) and rho of device 2.
std::vector<dsp::RangeEquation> monitor_equations(const DeviceExchange& d1, const DeviceExchange& d2,
                                                  const DeviceExchange& p, const Eigen::Matrix3d& r1p,
                                                  const Eigen::Vector3d& m, const Eigen::Vector3d& n,
                                                  double rho2_m, double n_sigma_m, const SolverConfig& cfg);

/// Selects a root: the one nearest `prior` when given and its cost is within `chi2_slack` of the
/// best, else the best. Index into roots, -1 when empty.
int choose_root(const std::vector<dsp::RangeRoot>& roots, const std::optional<Eigen::Vector3d>& prior,
                double chi2_slack = 9.0);

/// Solves one exchange. `priors` (by device id, origin in device 1 frame) steer the choice among
/// roots; may be empty. devices[0] and devices[1] are the working pair; the rest monitor.
ExchangeResult solve_exchange(const std::vector<DeviceExchange>& devices, const SolverConfig& cfg,
                              const std::vector<std::optional<Eigen::Vector3d>>& priors = {});

// ---- pairing exchanges across clocks (the loose synchronisation the acoustic data imply) ----

/// One device's exchange on its own clock: when it heard tone 1 and tone 2 (mean over mics, NaN = not).
struct Stamp {
  double t1 = 0.0, t2 = 0.0;
};
Stamp stamp_of(const DeviceExchange& d);

/// The index of dev's exchange that pairs with `r` under `offset_s`, -1 when none: tone-1 times differ
/// by the offset within `tolerance_s` (tone 2 when tone 1 is missing on either side) and, when both
/// heard both tones, the intervals (t2 - t1) differ by at most `interval_tolerance_s` (the two arrivals'
/// path difference, at most twice the devices' spread / c) and, when `interval_diff_s` is finite, by
/// `interval_diff_s` within `tolerance_s` (the path difference of a pairing changes only with motion).
int match_stamp(const Stamp& r, const std::vector<Stamp>& dev, double offset_s, double tolerance_s,
                double interval_tolerance_s, double interval_diff_s = std::numeric_limits<double>::quiet_NaN());

/// A clock pairing search (align_clocks).
struct ClockPairing {
  std::optional<double> offset_s;  ///< device - reference (s); nullopt: too few agree, or ambiguous
  int pairs = 0;                   ///< exchanges that agree under the best offset
  int runner_up_pairs = 0;         ///< under the best offset of another round (> interval_tolerance_s away)
  double runner_up_offset_s = std::numeric_limits<double>::quiet_NaN();
};

/// The clock offset (device - reference, s) that pairs the most exchanges. A candidate is one pair of
/// exchanges (both tones heard on both sides): its tone-1 offset and its interval difference
/// (d.t2 - d.t1) - (r.t2 - r.t1); an exchange agrees when match_stamp pairs it under both. Tone 1 comes
/// from device 1 on a fixed period, so the tone-1 times alone agree under every whole-period shift; the
/// interval difference is the geometry's (constant but for motion) under the right round and the
/// difference of two rounds' pseudo-random tone-2 delays under a wrong one, which is what tells them
/// apart. No offset (nullopt, with the counts) when fewer than `min_pairs` agree or the best does not
/// beat the best offset of another round (the runner-up) by `min_margin` exchanges: a device whose
/// exchanges lag device 1's by one pairs as many under a one-period shift when the intervals do not
/// tell the rounds apart (measured live, `./run hil tum`: both monitors paired 333 ms off).
ClockPairing align_clocks(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double tolerance_s,
                          double interval_tolerance_s, int min_pairs, int min_margin = 1);

/// How many of ref's exchanges pair under `offset_s` (align_clocks' count, its best interval difference).
int count_pairs(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double offset_s, double tolerance_s,
                double interval_tolerance_s);

/// Speed of sound from a device's own emission: its mics sit at known, different distances from its
/// speaker, so the own tone's arrival difference between the nearest and the farthest mic is
/// (|m_far - s| - |m_near - s|) / c. nullopt when no two heard mics differ by `min_baseline_m`.
std::optional<double> speed_of_sound_sample(const DeviceExchange& d, const std::vector<double>& t_own,
                                            double min_baseline_m = 0.05);

}  // namespace locus::plugins::tum
