// locus_amil_bound: what an ideal estimator can do on AMIL's field test (paper 004, Sec. V-D), to
// report Locus against. For each listener of the 1.22 m grid it prints the Cramér-Rao bound of the
// joint (x, y, skew, offset) model (plugins/amil/solver.hpp) and a Monte-Carlo of the exact solvers
// on synthetic arrivals: Gaussian timing error σ_t on every arrival *and* on every self-recorded beep
// (so σ of a_k − e_k is √2·σ_t), optional Gaussian beep-position error σ_p per axis (the IMU), a clock
// skew drawn uniform in ±skew_ppm per trial, beeps at the paper's triangle corners 1.4 s apart.
//
//   locus_amil_bound [--gestures 1|3] [--sigma-samples 0.01,0.05,0.2,1] [--position-std-m 0]
//                    [--skew-ppm 40] [--trials 300] [--seed 1] [--fs 44100]
//
// Methods in the Monte-Carlo: robust (joint position + skew, Huber, per listener), network (all 12
// listeners at once with the beep positions refined, solve_network), paper with the true skew given
// (a perfect calibration table), paper without calibration. Every trial is one gesture: the same
// beep-position errors for all listeners. Columns: CRB direction std (deg) and
// distance std (% of range); per method the mean direction error (deg), the median distance error
// (% of range) and the fraction of trials with a position (not direction-only).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "amil/solver.hpp"

namespace amil = locus::plugins::amil;

namespace {

[[noreturn]] void usage(const std::string& why) {
  std::fprintf(stderr, "locus_amil_bound: %s\nusage: locus_amil_bound [--gestures 1|3] [--sigma-samples a,b,..] "
                       "[--position-std-m X] [--skew-ppm X] [--trials N] [--seed N] [--fs HZ]\n", why.c_str());
  std::exit(2);
}

double number(const std::string& opt, const std::string& v) {
  char* end = nullptr;
  const double d = std::strtod(v.c_str(), &end);
  if (end == v.c_str() || *end != '\0' || !std::isfinite(d)) usage("option " + opt + ": expected a number, got '" + v + "'");
  return d;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

}  // namespace

int main(int argc, char** argv) {
  int gestures = 1, trials = 300;
  unsigned seed = 1;
  double pos_std = 0.0, skew_ppm = 40.0, fs = 44100.0;
  std::vector<double> sigmas{0.01, 0.05, 0.2, 1.0};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage("option " + a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--gestures") gestures = static_cast<int>(number(a, v));
    else if (a == "--trials") trials = static_cast<int>(number(a, v));
    else if (a == "--seed") seed = static_cast<unsigned>(number(a, v));
    else if (a == "--position-std-m") pos_std = number(a, v);
    else if (a == "--skew-ppm") skew_ppm = number(a, v);
    else if (a == "--fs") fs = number(a, v);
    else if (a == "--sigma-samples") {
      sigmas.clear();
      std::stringstream ss(v);
      std::string item;
      while (std::getline(ss, item, ',')) sigmas.push_back(number(a, item));
    } else usage("unknown option " + a);
  }
  if (gestures < 1 || gestures > 10 || trials < 1 || pos_std < 0 || fs <= 0 || sigmas.empty()) usage("bad option value");

  constexpr double c = 343.2, side = 0.305;
  std::vector<Eigen::Vector2d> pos{{0, 0}};
  for (int g = 0; g < gestures; ++g) {
    pos.emplace_back(-side, 0.0);
    pos.emplace_back(0.0, side);
    pos.emplace_back(side, 0.0);
    pos.emplace_back(0.0, 0.0);
  }
  std::vector<double> times;
  for (std::size_t k = 0; k < pos.size(); ++k) times.push_back(3.0 + 1.4 * static_cast<double>(k));
  std::vector<Eigen::Vector2d> grid;
  for (int row = 1; row <= 4; ++row)
    for (int col = -1; col <= 1; ++col) grid.emplace_back(1.22 * col, 1.22 * row);

  std::mt19937_64 rng(seed);
  std::normal_distribution<double> N(0.0, 1.0);
  std::uniform_real_distribution<double> U(-skew_ppm * 1e-6, skew_ppm * 1e-6);
  const double deg = 180.0 / std::numbers::pi;

  std::printf("# locus_amil_bound: %d gesture(s), %zu beeps, sigma_p %.4g m, skew ±%g ppm, %d trials per cell\n",
              gestures, pos.size(), pos_std, skew_ppm, trials);
  std::printf("# per method: mean direction error deg / median distance error %% / fraction located\n");
  for (double sig_samples : sigmas) {
    const double st = sig_samples / fs;
    std::printf("\n## sigma_t = %.3g samples (%.3g us per arrival)\n\n", sig_samples, st * 1e6);
    std::printf("| listener (m) | CRB dir (deg) | CRB dist (%%) | robust | network | paper, true skew | paper, no calibration |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    // per listener and method: direction errors, distance errors, located count
    constexpr int kMethods = 4;  // robust, network, paper (true skew), paper (no calibration)
    struct Acc {
      std::vector<double> dir, dist;
      int located = 0;
    };
    std::vector<std::array<Acc, kMethods>> acc(grid.size());
    for (int t = 0; t < trials; ++t) {
      // one gesture: the same beep-position errors for every listener
      std::vector<amil::Beep> beeps;
      for (std::size_t k = 0; k < pos.size(); ++k) {
        amil::Beep b;
        b.position_m = pos[k] + pos_std * Eigen::Vector2d(N(rng), N(rng));  // what the IMU says
        b.player_time_s = times[k] + st * N(rng);
        beeps.push_back(b);
      }
      std::vector<amil::ListenerArrivals> arrs;
      std::vector<double> skews;
      for (const auto& x : grid) {
        const double skew = U(rng);
        amil::ListenerArrivals arr;
        for (std::size_t k = 0; k < pos.size(); ++k)  // the truth: emitted at times[k] from pos[k]
          arr.arrival_s.push_back(0.7 + (1.0 + skew) * (times[k] + (x - pos[k]).norm() / c) + st * N(rng));
        arrs.push_back(arr);
        skews.push_back(skew);
      }
      amil::SolverConfig cfg;
      cfg.speed_of_sound_mps = c;
      cfg.timing_std_s = std::max(std::sqrt(2.0) * st, 1e-9);
      cfg.position_std_m = std::max(pos_std, 1e-4);
      const auto net = amil::solve_network(beeps, arrs, cfg);
      for (std::size_t l = 0; l < grid.size(); ++l) {
        const auto& x = grid[l];
        for (int m = 0; m < kMethods; ++m) {
          amil::Solution s;
          if (m == 1) s = net.listeners[l];
          else {
            amil::SolverConfig cm = cfg;
            cm.method = m == 0 ? amil::Method::Robust : amil::Method::Paper;
            cm.known_skew = m == 2 ? skews[l] : 0.0;
            s = amil::solve(beeps, arrs[l], cm);
          }
          auto& a = acc[l][static_cast<std::size_t>(m)];
          if (std::isfinite(s.direction_rad))
            a.dir.push_back(std::abs(std::remainder(s.direction_rad - std::atan2(x.y(), x.x()), 2 * std::numbers::pi)) * deg);
          if (s.located()) {
            ++a.located;
            a.dist.push_back(100.0 * std::abs(s.distance_m - x.norm()) / x.norm());
          }
        }
      }
    }
    for (std::size_t l = 0; l < grid.size(); ++l) {
      const auto& x = grid[l];
      const auto bd = amil::cramer_rao(pos, times, x, 0.0, std::sqrt(2.0) * st, pos_std, c);
      std::printf("| (%.2f, %.2f) | %.3f | %.1f |", x.x(), x.y(), bd.direction_std_rad * deg,
                  100.0 * bd.distance_std_m / x.norm());
      for (auto& a : acc[l]) {
        double mean_dir = 0;
        for (double d : a.dir) mean_dir += d;
        mean_dir = a.dir.empty() ? std::nan("") : mean_dir / static_cast<double>(a.dir.size());
        std::printf(" %.2f / %.1f / %.2f |", mean_dir, median(a.dist), static_cast<double>(a.located) / trials);
      }
      std::printf("\n");
    }
  }
  return 0;
}
