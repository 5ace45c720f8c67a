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

}  // namespace locus
