// FFTW-backed FftPlanner (single precision). Planning is serialised (FFTW's planner is not
// thread-safe) and can load/save wisdom so that a board plans in milliseconds after the first run.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "locus/fft.hpp"

namespace locus {

class FftwPlanner final : public FftPlanner {
 public:
  /// `wisdom_path`: file to import wisdom from at construction and export to on destruction ("" =
  /// none). `measure`: FFTW_MEASURE (slower planning, faster transforms) instead of FFTW_ESTIMATE.
  explicit FftwPlanner(std::string wisdom_path = {}, bool measure = true);
  ~FftwPlanner() override;

  std::unique_ptr<RealFft> plan_real(std::size_t n) override;
  std::unique_ptr<ComplexFft> plan_complex(std::size_t n) override;
  /// [main] Writes the accumulated wisdom to the wisdom path now; false on failure.
  bool save_wisdom();

 private:
  std::string wisdom_path_;
  bool measure_;
};

}  // namespace locus
