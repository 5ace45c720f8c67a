#include "locus/fftw_planner.hpp"

#include <fftw3.h>

#include <cstring>
#include <stdexcept>
#include <string>

namespace locus {

namespace {

// One process-wide planner lock: FFTW's planner (and wisdom) is global state.
std::mutex& planner_mutex() {
  static std::mutex m;
  return m;
}

class FftwRealFft final : public RealFft {
 public:
  FftwRealFft(std::size_t n, unsigned flags) : RealFft(n) {
    time_ = static_cast<float*>(fftwf_malloc(sizeof(float) * n));
    freq_ = static_cast<fftwf_complex*>(fftwf_malloc(sizeof(fftwf_complex) * (n / 2 + 1)));
    if (!time_ || !freq_) throw std::bad_alloc();
    const int ni = static_cast<int>(n);
    fwd_ = fftwf_plan_dft_r2c_1d(ni, time_, freq_, flags);
    inv_ = fftwf_plan_dft_c2r_1d(ni, freq_, time_, flags);
    if (!fwd_ || !inv_) throw std::runtime_error("FFTW could not plan a real FFT of size " + std::to_string(n));
  }
  ~FftwRealFft() override {
    std::lock_guard lock(planner_mutex());
    if (fwd_) fftwf_destroy_plan(fwd_);
    if (inv_) fftwf_destroy_plan(inv_);
    fftwf_free(time_);
    fftwf_free(freq_);
  }
  void forward(const float* in, std::complex<float>* out) noexcept override {
    std::memcpy(time_, in, sizeof(float) * n_);
    fftwf_execute(fwd_);
    std::memcpy(static_cast<void*>(out), freq_, sizeof(fftwf_complex) * (n_ / 2 + 1));
  }
  void forward_aligned(const float* in, std::complex<float>* out) noexcept override {
    auto* o = reinterpret_cast<fftwf_complex*>(out);
    // New-array execution needs the planned buffers' alignment (r2c out of place keeps its input).
    if (fftwf_alignment_of(const_cast<float*>(in)) == fftwf_alignment_of(time_) &&
        fftwf_alignment_of(reinterpret_cast<float*>(o)) == fftwf_alignment_of(reinterpret_cast<float*>(freq_)))
      fftwf_execute_dft_r2c(fwd_, const_cast<float*>(in), o);
    else
      forward(in, out);
  }
  void inverse_destroying(std::complex<float>* in, float* out) noexcept override {
    auto* i = reinterpret_cast<fftwf_complex*>(in);
    if (fftwf_alignment_of(reinterpret_cast<float*>(i)) == fftwf_alignment_of(reinterpret_cast<float*>(freq_)) &&
        fftwf_alignment_of(out) == fftwf_alignment_of(time_))
      fftwf_execute_dft_c2r(inv_, i, out);
    else
      inverse(in, out);
  }
  void inverse(const std::complex<float>* in, float* out) noexcept override {
    // c2r destroys its input, so it always works on the plan's own copy.
    std::memcpy(freq_, static_cast<const void*>(in), sizeof(fftwf_complex) * (n_ / 2 + 1));
    fftwf_execute(inv_);
    std::memcpy(out, time_, sizeof(float) * n_);
  }

 private:
  float* time_ = nullptr;
  fftwf_complex* freq_ = nullptr;
  fftwf_plan fwd_ = nullptr;
  fftwf_plan inv_ = nullptr;
};

class FftwComplexFft final : public ComplexFft {
 public:
  FftwComplexFft(std::size_t n, unsigned flags) : ComplexFft(n) {
    in_ = reinterpret_cast<std::complex<float>*>(fftwf_malloc(sizeof(fftwf_complex) * n));
    out_ = reinterpret_cast<std::complex<float>*>(fftwf_malloc(sizeof(fftwf_complex) * n));
    if (!in_ || !out_) {
      fftwf_free(in_);
      fftwf_free(out_);
      throw std::bad_alloc();
    }
    // Out of place: FFTW keeps the input of a complex transform (FFTW_PRESERVE_INPUT is its default).
    plan_ = fftwf_plan_dft_1d(static_cast<int>(n), reinterpret_cast<fftwf_complex*>(in_),
                              reinterpret_cast<fftwf_complex*>(out_), FFTW_BACKWARD, flags | FFTW_PRESERVE_INPUT);
    if (!plan_) throw std::runtime_error("FFTW could not plan a complex FFT of size " + std::to_string(n));
    std::memset(static_cast<void*>(in_), 0, sizeof(fftwf_complex) * n);
  }
  ~FftwComplexFft() override {
    std::lock_guard lock(planner_mutex());
    if (plan_) fftwf_destroy_plan(plan_);
    fftwf_free(in_);
    fftwf_free(out_);
  }
  void inverse() noexcept override { fftwf_execute(plan_); }

 private:
  fftwf_plan plan_ = nullptr;
};

}  // namespace

FftwPlanner::FftwPlanner(std::string wisdom_path, bool measure)
    : wisdom_path_(std::move(wisdom_path)), measure_(measure) {
  if (!wisdom_path_.empty()) {
    std::lock_guard lock(planner_mutex());
    fftwf_import_wisdom_from_filename(wisdom_path_.c_str());  // absent file: no wisdom yet
  }
}

FftwPlanner::~FftwPlanner() {
  if (!wisdom_path_.empty()) save_wisdom();
}

bool FftwPlanner::save_wisdom() {
  if (wisdom_path_.empty()) return false;
  std::lock_guard lock(planner_mutex());
  return fftwf_export_wisdom_to_filename(wisdom_path_.c_str()) != 0;
}

std::unique_ptr<RealFft> FftwPlanner::plan_real(std::size_t n) {
  if (n < 2) throw std::invalid_argument("FFT size must be >= 2, got " + std::to_string(n));
  std::lock_guard lock(planner_mutex());
  return std::make_unique<FftwRealFft>(n, measure_ ? FFTW_MEASURE : FFTW_ESTIMATE);
}

std::unique_ptr<ComplexFft> FftwPlanner::plan_complex(std::size_t n) {
  if (n < 2 || n % 2 != 0) throw std::invalid_argument("plan_complex: n must be even and >= 2, got " + std::to_string(n));
  std::lock_guard lock(planner_mutex());
  return std::make_unique<FftwComplexFft>(n, measure_ ? FFTW_MEASURE : FFTW_ESTIMATE);
}

}  // namespace locus
