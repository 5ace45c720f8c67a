// dsp::simd kernels against scalar references. The element-wise kernels (sub1, sub2, cmul_split,
// max_norm) must give exactly the scalar loop's values; the reductions (dot2, energy, dot_f64) exactly
// the values of a scalar emulation of their documented 8-lane order (so the AVX2 and the baseline
// clone agree to the bit), and the plain double sum within their precision. Lengths cover the vector
// body, the scalar tail and empty input.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "locus/dsp/simd.hpp"

namespace locus::dsp::simd {
namespace {

std::vector<float> randf(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> g;
  std::vector<float> v(n);
  for (float& x : v) x = g(rng);
  return v;
}

const std::size_t kLengths[] = {0, 1, 7, 8, 9, 13, 64, 1286, 5339};

// Σ y·a in the kernels' order: 8 float lanes over the full blocks, lanes 0-3 then 4-7 added in
// double, then the tail in double.
double dot8(const float* y, const float* a, std::size_t n) {
  float lane[8] = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8)
    for (int l = 0; l < 8; ++l) lane[l] += y[j + l] * a[j + l];
  double s = (static_cast<double>(lane[0]) + lane[1] + lane[2] + lane[3]) +
             (static_cast<double>(lane[4]) + lane[5] + lane[6] + lane[7]);
  for (; j < n; ++j) s += static_cast<double>(y[j]) * a[j];
  return s;
}

TEST(Simd, ReductionsFollowTheirLaneOrderExactly) {
  for (std::size_t n : kLengths) {
    const auto y = randf(n, 1), a = randf(n, 2), b = randf(n, 3);
    double ra = 0.0, rb = 0.0;
    dot2(y.data(), a.data(), b.data(), n, ra, rb);
    EXPECT_EQ(ra, dot8(y.data(), a.data(), n)) << n;
    EXPECT_EQ(rb, dot8(y.data(), b.data(), n)) << n;
    EXPECT_EQ(energy(y.data(), n), dot8(y.data(), y.data(), n)) << n;
    double exact = 0.0, mag = 0.0;
    for (std::size_t j = 0; j < n; ++j) {
      exact += static_cast<double>(y[j]) * a[j];
      mag += std::abs(static_cast<double>(y[j]) * a[j]);
    }
    EXPECT_NEAR(ra, exact, 1e-6 * mag + 1e-12) << n;
  }
}

TEST(Simd, DoubleDotIsExactToDoubleRounding) {
  for (std::size_t n : kLengths) {
    std::mt19937 rng(7);
    std::normal_distribution<double> g;
    std::vector<double> a(n), b(n);
    for (std::size_t j = 0; j < n; ++j) {
      a[j] = g(rng);
      b[j] = g(rng);
    }
    // The kernel's order: 8 double lanes, then ((l0 + l2) + (l4 + l6)) + ((l1 + l3) + (l5 + l7)) (four
    // 2-lane accumulators s0..s3 added as (s0 + s1) + (s2 + s3), then its two lanes), then the tail.
    double lane[8] = {};
    std::size_t j = 0;
    for (; j + 8 <= n; j += 8)
      for (int l = 0; l < 8; ++l) lane[l] += a[j + l] * b[j + l];
    double ref = ((lane[0] + lane[2]) + (lane[4] + lane[6])) + ((lane[1] + lane[3]) + (lane[5] + lane[7]));
    for (; j < n; ++j) ref += a[j] * b[j];
    const double got = dot_f64(a.data(), b.data(), n);
    EXPECT_EQ(got, ref) << n;
    long double exact = 0.0L, mag = 0.0L;
    for (std::size_t k = 0; k < n; ++k) {
      exact += static_cast<long double>(a[k]) * b[k];
      mag += std::abs(static_cast<long double>(a[k]) * b[k]);
    }
    EXPECT_NEAR(got, static_cast<double>(exact), 1e-14 * static_cast<double>(mag) + 1e-300) << n;
  }
}

TEST(Simd, ElementWiseKernelsEqualTheScalarLoop) {
  for (std::size_t n : kLengths) {
    const auto a = randf(n, 4), b = randf(n, 5), c = randf(n, 6), d = randf(n, 7);
    auto y1 = randf(n, 8), y2 = y1, r1 = y1, r2 = y1;
    sub1(y1.data(), a.data(), 0.37f, n);
    sub2(y2.data(), a.data(), b.data(), -1.3f, 0.61f, n);
    for (std::size_t j = 0; j < n; ++j) {
      r1[j] -= 0.37f * a[j];
      r2[j] -= -1.3f * a[j] + 0.61f * b[j];
    }
    EXPECT_EQ(y1, r1) << n;
    EXPECT_EQ(y2, r2) << n;
    std::vector<float> out(2 * n), ref(2 * n);
    cmul_split(a.data(), b.data(), c.data(), d.data(), out.data(), n);
    for (std::size_t k = 0; k < n; ++k) {
      ref[2 * k] = a[k] * c[k] - b[k] * d[k];
      ref[2 * k + 1] = a[k] * d[k] + b[k] * c[k];
    }
    EXPECT_EQ(out, ref) << n;
  }
}

TEST(Simd, MaxNormKeepsTheLargestScaledPowerAndItsTag) {
  for (std::size_t n : kLengths) {
    std::vector<float> best(n, 0.0f), tag(n, -1.0f), rb(n, 0.0f), rt(n, -1.0f);
    for (int v = 0; v < 6; ++v) {
      const auto z = randf(2 * n, 20 + static_cast<unsigned>(v));
      const float scale = 0.5f + 0.25f * static_cast<float>(v);
      max_norm(z.data(), scale, static_cast<float>(v), best.data(), tag.data(), n);
      for (std::size_t d = 0; d < n; ++d) {
        const float e = (z[2 * d] * z[2 * d] + z[2 * d + 1] * z[2 * d + 1]) * scale;
        if (e > rb[d]) {
          rb[d] = e;
          rt[d] = static_cast<float>(v);
        }
      }
    }
    EXPECT_EQ(best, rb) << n;
    EXPECT_EQ(tag, rt) << n;
    if (n >= 8) {  // a real maximum: several versions win somewhere
      int changed = 0;
      for (float t : tag) changed += t > 0.0f;
      EXPECT_GT(changed, 0);
    }
  }
}

}  // namespace
}  // namespace locus::dsp::simd
