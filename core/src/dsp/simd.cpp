// Vector kernels (interface and why in locus/dsp/simd.hpp). Written on 8-lane GCC/Clang vectors: one
// 256-bit register in the AVX2 clone, two 128-bit ones (SSE2 / NEON) in the baseline; the lane
// layout and the order of every sum are the same in both, so both give the same bits.
#include "locus/dsp/simd.hpp"

#include <cstring>

// The 8-lane helpers below are always inlined into the clones (LOCUS_SIMD_INLINE, also at -O0): their
// by-value AVX-sized vectors must never cross a call, whose ABI differs between the AVX2 clone and the
// baseline helper (a Debug build that called them read garbage: ASan, Goldcode tests). GCC warns about
// that ABI regardless.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#define LOCUS_SIMD_INLINE inline __attribute__((always_inline))

namespace locus::dsp::simd {

namespace {

using v8f = float __attribute__((vector_size(32)));
using v8i = int __attribute__((vector_size(32)));
using v4d = double __attribute__((vector_size(32)));

// Unaligned vector load / store (memcpy: no alignment assumed, one instruction once inlined).
template <class V, class T>
LOCUS_SIMD_INLINE V load(const T* p) noexcept {
  V v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
LOCUS_SIMD_INLINE v8f load8(const float* p) noexcept { return load<v8f>(p); }
LOCUS_SIMD_INLINE v4d load4d(const double* p) noexcept { return load<v4d>(p); }
LOCUS_SIMD_INLINE void store8(float* p, v8f v) noexcept { std::memcpy(p, &v, sizeof v); }
// The 8 lanes added in double, lanes 0-3 then 4-7 (the order of the former two 4-lane accumulators).
LOCUS_SIMD_INLINE double hsum8(v8f a) noexcept {
  return (static_cast<double>(a[0]) + a[1] + a[2] + a[3]) + (static_cast<double>(a[4]) + a[5] + a[6] + a[7]);
}

}  // namespace

// Not in sanitizer and fuzzer builds (LOCUS_SANITIZED): target_clones dispatch through an ifunc
// resolver that the dynamic loader runs before any sanitizer runtime is up, and TSan's instrumented
// resolver crashed every test binary at load (./run sanitize tsan). The baseline clone gives the same bits.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(LOCUS_NO_TARGET_CLONES) && \
    !defined(LOCUS_SANITIZED)
#define LOCUS_SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LOCUS_SIMD_CLONES
#endif

LOCUS_SIMD_CLONES
void dot2(const float* y, const float* a, const float* b, std::size_t n, double& ra, double& rb) noexcept {
  v8f sa = {}, sb = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const v8f yv = load8(y + j);
    sa += yv * load8(a + j);
    sb += yv * load8(b + j);
  }
  double da = hsum8(sa), db = hsum8(sb);
  for (; j < n; ++j) {
    da += static_cast<double>(y[j]) * a[j];
    db += static_cast<double>(y[j]) * b[j];
  }
  ra = da;
  rb = db;
}

LOCUS_SIMD_CLONES
double energy(const float* y, std::size_t n) noexcept {
  v8f s = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    const v8f yv = load8(y + j);
    s += yv * yv;
  }
  double e = hsum8(s);
  for (; j < n; ++j) e += static_cast<double>(y[j]) * y[j];
  return e;
}

LOCUS_SIMD_CLONES
void sub2(float* y, const float* a, const float* b, float ci, float cq, std::size_t n) noexcept {
  const v8f vi = {ci, ci, ci, ci, ci, ci, ci, ci}, vq = {cq, cq, cq, cq, cq, cq, cq, cq};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) store8(y + j, load8(y + j) - (vi * load8(a + j) + vq * load8(b + j)));
  for (; j < n; ++j) y[j] -= ci * a[j] + cq * b[j];
}

LOCUS_SIMD_CLONES
void sub1(float* y, const float* a, float g, std::size_t n) noexcept {
  const v8f vg = {g, g, g, g, g, g, g, g};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) store8(y + j, load8(y + j) - vg * load8(a + j));
  for (; j < n; ++j) y[j] -= g * a[j];
}

LOCUS_SIMD_CLONES
double dot_f64(const double* a, const double* b, std::size_t n) noexcept {
  v4d s01 = {}, s23 = {};
  std::size_t j = 0;
  for (; j + 8 <= n; j += 8) {
    s01 += load4d(a + j) * load4d(b + j);
    s23 += load4d(a + j + 4) * load4d(b + j + 4);
  }
  // (s0 + s1) + (s2 + s3) with s0 = lanes 0-1, s1 = 2-3 of s01 (and s2, s3 of s23), as 2-lane sums.
  const double r0 = s01[0] + s01[2], r1 = s01[1] + s01[3], r2 = s23[0] + s23[2], r3 = s23[1] + s23[3];
  double r = (r0 + r2) + (r1 + r3);
  for (; j < n; ++j) r += a[j] * b[j];
  return r;
}

LOCUS_SIMD_CLONES
void cmul_split(const float* xr, const float* xi, const float* cr, const float* ci, float* out, std::size_t n) noexcept {
  std::size_t k = 0;
  for (; k + 8 <= n; k += 8) {
    const v8f ar = load8(xr + k), ai = load8(xi + k), br = load8(cr + k), bi = load8(ci + k);
    const v8f pr = ar * br - ai * bi, pi = ar * bi + ai * br;
    store8(out + 2 * k, __builtin_shufflevector(pr, pi, 0, 8, 1, 9, 2, 10, 3, 11));
    store8(out + 2 * k + 8, __builtin_shufflevector(pr, pi, 4, 12, 5, 13, 6, 14, 7, 15));
  }
  for (; k < n; ++k) {
    out[2 * k] = xr[k] * cr[k] - xi[k] * ci[k];
    out[2 * k + 1] = xr[k] * ci[k] + xi[k] * cr[k];
  }
}

LOCUS_SIMD_CLONES
void max_norm(const float* z, float scale, float tag_value, float* best, float* tag, std::size_t n) noexcept {
  const v8f vs = {scale, scale, scale, scale, scale, scale, scale, scale};
  const v8f vt = {tag_value, tag_value, tag_value, tag_value, tag_value, tag_value, tag_value, tag_value};
  std::size_t d = 0;
  for (; d + 8 <= n; d += 8) {
    const v8f a = load8(z + 2 * d), b = load8(z + 2 * d + 8);
    const v8f a2 = a * a, b2 = b * b;
    const v8f e = (__builtin_shufflevector(a2, b2, 0, 2, 4, 6, 8, 10, 12, 14) +
                   __builtin_shufflevector(a2, b2, 1, 3, 5, 7, 9, 11, 13, 15)) * vs;
    const v8f old = load8(best + d);
    const v8i gt = e > old;
    store8(best + d, reinterpret_cast<v8f>((reinterpret_cast<v8i>(e) & gt) | (reinterpret_cast<v8i>(old) & ~gt)));
    const v8f t = load8(tag + d);
    store8(tag + d, reinterpret_cast<v8f>((reinterpret_cast<v8i>(vt) & gt) | (reinterpret_cast<v8i>(t) & ~gt)));
  }
  for (; d < n; ++d) {
    const float e = (z[2 * d] * z[2 * d] + z[2 * d + 1] * z[2 * d + 1]) * scale;
    if (e > best[d]) {
      best[d] = e;
      tag[d] = tag_value;
    }
  }
}

}  // namespace locus::dsp::simd
