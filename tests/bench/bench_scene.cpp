// Scene stream I/O throughput: WAV write/read (4 channels, 48 kHz, 4096-frame blocks) in each sample
// format, and IMU CSV write/read. x_realtime = seconds of recording processed per second.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "locus/scene/streams.hpp"

using namespace locus;
using namespace locus::scene;

namespace {

constexpr int kChannels = 4;
constexpr double kRate = 48000.0;
constexpr double kSeconds = 20.0;
constexpr std::size_t kBlock = 4096;

std::string tmp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("locus-bench-scene-" + name)).string();
}

std::vector<float> block_signal() {
  std::vector<float> x(kBlock * kChannels);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(0.5 * std::sin(0.001 * static_cast<double>(i)));
  return x;
}

void write_wav(const std::string& p, WavSampleFormat fmt, const std::vector<float>& x) {
  WavWriter w(p, kChannels, kRate, fmt);
  const auto frames = static_cast<std::size_t>(kSeconds * kRate);
  for (std::size_t done = 0; done < frames; done += kBlock) w.write(x.data(), std::min(kBlock, frames - done));
  w.close();
}

void BM_WavWrite(benchmark::State& st) {
  const auto fmt = static_cast<WavSampleFormat>(st.range(0));
  const auto x = block_signal();
  const std::string p = tmp_path(std::string("w-") + to_string(fmt) + ".wav");
  for (auto _ : st) write_wav(p, fmt, x);
  st.counters["x_realtime"] = benchmark::Counter(kSeconds, benchmark::Counter::kIsIterationInvariantRate);
  st.SetLabel(to_string(fmt));
  std::filesystem::remove(p);
}

void BM_WavRead(benchmark::State& st) {
  const auto fmt = static_cast<WavSampleFormat>(st.range(0));
  const std::string p = tmp_path(std::string("r-") + to_string(fmt) + ".wav");
  write_wav(p, fmt, block_signal());
  std::vector<float> buf(kBlock * kChannels);
  double sum = 0.0;
  for (auto _ : st) {
    WavReader r(p);
    while (std::size_t n = r.read(buf.data(), kBlock)) sum += buf[n - 1];
  }
  benchmark::DoNotOptimize(sum);
  st.counters["x_realtime"] = benchmark::Counter(kSeconds, benchmark::Counter::kIsIterationInvariantRate);
  st.SetLabel(to_string(fmt));
  std::filesystem::remove(p);
}

constexpr int kImuRows = 200 * 600;  // 10 minutes at 200 Hz

void BM_ImuCsvWrite(benchmark::State& st) {
  const std::string p = tmp_path("imu-w.csv");
  for (auto _ : st) {
    ImuCsvWriter w(p, true);
    ImuSample s;
    s.has_mag = true;
    for (int i = 0; i < kImuRows; ++i) {
      s.t_s = i * 0.005;
      s.accel_mps2 = {0.1f * i, -0.25f, 9.81f};
      s.gyro_radps = {0.001f, 0.002f * i, -0.003f};
      s.mag_ut = {12.5f, -3.0f, 44.0f};
      w.write(s);
    }
    w.close();
  }
  st.counters["x_realtime"] = benchmark::Counter(kImuRows * 0.005, benchmark::Counter::kIsIterationInvariantRate);
  std::filesystem::remove(p);
}

void BM_ImuCsvRead(benchmark::State& st) {
  const std::string p = tmp_path("imu-r.csv");
  {
    ImuCsvWriter w(p, true);
    ImuSample s;
    s.has_mag = true;
    for (int i = 0; i < kImuRows; ++i) {
      s.t_s = i * 0.005;
      s.accel_mps2 = {0.1f * i, -0.25f, 9.81f};
      w.write(s);
    }
  }
  double sum = 0.0;
  for (auto _ : st) {
    ImuCsvReader r(p, "A");
    ImuSample s;
    while (r.next(s)) sum += s.accel_mps2[0];
  }
  benchmark::DoNotOptimize(sum);
  st.counters["x_realtime"] = benchmark::Counter(kImuRows * 0.005, benchmark::Counter::kIsIterationInvariantRate);
  std::filesystem::remove(p);
}

}  // namespace

BENCHMARK(BM_WavWrite)->DenseRange(0, 3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_WavRead)->DenseRange(0, 3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ImuCsvWrite)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ImuCsvRead)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
