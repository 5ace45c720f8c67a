// Montage reporter cost per ranging round (docs/montage.md, "Speed"): four users walking (2 steps per
// 1 s round), every pair reported both ways; per iteration: the round's ETOA distances from its four
// reports, and the formation update of that round (difference vectors / localization while users are
// not all placed, then the robust adjustment over the window of `window_rounds` rounds), with the pair
// clock lines the reporter keeps by default (`pair_clocks`: each pair's line from its latest 30 rounds
// checks the round's two-way ranges; learn_clocks). Issue 15 asks
// < 50 ms of CPU per round for 4 users, with detection on every device (the goldcode benchmark).
#include <benchmark/benchmark.h>

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "montage/solver.hpp"

namespace {

namespace mt = locus::plugins::montage;

void BM_MontageRound4Users(benchmark::State& state) {
  const std::size_t warm = static_cast<std::size_t>(state.range(0));  // rounds already solved
  const std::vector<std::string> users{"U0", "U1", "U2", "U3"};
  std::mt19937 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  const double c = 343.0;
  for (auto _ : state) {
    state.PauseTiming();
    mt::FormationConfig cfg;
    mt::Formation f(users, cfg);
    mt::PairClocks clocks;
    std::array<Eigen::Vector2d, 4> p{Eigen::Vector2d(0, 0), {4, 1}, {1, 6}, {-3, 3}};
    std::array<double, 4> h{0.3, 2.0, -1.0, 4.0};
    std::vector<mt::Round> rounds;
    for (std::size_t k = 0; k <= warm; ++k) {
      mt::Round r;
      r.tau_s = static_cast<double>(k);
      for (std::size_t i = 0; i < 4; ++i) {
        mt::RoundMessage m{users[i], r.tau_s, 0.02, {}};
        for (std::size_t j = 0; j < 4; ++j)
          if (j != i) m.arrivals.emplace_back(users[j], (p[j] - p[i]).norm() / c + 0.001 * (static_cast<double>(j) - static_cast<double>(i)) + 1e-5 * n(rng));
        r.reports.emplace(users[i], m);
      }
      rounds.push_back(r);
      for (int s = 1; s <= 2; ++s)
        for (std::size_t u = 0; u < 4; ++u) {
          h[u] += 0.08;
          p[u] += 0.7 * Eigen::Vector2d(std::cos(h[u]), std::sin(h[u]));
          f.add_step(u, static_cast<double>(k) + 0.5 * s, 0.7, h[u], 0.0);
        }
    }
    for (std::size_t k = 0; k < warm; ++k) {
      std::vector<mt::RangeObs> ranges = mt::round_ranges(rounds[k], users, c, 40.0);
      mt::learn_clocks(rounds[k], users, c, ranges, clocks);
      f.add_round(rounds[k].tau_s, std::move(ranges));
      f.solve(k);
    }
    state.ResumeTiming();
    std::vector<mt::RangeObs> ranges = mt::round_ranges(rounds[warm], users, c, 40.0);
    mt::learn_clocks(rounds[warm], users, c, ranges, clocks);
    const std::size_t k = f.add_round(rounds[warm].tau_s, std::move(ranges));
    benchmark::DoNotOptimize(f.solve(k));
  }
}
BENCHMARK(BM_MontageRound4Users)->Arg(5)->Arg(29)->Arg(60)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
