// LocBLE per-update cost (docs/locble.md, "Speed"): what the localizer does for every tag at each
// update — the readings' positions on the dead-reckoned path, the bins, the grid posterior — for
// 1 to 20 tags heard at 10 Hz over a 12 s L walk (~120 readings each, the shipped config's grid), and
// the paper's Eq. 2-5 regression alone. Issue 17 asks < 2 ms of CPU for 20 tags.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "locble/solver.hpp"

namespace {

namespace lb = locus::plugins::locble;

struct Scenario {
  lb::DeadReckoning dr;
  std::vector<std::vector<lb::Reading>> tags;
};

Scenario make(int tags) {
  Scenario s;
  s.dr.add_heading(0.0, 0.0);
  double t = 2.0;
  for (int k = 0; k < 10; ++k, t += 0.55) {
    const double h = k < 5 ? 0.0 : std::numbers::pi / 2;
    for (double u = t - 0.5; u <= t; u += 0.05) s.dr.add_heading(u, h);
    s.dr.add_step(t, 0.75, 1.8);
  }
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 4.0);
  std::uniform_real_distribution<double> u(-8.0, 8.0);
  for (int i = 0; i < tags; ++i) {
    const lb::Vec2 tag(u(rng), u(rng));
    std::vector<lb::Reading> r;
    for (double ts = 0.0; ts < 12.0; ts += 0.1) {
      const double d = std::max((tag - s.dr.position_at(ts)).norm(), 0.5);
      r.push_back({ts, std::round(-60.0 - 20.0 * std::log10(d) + g(rng))});
    }
    s.tags.push_back(std::move(r));
  }
  return s;
}

/// What an update does per tag before solving: place each reading on the dead-reckoned path, bin it.
template <typename Readings>
auto bins_of(const Scenario& s, const Readings& readings) {
  std::vector<lb::Vec2> pos(readings.size());
  std::vector<double> len(readings.size());
  for (std::size_t i = 0; i < readings.size(); ++i) {
    pos[i] = s.dr.position_at(readings[i].t_s);
    len[i] = s.dr.path_length_at(readings[i].t_s);
  }
  return lb::make_bins(readings, pos, len, 0.5);
}

void BM_LocBleUpdate(benchmark::State& state) {
  const Scenario s = make(static_cast<int>(state.range(0)));
  lb::PosteriorOptions po;  // the shipped config: 20 m radius, 1 m grid
  po.grid_step_m = 1.0;
  lb::PositionPosterior post(po);
  for (auto _ : state) {
    for (const auto& readings : s.tags) {
      const auto bins = bins_of(s, readings);
      benchmark::DoNotOptimize(post.solve(bins, lb::Vec2(0, 1)));
    }
  }
  state.counters["tags"] = static_cast<double>(state.range(0));
}
BENCHMARK(BM_LocBleUpdate)->ArgName("tags")->Arg(1)->Arg(20)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

// What the plugin runs per tag (solve_coarse_to_fine, adaptive_noise on: its default).
void BM_LocBleUpdatePlugin(benchmark::State& state) {
  const Scenario s = make(static_cast<int>(state.range(0)));
  lb::PosteriorOptions po;
  po.grid_step_m = 1.0;
  lb::PositionPosterior post(po);
  for (auto _ : state) {
    for (const auto& readings : s.tags) {
      const auto bins = bins_of(s, readings);
      benchmark::DoNotOptimize(post.solve_coarse_to_fine(bins, lb::Vec2(0, 1), true, 0.1));
    }
  }
}
BENCHMARK(BM_LocBleUpdatePlugin)->ArgName("tags")->Arg(1)->Arg(20)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

// Sec. 6 clustering at one update of 20 tags: every tag's 12 s trace (10 Hz grid) against the 19
// others (cluster_matrix: LB_Keogh + DTW per 10-point segment, each pair once); the ANF that makes
// the traces is in bench_motion.
void BM_LocBleClusters(benchmark::State& state) {
  const int tags = static_cast<int>(state.range(0));
  std::mt19937_64 rng(3);
  std::normal_distribution<float> g(0.0f, 0.3f);
  std::vector<std::vector<float>> traces(static_cast<std::size_t>(tags));
  for (int k = 0; k < tags; ++k)
    for (int i = 0; i < 120; ++i)
      traces[static_cast<std::size_t>(k)].push_back(-70.0f + 5.0f * std::sin(0.05f * static_cast<float>(i) * (1.0f + 0.1f * static_cast<float>(k % 3))) + g(rng));
  for (auto _ : state) benchmark::DoNotOptimize(lb::cluster_matrix(traces));
}
BENCHMARK(BM_LocBleClusters)->ArgName("tags")->Arg(20)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

void BM_LocBleRegression(benchmark::State& state) {
  const Scenario s = make(1);
  std::vector<lb::Vec2> o;
  std::vector<double> r;
  for (const auto& x : s.tags[0]) {
    o.push_back(s.dr.position_at(x.t_s));
    r.push_back(x.rssi_dbm);
  }
  for (auto _ : state) benchmark::DoNotOptimize(lb::elliptical_regression(o, r));
}
BENCHMARK(BM_LocBleRegression)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
