#include "locus/fftw_planner.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <vector>

#include "support/test_host.hpp"

namespace locus {
namespace {

TEST(FftwPlanner, MatchesDirectDftAndRoundTrips) {
  FftwPlanner planner({}, /*measure=*/false);
  for (std::size_t n : {8u, 30u, 256u, 1000u}) {
    auto fft = planner.plan_real(n);
    test::NaiveRealFft reference(n);
    std::vector<float> x(n);
    for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>(std::sin(0.37 * i) + 0.25 * std::cos(1.9 * i * i / n));
    std::vector<std::complex<float>> X(n / 2 + 1), R(n / 2 + 1);
    fft->forward(x.data(), X.data());
    reference.forward(x.data(), R.data());
    for (std::size_t k = 0; k <= n / 2; ++k) {
      EXPECT_NEAR(X[k].real(), R[k].real(), 1e-3 * n) << "n=" << n << " k=" << k;
      EXPECT_NEAR(X[k].imag(), R[k].imag(), 1e-3 * n) << "n=" << n << " k=" << k;
    }
    std::vector<float> y(n);
    fft->inverse(X.data(), y.data());
    for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR(y[i] / n, x[i], 1e-5);
    // inverse leaves its input alone
    EXPECT_NEAR(X[1].real(), R[1].real(), 1e-3 * n);
  }
}

TEST(FftwPlanner, RejectsTinySizes) {
  FftwPlanner planner({}, false);
  EXPECT_THROW(planner.plan_real(1), std::invalid_argument);
}

TEST(FftwPlanner, SavesWisdom) {
  const auto path = std::filesystem::temp_directory_path() / ("locus-wisdom-" + std::to_string(::getpid()));
  {
    FftwPlanner planner(path.string(), /*measure=*/true);
    planner.plan_real(512);
    EXPECT_TRUE(planner.save_wisdom());
  }
  EXPECT_GT(std::filesystem::file_size(path), 0u);
  FftwPlanner again(path.string(), true);  // imports it
  auto fft = again.plan_real(512);
  EXPECT_EQ(fft->size(), 512u);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace locus
