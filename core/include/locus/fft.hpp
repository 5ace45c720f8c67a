// Host-owned FFT planning: plans are made once, on the main thread, outside the real-time path;
// executing a plan is real-time safe (no allocation, no lock, no syscall).
#pragma once

#include <complex>
#include <cstddef>
#include <memory>
#include <stdexcept>
#include <vector>

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
  /// [RT] forward() without copies when `in` and `out` are 64-byte aligned (the plan then runs on
  /// them directly); any other alignment works too, through the copying path.
  virtual void forward_aligned(const float* in, std::complex<float>* out) noexcept { forward(in, out); }
  /// [RT] inverse() without copies for 64-byte aligned buffers; `in` is DESTROYED (used as scratch).
  virtual void inverse_destroying(std::complex<float>* in, float* out) noexcept { inverse(in, out); }

 protected:
  explicit RealFft(std::size_t n) : n_(n) {}
  std::size_t n_;
};

/// A complex inverse DFT of a fixed size n working in place on the plan's own buffers (no copies):
/// fill input()[0..n-1], call inverse(), read output()[m] = sum_k input()[k] exp(+2 pi j k m / n)
/// (unnormalised). input() is preserved by inverse().
class ComplexFft {
 public:
  virtual ~ComplexFft() = default;
  std::size_t size() const noexcept { return n_; }
  std::complex<float>* input() noexcept { return in_; }
  const std::complex<float>* input() const noexcept { return in_; }
  const std::complex<float>* output() const noexcept { return out_; }
  /// [RT]
  virtual void inverse() noexcept = 0;

 protected:
  explicit ComplexFft(std::size_t n) : n_(n) {}
  std::size_t n_;
  std::complex<float>* in_ = nullptr;   // set by the implementation (n values)
  std::complex<float>* out_ = nullptr;  // set by the implementation (n values)
};

class FftPlanner {
 public:
  virtual ~FftPlanner() = default;
  /// [main] Plans a real FFT of size n (thread-safe; may take a while the first time for a size,
  /// faster with saved wisdom). Throws std::invalid_argument for n < 2.
  virtual std::unique_ptr<RealFft> plan_real(std::size_t n) = 0;
  /// [main] Plans a complex inverse DFT of size n (even, >= 2). The default builds it from two real
  /// inverse FFTs of size n (Re and Im of the output are the c2r transforms of the Hermitian and
  /// anti-Hermitian parts of the input); planners with a native complex FFT override it.
  virtual std::unique_ptr<ComplexFft> plan_complex(std::size_t n);
};

namespace detail {
/// The default ComplexFft: two real inverse transforms (see FftPlanner::plan_complex).
class ComplexFromRealFft final : public ComplexFft {
 public:
  ComplexFromRealFft(std::size_t n, std::unique_ptr<RealFft> real)
      : ComplexFft(n), real_(std::move(real)), in_buf_(n), out_buf_(n), half_(n / 2 + 1), re_(n), im_(n) {
    in_ = in_buf_.data();
    out_ = out_buf_.data();
  }
  void inverse() noexcept override {
    // z = IDFT(P): Re z = c2r(E), Im z = c2r(O) with E[k] = (P[k] + conj P[-k]) / 2 and
    // O[k] = (P[k] - conj P[-k]) / (2j), both Hermitian, so bins 0..n/2 determine them.
    const std::size_t n = n_;
    for (std::size_t k = 0; k <= n / 2; ++k) {
      const std::complex<float> a = in_[k], b = std::conj(in_[(n - k) % n]);
      half_[k] = 0.5f * (a + b);
    }
    real_->inverse(half_.data(), re_.data());
    for (std::size_t k = 0; k <= n / 2; ++k) {
      const std::complex<float> a = in_[k], b = std::conj(in_[(n - k) % n]);
      const std::complex<float> d = 0.5f * (a - b);
      half_[k] = {d.imag(), -d.real()};  // d / j
    }
    real_->inverse(half_.data(), im_.data());
    for (std::size_t m = 0; m < n; ++m) out_[m] = {re_[m], im_[m]};
  }

 private:
  std::unique_ptr<RealFft> real_;
  std::vector<std::complex<float>> in_buf_, out_buf_, half_;
  std::vector<float> re_, im_;
};
}  // namespace detail

inline std::unique_ptr<ComplexFft> FftPlanner::plan_complex(std::size_t n) {
  if (n < 2 || n % 2 != 0) throw std::invalid_argument("plan_complex: n must be even and >= 2");
  return std::make_unique<detail::ComplexFromRealFft>(n, plan_real(n));
}

}  // namespace locus
