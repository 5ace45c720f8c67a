// BleRssiModel: mean RSSI vs distance fits the set exponent, loss rate matches, channels/quantisation,
// determinism for a seed.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "locus/sim/motion/ble.hpp"

using namespace locus::sim;
using namespace locus::sim::motion;
using Eigen::Vector3d;

namespace {

// Tags at the origin; an observer walking away along x from 1 m to 21 m over `duration` s.
Simulation make_sim(int n_tags, double duration) {
  Simulation sim;
  sim.duration_s = duration;
  for (int i = 0; i < n_tags; ++i) {
    EmitterModel e;
    e.id = "tag" + std::to_string(i);
    locus::dsp::SignalSpec s;
    s.type = "ble";
    char addr[32];
    std::snprintf(addr, sizeof addr, "C4:2C:03:3A:2C:%02X", i);
    s.address = addr;
    s.tx_power_dbm = -59.0;
    s.interval_s = 0.1;
    e.emits.push_back(s);
    e.trajectory = std::make_shared<StaticTrajectory>(Vector3d(0, 0, 1));
    sim.emitters.push_back(e);
  }
  DeviceModel obs;
  obs.id = "P";
  obs.trajectory = std::make_shared<FunctionTrajectory>(
      [duration](double t) {
        Pose p;
        p.position_m = Vector3d(1.0 + 20.0 * std::clamp(t / duration, 0.0, 1.0), 0.0, 1.0);
        return p;
      },
      20.0 / duration);
  sim.devices.push_back(obs);
  return sim;
}

struct Fit {
  double slope, intercept;
};
Fit fit(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return {slope, (sy - slope * sx) / n};
}

}  // namespace

class BleExponent : public ::testing::TestWithParam<Propagation> {};

TEST_P(BleExponent, MeanRssiVsDistanceFitsTheSetExponent) {
  const Propagation env = GetParam();
  const Simulation sim = make_sim(30, 60.0);
  BleChannelParams p;
  p.loss_probability = 0.0;
  p.sensitivity_dbm = -200.0;
  BleRssiModel model(p, [env](const std::string&, const Vector3d&, const Vector3d&, double) { return env; });
  Rng rng(17);
  std::vector<double> x, y;
  model.scan(sim, sim.devices[0], 0.0, sim.duration_s, rng, [&](const BleReception& r) {
    const double d = (sim.devices[0].trajectory->pose(r.t_true_s).position_m - Vector3d(0, 0, 1)).norm();
    x.push_back(-10.0 * std::log10(d));
    y.push_back(r.rssi_dbm);
  });
  ASSERT_GT(x.size(), 15000u);
  const Fit f = fit(x, y);
  const auto e = static_cast<std::size_t>(env);
  EXPECT_NEAR(f.slope, p.exponent[e], 0.1) << to_string(env);
  // Intercept: tx power − blockage + the mean of the fading in dB (Rician mean in dB is < 0) ± offsets.
  EXPECT_NEAR(f.intercept, -59.0 - p.extra_loss_db[e], 3.5) << to_string(env);
}

INSTANTIATE_TEST_SUITE_P(Classes, BleExponent,
                         ::testing::Values(Propagation::los, Propagation::partial, Propagation::nlos));

TEST(Ble, LossRateChannelsAndQuantisation) {
  const Simulation sim = make_sim(10, 100.0);
  BleChannelParams p;
  p.loss_probability = 0.25;
  p.sensitivity_dbm = -200.0;
  BleRssiModel model(p);
  Rng rng(5);
  std::map<int, int> channels;
  std::size_t n = 0;
  model.scan(sim, sim.devices[0], 0.0, sim.duration_s, rng, [&](const BleReception& r) {
    ++n;
    ++channels[r.channel];
    EXPECT_EQ(r.rssi_dbm, std::round(r.rssi_dbm));
    ASSERT_TRUE(r.tx_power_dbm.has_value());
    EXPECT_EQ(*r.tx_power_dbm, -59.0);
  });
  // Events: every interval + advDelay (mean 5 ms) → 100 s / 0.105 s per tag.
  const double expected_events = 10 * 100.0 / 0.105;
  EXPECT_NEAR(n / expected_events, 0.75, 0.02);
  EXPECT_EQ(channels.size(), 3u);
  for (int ch = 37; ch <= 39; ++ch) EXPECT_GT(channels[ch], static_cast<int>(n / 4)) << ch;
}

TEST(Ble, SensitivityDropsWeakPackets) {
  const Simulation sim = make_sim(3, 30.0);
  BleChannelParams p;
  p.loss_probability = 0.0;
  p.sensitivity_dbm = -80.0;
  BleRssiModel model(p);
  Rng rng(5);
  model.scan(sim, sim.devices[0], 0.0, sim.duration_s, rng,
             [&](const BleReception& r) { EXPECT_GE(r.rssi_dbm, -80.0); });
}

TEST(Ble, ShadowingIsCorrelatedAlongTheWalk) {
  // No fading: consecutive packets (~14 cm apart) share most of their shadowing; far apart they do not.
  const Simulation sim = make_sim(20, 150.0);
  BleChannelParams p;
  p.loss_probability = 0.0;
  p.sensitivity_dbm = -200.0;
  p.fading = false;
  p.quantize = false;
  p.channel_offset_db = {0.0, 0.0, 0.0};
  BleRssiModel model(p);
  Rng rng(8);
  std::map<std::string, std::vector<double>> resid;  // per tag, in time order
  model.scan(sim, sim.devices[0], 0.0, sim.duration_s, rng, [&](const BleReception& r) {
    const double d = (sim.devices[0].trajectory->pose(r.t_true_s).position_m - Vector3d(0, 0, 1)).norm();
    resid[locus::scene::format_ble_address(r.address)].push_back(r.rssi_dbm - mean_rssi_dbm(p, -59.0, d, Propagation::los));
  });
  auto corr = [&](std::size_t lag) {
    double sxy = 0, sxx = 0;
    for (const auto& [k, v] : resid)
      for (std::size_t i = 0; i + lag < v.size(); ++i) {
        sxy += v[i] * v[i + lag];
        sxx += v[i] * v[i];
      }
    return sxy / sxx;
  };
  // 20 m in 150 s: ~1.4 cm per packet; decorrelation 1 m → lag 1 ρ≈0.986, lag 140 (~2 m) ρ≈0.14.
  EXPECT_GT(corr(1), 0.95);
  EXPECT_LT(corr(140), 0.4);
}

TEST(Ble, DeterministicForASeed) {
  const Simulation sim = make_sim(4, 20.0);
  BleRssiModel model;
  auto run = [&](std::uint64_t seed) {
    Rng rng(seed);
    std::vector<double> out;
    model.scan(sim, sim.devices[0], 0.0, sim.duration_s, rng, [&](const BleReception& r) {
      out.push_back(r.t_true_s);
      out.push_back(r.rssi_dbm);
    });
    return out;
  };
  EXPECT_EQ(run(3), run(3));
  EXPECT_NE(run(3), run(4));
}

TEST(Ble, RejectsBadTagsAndParameters) {
  Simulation sim = make_sim(1, 5.0);
  sim.emitters[0].emits[0].address = "C4:2C:03";
  BleRssiModel model;
  Rng rng(1);
  try {
    model.scan(sim, sim.devices[0], 0.0, 5.0, rng, [](const BleReception&) {});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tag0"), std::string::npos) << e.what();
  }
  BleChannelParams p;
  p.loss_probability = 1.5;
  EXPECT_THROW(BleRssiModel{p}, std::invalid_argument);
}
