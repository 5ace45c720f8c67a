// BLE RSSI model (see ble.hpp).
#include "locus/sim/motion/ble.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace locus::sim::motion {

using Eigen::Vector3d;

const char* to_string(Propagation p) noexcept {
  switch (p) {
    case Propagation::los: return "los";
    case Propagation::partial: return "partial";
    case Propagation::nlos: return "nlos";
  }
  return "?";
}

double mean_rssi_dbm(const BleChannelParams& p, double tx_power_dbm, double distance_m, Propagation env) {
  const auto e = static_cast<std::size_t>(env);
  return tx_power_dbm - 10.0 * p.exponent[e] * std::log10(std::max(distance_m, p.min_distance_m)) -
         p.extra_loss_db[e];
}

double rician_fading_db(double k_db, Rng& rng) {
  const double k = std::pow(10.0, k_db / 10.0);
  // h = LOS part sqrt(K/(K+1)) + scattered CN(0, 1/(K+1)): E|h|² = 1.
  const double los = std::sqrt(k / (k + 1.0));
  const double s = std::sqrt(0.5 / (k + 1.0));
  const double re = los + s * rng.normal(), im = s * rng.normal();
  return 10.0 * std::log10(std::max(re * re + im * im, 1e-12));
}

BleRssiModel::BleRssiModel(BleChannelParams params, PropagationFn env)
    : params_(std::move(params)), env_(std::move(env)) {
  const auto& p = params_;
  if (!(p.loss_probability >= 0.0 && p.loss_probability <= 1.0))
    throw std::invalid_argument("ble: loss_probability must be in [0, 1]");
  if (!(p.decorrelation_m > 0.0) || !(p.scan_interval_s > 0.0) || !(p.min_distance_m > 0.0))
    throw std::invalid_argument("ble: decorrelation_m, scan_interval_s and min_distance_m must be > 0");
  for (int i = 0; i < 3; ++i)
    if (!(p.shadowing_std_db[i] >= 0.0) || !(p.exponent[i] > 0.0))
      throw std::invalid_argument("ble: shadowing sigmas must be >= 0 and exponents > 0");
}

void BleRssiModel::scan(const Simulation& sim, const DeviceModel& observer, double t0, double t1, Rng& rng,
                        const std::function<void(const BleReception&)>& emit) {
  if (!observer.trajectory) throw std::invalid_argument("ble: scanner '" + observer.id + "' has no trajectory");
  struct Tag {
    std::string id;
    const Trajectory* traj;
    dsp::SignalSpec spec;
    std::array<std::uint8_t, 6> addr;
  };
  std::vector<Tag> tags;
  auto collect = [&](const std::string& id, const std::shared_ptr<const Trajectory>& traj,
                     const std::vector<dsp::SignalSpec>& emits) {
    for (const auto& s : emits) {
      if (s.type != "ble") continue;
      Tag t{id, traj.get(), s, {}};
      if (!traj) throw std::invalid_argument("ble: tag '" + id + "' has no trajectory");
      if (!scene::parse_ble_address(s.address, t.addr))
        throw std::invalid_argument("ble: tag '" + id + "': address '" + s.address +
                                    "' is not AA:BB:CC:DD:EE:FF");
      if (!(s.interval_s > 0.0)) throw std::invalid_argument("ble: tag '" + id + "': interval_s must be > 0");
      tags.push_back(std::move(t));
    }
  };
  for (const auto& e : sim.emitters) collect(e.id, e.trajectory, e.emits);
  for (const auto& d : sim.devices)
    if (d.id != observer.id) collect(d.id, d.trajectory, d.emits);

  const auto& p = params_;
  for (const auto& tag : tags) {
    Rng r = Rng::derive(rng.next_u64(), tag.id);  // one stream per tag, independent of the others
    double shadow = 0.0;
    bool have_shadow = false;
    Vector3d last_rel = Vector3d::Zero();
    const auto link_it = p.tags.find(tag.id);
    const BleTagChannel link = link_it != p.tags.end() ? link_it->second : BleTagChannel{};
    bool in_burst = false;
    for (double t = t0 + r.uniform(0.0, tag.spec.interval_s); t < t1;
         t += tag.spec.interval_s + r.uniform(0.0, 0.010)) {
      const Vector3d tag_pos = tag.traj->pose(t).position_m;
      const Vector3d rx_pos = observer.trajectory->pose(t).position_m;
      const Vector3d rel = tag_pos - rx_pos;
      const Propagation env = env_ ? env_(tag.id, tag_pos, rx_pos, t) : Propagation::los;
      const auto e = static_cast<std::size_t>(env);
      // Shadowing: AR(1) over the movement of the relative position (unit variance, scaled by σ(env)).
      if (!have_shadow) {
        shadow = r.normal();
        have_shadow = true;
      } else {
        const double rho = std::exp(-(rel - last_rel).norm() / p.decorrelation_m);
        shadow = rho * shadow + std::sqrt(1.0 - rho * rho) * r.normal();
      }
      last_rel = rel;
      const double fading = p.fading ? rician_fading_db(p.rician_k_db[e], r) : 0.0;
      bool lost = r.bernoulli(p.loss_probability);
      if (p.burst_enter_probability > 0.0) {
        in_burst = in_burst ? !r.bernoulli(p.burst_exit_probability) : r.bernoulli(p.burst_enter_probability);
        if (in_burst && r.bernoulli(p.burst_loss)) lost = true;
      }
      const int ch_index = static_cast<int>(std::floor(t / p.scan_interval_s)) % 3;
      const auto ch = static_cast<std::size_t>((ch_index + 3) % 3);
      const double exponent_extra = link.exponent_offset[e] * 10.0 * std::log10(std::max(rel.norm(), p.min_distance_m));
      double rssi = mean_rssi_dbm(p, tag.spec.tx_power_dbm, rel.norm(), env) + p.shadowing_std_db[e] * shadow +
                    fading + p.rx_offset_db + p.channel_offset_db[ch] - exponent_extra + link.static_offset_db[e] +
                    link.channel_offset_db[ch] + link.tx_bias_db;
      if (lost || rssi < p.sensitivity_dbm) continue;
      if (p.quantize) rssi = std::round(rssi);
      BleReception rec;
      rec.t_true_s = t;
      rec.address = tag.addr;
      rec.rssi_dbm = rssi;
      rec.tx_power_dbm = tag.spec.tx_power_dbm;
      rec.channel = 37 + (ch_index + 3) % 3;
      emit(rec);
    }
  }
}

}  // namespace locus::sim::motion
