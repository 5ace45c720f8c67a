// Deterministic random numbers for the simulator.
//
// Why not <random>: the distributions of the standard library are implementation-defined, so the
// same seed could give different scenes with another standard library. This generator
// (xoshiro256** seeded through splitmix64) and its distributions are fully specified here, so a
// scene is a pure function of (family, seed, difficulty, options) on every platform.
//
// Every independent random stream (noise of device A, latency of emissions, IMU of B, ...) is made
// with Rng::derive(seed, "name"): adding a new stream never shifts the numbers of another one.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string_view>

namespace locus::sim {

class Rng {
 public:
  explicit Rng(std::uint64_t seed = 0) noexcept {
    std::uint64_t x = seed;
    for (auto& w : s_) w = splitmix(x);
  }
  /// An independent stream for `name` under `seed` (FNV-1a of the name mixed into the seed).
  static Rng derive(std::uint64_t seed, std::string_view name) noexcept {
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char c : name) h = (h ^ c) * 1099511628211ull;
    return Rng(seed ^ (h * 0x9E3779B97F4A7C15ull));
  }

  std::uint64_t next_u64() noexcept {
    const std::uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  /// Uniform in [0, 1).
  double uniform() noexcept { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) noexcept { return lo + (hi - lo) * uniform(); }
  /// Uniform integer in [lo, hi] (hi >= lo).
  long long integer(long long lo, long long hi) noexcept {
    const auto span = static_cast<std::uint64_t>(hi - lo) + 1u;
    return lo + static_cast<long long>(next_u64() % span);
  }
  /// Standard normal (Box-Muller, both values used).
  double normal() noexcept {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    if (u1 < 1e-300) u1 = 1e-300;
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * std::numbers::pi * u2);
  }
  double normal(double mean, double sigma) noexcept { return mean + sigma * normal(); }
  /// Exponential with the given mean.
  double exponential(double mean) noexcept { return -mean * std::log(1.0 - uniform()); }
  /// True with probability p.
  bool bernoulli(double p) noexcept { return uniform() < p; }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) noexcept { return (x << k) | (x >> (64 - k)); }
  static std::uint64_t splitmix(std::uint64_t& x) noexcept {
    std::uint64_t z = (x += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::uint64_t s_[4];
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace locus::sim
