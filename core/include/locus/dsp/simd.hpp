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

namespace locus::dsp::simd {

using v4f = float __attribute__((vector_size(16)));  // 4 float lanes (the IQ decimator's taps)

// The kernels below are compiled twice on x86-64 (simd.cpp: GCC/Clang target_clones, picked at load
// time): for AVX2 (256-bit registers) and for baseline SSE2. Both run the same 8-lane arithmetic in
// the same order, so the results are bit-identical on every x86-64 machine; elsewhere (the Pi) the
// baseline build runs.

/// Σ y·a and Σ y·b over n floats (8 float lanes, lane sums added in double; relative error ~1e-6).
void dot2(const float* y, const float* a, const float* b, std::size_t n, double& ra, double& rb) noexcept;

/// Σ y² over n floats (8 float lanes).
double energy(const float* y, std::size_t n) noexcept;

/// y[j] −= ci·a[j] + cq·b[j], j < n (float, element-wise: the same values as the scalar loop).
void sub2(float* y, const float* a, const float* b, float ci, float cq, std::size_t n) noexcept;

/// y[j] −= g·a[j], j < n (float, element-wise: the same values as the scalar loop).
void sub1(float* y, const float* a, float g, std::size_t n) noexcept;

/// Σ a·b over n doubles (8 double lanes: full double precision, for sums whose errors a fit amplifies).
double dot_f64(const double* a, const double* b, std::size_t n) noexcept;

/// out[k] = (xr[k] + j·xi[k]) · (cr[k] + j·ci[k]), k < n, written interleaved
/// (re, im) to out[2k], out[2k+1]: a spectrum times a (conjugated, split) template spectrum.
void cmul_split(const float* xr, const float* xi, const float* cr, const float* ci, float* out, std::size_t n) noexcept;

/// Running maximum over versions: for d < n, e = |z[d]|²·scale (z interleaved complex); where
/// e > best[d]: best[d] = e, tag[d] = tag_value.
void max_norm(const float* z, float scale, float tag_value, float* best, float* tag, std::size_t n) noexcept;

}  // namespace locus::dsp::simd
