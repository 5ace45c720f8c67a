// locus_bench_tum: CPU cost of TUM's localization per exchange (issue 14: a particle-filter update with
// 200 particles < 1 ms; one exchange, detection on 4 devices x 2 mics + solve + filter, < 20 ms; the
// paper's phones: 228 ms detection + 25 ms filter, Table I).
//
//   BM_TumParticleUpdate     one Sec. V update of a moving device's filter (200 particles): predict,
//                            outlier test, Gaussian weights from the window fix, resampling when due
//   BM_TumPairRoots          one exchange's working pair alone: every root of Eq. 6 (multi-start LM)
//   BM_TumNetworkExchange    one exchange added to the 12-exchange window (4 devices, one moving):
//                            the pair's roots as candidates, the window's Levenberg-Marquardt, the
//                            covariances (steady state: the window is full, the devices known);
//                            exchange_motion:1 as the plugin runs (motion within an exchange, Doppler
//                            coupling: up to three LM passes), :0 without
// Detection of one exchange is the chirp detector's cost (locus_bench_chirp, BM_ChirpTumWorking): its
// per-exchange figure and the sum are in docs/tum.md, "Speed". CPU time, single-threaded.
#include <benchmark/benchmark.h>

#include <random>

#include "locus/dsp/signals.hpp"
#include "support/tum_synthetic.hpp"
#include "tum/network.hpp"
#include "tum/tracker.hpp"

namespace {

using namespace locus::test::tum_synthetic;

void BM_TumParticleUpdate(benchmark::State& state) {
  tum::TrackerConfig cfg;
  cfg.particles = static_cast<int>(state.range(0));
  tum::Tracker tr(cfg, 1);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 0.02);
  const Eigen::Matrix3d cov = Eigen::Matrix3d::Identity() * 0.02 * 0.02;
  double t = 0.0;
  Vector3d x(1.0, 0.5, 0.0);
  tr.update_gaussian(x, cov, true, t);
  for (auto _ : state) {
    t += 1.0 / 3.0;
    x += Vector3d(0.08, 0.0, 0.0);
    const Vector3d fix = x + Vector3d(n01(rng), n01(rng), n01(rng));
    benchmark::DoNotOptimize(tr.update_gaussian(fix, cov, true, t));
  }
}
BENCHMARK(BM_TumParticleUpdate)->ArgName("particles")->Arg(200)->Unit(benchmark::kMicrosecond);

void BM_TumPairRoots(benchmark::State& state) {
  const auto poses = layout(1.0);
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  const auto ex = exchange(poses, 1.0, 1.02);
  for (auto _ : state) benchmark::DoNotOptimize(tum::solve_exchange({ex[0], ex[1]}, cfg));
}
BENCHMARK(BM_TumPairRoots)->Unit(benchmark::kMillisecond);

void BM_TumNetworkExchange(benchmark::State& state) {
  auto poses = layout(0.8, true);
  tum::SolverConfig cfg;
  cfg.speed_of_sound_mps = kC;
  tum::NetworkConfig ncfg;
  ncfg.exchange_motion = state.range(0) != 0;  // the plugin's default: on, with TUM's tones' instants
  locus::SignalSpec up;
  up.type = "lfm", up.f0_hz = 2000, up.f1_hz = 8000, up.duration_s = 0.04, up.fade_s = 0.005;
  locus::SignalSpec down = up;
  std::swap(down.f0_hz, down.f1_hz);
  ncfg.doppler_instant1_s = locus::dsp::doppler_timing_instant_s(up, 44100.0);
  ncfg.doppler_instant2_s = locus::dsp::doppler_timing_instant_s(down, 44100.0);
  tum::NetworkSolver net(cfg, ncfg);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> lat(-0.03, 0.04);
  int k = 0;
  auto next = [&] {
    const double t1 = 1.0 + k / 3.0;
    // device 2 (M) rides a circle of 0.3 m at 0.25 m/s
    const double a = 0.8 * t1;
    poses[1].p = Vector3d(3.0 + 0.3 * std::cos(a), 3.7 + 0.3 * std::sin(a), 0.8);
    poses[1].q = flat(2.356 + a);
    auto ex = exchange(poses, t1, t1 + lat(rng), 5e-6, &rng);
    ex[1].moving = true;
    ++k;
    return ex;
  };
  for (int i = 0; i < 14; ++i) net.add(next());  // fill the window, place every device
  for (auto _ : state) {
    state.PauseTiming();
    const auto ex = next();
    state.ResumeTiming();
    benchmark::DoNotOptimize(net.add(ex));
  }
}
BENCHMARK(BM_TumNetworkExchange)->ArgName("exchange_motion")->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
