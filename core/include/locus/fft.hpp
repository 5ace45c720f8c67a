// Host-owned FFT planning: plans are made once, on the main thread, outside the real-time path;
// executing a plan is real-time safe (no allocation, no lock, no syscall).
#pragma once

#include <complex>
#include <cstddef>
#include <memory>

namespace locus {

/// A real <-> complex FFT of a fixed size n (n/2+1 complex bins), unnormalised (inverse(forward(x))
/// = n*x). Inputs and outputs may be any float arrays; the plan works on its own aligned buffers.
class RealFft {
 public:
  virtual ~RealFft() = default;
  std::size_t size() const noexcept { return n_; }
  /// [RT] `in`: n floats; `out`: n/2+1 complex values.
  virtual void forward(const float* in, std::complex<float>* out) noexcept = 0;
  /// [RT] `in`: n/2+1 complex values; `out`: n floats.
  virtual void inverse(const std::complex<float>* in, float* out) noexcept = 0;

 protected:
  explicit RealFft(std::size_t n) : n_(n) {}
  std::size_t n_;
};

class FftPlanner {
 public:
  virtual ~FftPlanner() = default;
  /// [main] Plans a real FFT of size n (thread-safe; may take a while the first time for a size,
  /// faster with saved wisdom). Throws std::invalid_argument for n < 2.
  virtual std::unique_ptr<RealFft> plan_real(std::size_t n) = 0;
};

}  // namespace locus
