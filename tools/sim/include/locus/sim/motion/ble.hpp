// BLE received-signal-strength model (LocBLE, seeds/003): what a scanning phone logs from BLE tags,
// as an engine BleScanModel (engine.hpp). Tags are the simulation's emitters (and devices) with a
// `ble` emits entry (address, tx_power_dbm = RSSI at 1 m, interval_s).
//
//   rssi = tx_power_dbm − 10·n(env)·log10(d) − extra_loss(env) + X_shadow + F_fading + rx_offset_db
//          + channel_offset
//
//  - n(env): path-loss exponent per propagation class, LocBLE's LOS / partial-LOS / NLOS (the paper
//    fits n(e) per environment online but prints no values; defaults are the usual indoor 2.4 GHz
//    figures: LOS 2.0, p-LOS 2.8, NLOS 3.5), plus a fixed blockage loss for blocked classes.
//  - X_shadow: log-normal shadowing, spatially correlated along the walk (Gudmundson AR(1) over the
//    distance the tag-to-scanner vector moved: ρ = exp(−Δ/decorrelation_m)), one process per tag.
//  - F_fading: 10·log10|h|², E|h|² = 1, Rician with K(env) (NLOS: Rayleigh); independent per packet
//    (events hop channels 37-39 and the phone moves more than the few-cm coherence distance).
//  - advertising: events every interval_s + advDelay, advDelay uniform in [0, 10 ms] (BLE spec),
//    first event at a random phase; the scanner hears the event on the channel it is scanning
//    (37, 38, 39 rotating every scan_interval_s). A packet is lost with loss_probability, or when
//    below sensitivity_dbm. RSSI in whole dBm (quantize).
#pragma once

#include <functional>
#include <map>
#include <string>

#include "locus/sim/engine.hpp"

namespace locus::sim::motion {

enum class Propagation { los = 0, partial = 1, nlos = 2 };
const char* to_string(Propagation p) noexcept;

/// What differs from tag to tag (optional, BleChannelParams::tags): a real room gives every link its
/// own exponent, static shadowing per propagation class, channel offsets and a true 1 m power that
/// differs from the advertised one.
struct BleTagChannel {
  std::array<double, 3> exponent_offset{0.0, 0.0, 0.0};   ///< added to exponent[env]
  std::array<double, 3> static_offset_db{0.0, 0.0, 0.0};  ///< per-link shadowing per class
  std::array<double, 3> channel_offset_db{0.0, 0.0, 0.0}; ///< added to the common channel offsets
  double tx_bias_db = 0.0;                                ///< true RSS at 1 m − advertised tx_power_dbm
};

struct BleChannelParams {
  std::array<double, 3> exponent{2.0, 2.8, 3.5};        ///< n for los, partial, nlos
  std::array<double, 3> extra_loss_db{0.0, 3.0, 8.0};   ///< fixed blockage loss
  std::array<double, 3> shadowing_std_db{2.5, 3.5, 5.0};
  double decorrelation_m = 1.0;                         ///< shadowing decorrelation distance
  std::array<double, 3> rician_k_db{6.0, 2.0, -100.0};  ///< K factor (−100 dB ≈ Rayleigh)
  double loss_probability = 0.1;                        ///< random packet loss
  double sensitivity_dbm = -100.0;                      ///< weaker packets are not received
  double rx_offset_db = 0.0;                            ///< receiver (phone model) offset
  std::array<double, 3> channel_offset_db{0.0, -0.5, 0.5};  ///< advertising channels 37, 38, 39
  double scan_interval_s = 0.1;                         ///< scanner channel rotation period
  double min_distance_m = 0.1;                          ///< near-field clamp
  bool fading = true;
  bool quantize = true;                                 ///< whole dBm
  /// Per-tag link parameters by tag id (absent = none of the above).
  std::map<std::string, BleTagChannel> tags;
  /// Bursty loss (Gilbert-Elliott, per tag, on top of loss_probability): a good link enters a burst
  /// with this probability per advertising event, leaves it with burst_exit_probability, and loses
  /// burst_loss of the packets inside. 0 = off (no extra random draws).
  double burst_enter_probability = 0.0;
  double burst_exit_probability = 0.3;
  double burst_loss = 0.9;
};

/// Propagation class between tag `tag_id` (world position tag_m) and the scanner at true time t.
using PropagationFn =
    std::function<Propagation(const std::string& tag_id, const Eigen::Vector3d& tag_m, const Eigen::Vector3d& scanner_m, double t_s)>;

/// Mean received power, no shadowing/fading/offsets: tx − 10·n·log10(max(d, min_d)) − extra_loss.
double mean_rssi_dbm(const BleChannelParams& p, double tx_power_dbm, double distance_m, Propagation env);

/// Draws 10·log10|h|² of a unit-mean-power Rician channel with K factor k_db.
double rician_fading_db(double k_db, Rng& rng);

class BleRssiModel final : public BleScanModel {
 public:
  /// `env` empty = everything LOS. Throws std::invalid_argument for out-of-range parameters
  /// (loss probability outside [0,1], negative sigmas, decorrelation or scan interval <= 0).
  explicit BleRssiModel(BleChannelParams params = {}, PropagationFn env = {});
  /// Throws std::invalid_argument naming the tag for a malformed address or interval <= 0.
  void scan(const Simulation& sim, const DeviceModel& observer, double t0_true_s, double t1_true_s, Rng& rng,
            const std::function<void(const BleReception&)>& emit) override;
  const BleChannelParams& params() const noexcept { return params_; }

 private:
  BleChannelParams params_;
  PropagationFn env_;
};

}  // namespace locus::sim::motion
