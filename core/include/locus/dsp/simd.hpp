// Small vector kernels shared by the detectors' hot loops (goldcode, the own-emission canceller).
//
// Why here: the project builds for baseline x86-64 (SSE2) and the Pi (NEON) without -march or
// -ffast-math, so GCC does not vectorise reductions (a float sum is not associative) and keeps every
// `s += a[j] * b[j]` a serial dependency chain (one add latency per element). These kernels split the
// work over independent lanes with the GCC/Clang vector extensions (SSE on x86-64, NEON on ARM),
// which is as portable as the scalar code. Summation order differs from a scalar loop (rounding at
// the last bits), nothing else. All are [RT]: no allocation, no branches on data beyond loop bounds.
#pragma once

#include <cstddef>
#include <cstring>

namespace locus::dsp::simd {

using v4f = float __attribute__((vector_size(16)));
using v2d = double __attribute__((vector_size(16)));
using v4i = int __attribute__((vector_size(16)));  // lane masks (a v4f comparison gives -1 / 0)

/// Lane-wise mask ? a : b (mask from a comparison).
inline v4f select(v4i mask, v4f a, v4f b) noexcept {
  return reinterpret_cast<v4f>((reinterpret_cast<v4i>(a) & mask) | (reinterpret_cast<v4i>(b) & ~mask));
}

inline v4f load4(const float* p) noexcept {
  v4f v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline void store4(float* p, v4f v) noexcept { std::memcpy(p, &v, sizeof v); }
inline v2d load2(const double* p) noexcept {
  v2d v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// The 8 float lanes of two accumulators added in double.
inline double hsum(v4f a, v4f b) noexcept {
  return (static_cast<double>(a[0]) + a[1] + a[2] + a[3]) + (static_cast<double>(b[0]) + b[1] + b[2] + b[3]);
}

/// Σ y·a and Σ y·b over n floats (8 float lanes, partial sums added in double; relative error ~1e-6).
inline void dot2(const float* y, const float* a, const float* b, std::size_t n, double& ra, double& rb) noexcept {
  v4f sa0 = {}, sa1 = {}, sb0 = {}, sb1 = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const v4f y0 = load4(y + j), y1 = load4(y + j + 4);
    sa0 += y0 * load4(a + j);
    sa1 += y1 * load4(a + j + 4);
    sb0 += y0 * load4(b + j);
    sb1 += y1 * load4(b + j + 4);
  }
  double da = hsum(sa0, sa1), db = hsum(sb0, sb1);
  for (; j < n; ++j) {
    da += static_cast<double>(y[j]) * a[j];
    db += static_cast<double>(y[j]) * b[j];
  }
  ra = da;
  rb = db;
}

/// Σ y² over n floats (8 float lanes).
inline double energy(const float* y, std::size_t n) noexcept {
  v4f s0 = {}, s1 = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const v4f y0 = load4(y + j), y1 = load4(y + j + 4);
    s0 += y0 * y0;
    s1 += y1 * y1;
  }
  double e = hsum(s0, s1);
  for (; j < n; ++j) e += static_cast<double>(y[j]) * y[j];
  return e;
}

/// y[j] −= ci·a[j] + cq·b[j], j < n (float, element-wise: the same values as the scalar loop).
inline void sub2(float* y, const float* a, const float* b, float ci, float cq, std::size_t n) noexcept {
  const v4f vi = {ci, ci, ci, ci}, vq = {cq, cq, cq, cq};
  std::size_t j = 0;
  for (; j + 4 <= n; j += 4) store4(y + j, load4(y + j) - (vi * load4(a + j) + vq * load4(b + j)));
  for (; j < n; ++j) y[j] -= ci * a[j] + cq * b[j];
}

/// y[j] −= g·a[j], j < n (float, element-wise: the same values as the scalar loop).
inline void sub1(float* y, const float* a, float g, std::size_t n) noexcept {
  const v4f vg = {g, g, g, g};
  std::size_t j = 0;
  for (; j + 4 <= n; j += 4) store4(y + j, load4(y + j) - vg * load4(a + j));
  for (; j < n; ++j) y[j] -= g * a[j];
}

/// Σ a·b over n doubles (8 double lanes: full double precision, for sums whose errors a fit amplifies).
inline double dot_f64(const double* a, const double* b, std::size_t n) noexcept {
  v2d s0 = {}, s1 = {}, s2 = {}, s3 = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    s0 += load2(a + j) * load2(b + j);
    s1 += load2(a + j + 2) * load2(b + j + 2);
    s2 += load2(a + j + 4) * load2(b + j + 4);
    s3 += load2(a + j + 6) * load2(b + j + 6);
  }
  const v2d s = (s0 + s1) + (s2 + s3);
  double r = s[0] + s[1];
  for (; j < n; ++j) r += a[j] * b[j];
  return r;
}

}  // namespace locus::dsp::simd
