// locus_bench_chirp: the `chirp` detector and its correlator against direct time-domain correlation,
// on the same 9 s of 44.1 kHz audio (white noise, a 2-8 kHz 40 ms TUM chirp every 0.5 s at 10 dB SNR).
//
//   BM_ChirpDetector/prescreen:{0,1}   the whole detector (correlation, noise, earliest path, refine)
//   BM_ChirpDetectorFftSize/fft_size:N the same with another overlap-save FFT size (default 8192)
//   BM_ChirpDetector4x4                4 channels x 4 templates (x_realtime is per channel per template)
//   BM_ChirpTumWorking/cancel_own:{0,1} a TUM working device: 2 channels, the scene's up and down
//                                      chirps as templates, its own up chirp (0.5 FS) every 1/3 s overlapped
//                                      20 ms later by the other's down chirp 40 dB weaker; with and
//                                      without the own-emission canceller (x_realtime per channel per template)
//   BM_CorrelatorOnly                  dsp::Correlator streaming, real output only (no detection)
//   BM_DirectCorrelation               y[k] = sum_j x[k+j] h[j] over the same 9 s (the O(n m) baseline)
// Counter x_realtime = seconds of audio processed per second of CPU time of the benchmark thread (per
// channel per template; single-threaded, so on an idle core CPU time = wall time; on the shared build
// machine wall time is inflated by other processes and CPU time is the fair measure).
// tests/bench/chirp_vs_scipy.py runs this and times scipy.signal.correlate on the same samples
// (LOCUS_BENCH_CHIRP_DUMP=<file> makes this binary write them as raw float32).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "chirp/chirp.hpp"
#include "locus/dsp/correlator.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "support/test_host.hpp"

namespace {

using namespace locus;

constexpr double kFs = 44100.0;
constexpr double kSeconds = 9.0;

dsp::SignalSpec tum_chirp(double f0 = 2000, double f1 = 8000) {
  dsp::SignalSpec s;
  s.type = "lfm";
  s.f0_hz = f0;
  s.f1_hz = f1;
  s.duration_s = 0.040;
  s.fade_s = 0.005;
  return s;
}

/// The 9 s benchmark signal (deterministic).
const std::vector<float>& audio() {
  static const std::vector<float> x = [] {
    const auto h = dsp::render_signal(tum_chirp(), kFs);
    double ps = 0;
    for (float v : h) ps += double(v) * v;
    ps /= double(h.size());
    const double a = 0.3, sigma = a * std::sqrt(ps / 10.0);  // 10 dB SNR
    std::vector<float> v(static_cast<std::size_t>(kSeconds * kFs));
    std::mt19937_64 rng(42);
    std::normal_distribution<double> g(0, sigma);
    for (float& s : v) s = static_cast<float>(g(rng));
    for (double t = 0.1; t + 0.05 < kSeconds; t += 0.5) {
      const auto n0 = static_cast<std::size_t>(t * kFs);
      for (std::size_t j = 0; j < h.size(); ++j) v[n0 + j] += static_cast<float>(a * h[j]);
    }
    if (const char* dump = std::getenv("LOCUS_BENCH_CHIRP_DUMP")) {
      if (FILE* f = std::fopen(dump, "wb")) {
        std::fwrite(v.data(), sizeof(float), v.size(), f);
        std::fclose(f);
      }
      const std::string tpath = std::string(dump) + ".template";
      if (FILE* f = std::fopen(tpath.c_str(), "wb")) {
        std::fwrite(h.data(), sizeof(float), h.size(), f);
        std::fclose(f);
      }
    }
    return v;
  }();
  return x;
}

FftwPlanner& planner() {
  static FftwPlanner p("", true);
  return p;
}

/// Feeds `x` (the same signal on every channel) through `det` in 1024-frame blocks once per benchmark
/// iteration, the stream's frame counter running on; returns the detections of all passes.
std::size_t run_passes(benchmark::State& state, Detector& det, const std::vector<float>& x, std::uint32_t channels) {
  std::vector<const float*> ptrs(channels);
  test::CollectingSink sink(1 << 20);
  std::uint64_t frame = 0;
  std::size_t detections = 0;
  for (auto _ : state) {
    for (std::size_t pos = 0; pos < x.size(); pos += 1024) {
      const std::size_t n = std::min<std::size_t>(1024, x.size() - pos);
      for (auto& ptr : ptrs) ptr = x.data() + pos;
      AudioBlock b;
      b.channel_data = ptrs.data();
      b.channels = channels;
      b.frames = static_cast<std::uint32_t>(n);
      b.first_frame = frame;
      det.process_audio(b, sink);
      frame += n;
    }
    detections += sink.events.size();
    sink.events.clear();
  }
  return detections;
}

void run_detector(benchmark::State& state, std::uint32_t channels, std::size_t templates, bool prescreen,
                  std::int64_t fft_size = 0) {
  const std::vector<float>& x = audio();
  test::TestHost host;
  std::unique_ptr<Detector> det(plugins::chirp::descriptor()->create_detector());
  Params p = Params::defaults(plugins::chirp::schema());
  p.set("prescreen", prescreen);
  p.set("fft_size", fft_size);
  if (templates > 1) {
    std::vector<double> list;
    const double bands[4][2] = {{2000, 8000}, {8000, 2000}, {2500, 7500}, {7500, 2500}};
    for (std::size_t t = 0; t < templates; ++t) list.insert(list.end(), {bands[t % 4][0], bands[t % 4][1], 0.04, 0.005});
    p.set("templates", list);
  }
  StreamInfo info;
  info.device = "bench";
  info.channels = channels;
  info.sample_rate_hz = kFs;
  info.max_block_frames = 1024;
  HostContext ctx{host.log, host.clock, planner(), host.link, "chirp_bench", "bench"};
  det->configure(info, p, ctx);
  const std::size_t detections = run_passes(state, *det, x, channels);
  const double audio_s = kSeconds * double(state.iterations()) * channels * double(templates);
  state.counters["x_realtime"] = benchmark::Counter(audio_s, benchmark::Counter::kIsRate);
  state.counters["detections_per_pass"] =
      double(detections) / double(std::max<benchmark::IterationCount>(1, state.iterations()));
}

void BM_ChirpDetector(benchmark::State& state) { run_detector(state, 1, 1, state.range(0) != 0); }
BENCHMARK(BM_ChirpDetector)->ArgName("prescreen")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_ChirpDetectorFftSize(benchmark::State& state) { run_detector(state, 1, 1, false, state.range(0)); }
BENCHMARK(BM_ChirpDetectorFftSize)->ArgName("fft_size")->Arg(4096)->Arg(16384)->Arg(32768)->Unit(benchmark::kMillisecond);

void BM_ChirpDetector4x4(benchmark::State& state) { run_detector(state, 4, 4, false); }
BENCHMARK(BM_ChirpDetector4x4)->Unit(benchmark::kMillisecond);

/// 9 s of a TUM working device's mic: own up chirp at 0.5 every 1/3 s, the other's down chirp 40 dB
/// weaker 20 ms later, white noise 70 dB below the own chirp.
const std::vector<float>& tum_working_audio() {
  static const std::vector<float> x = [] {
    const auto up = dsp::render_signal(tum_chirp(2000, 8000), kFs), down = dsp::render_signal(tum_chirp(8000, 2000), kFs);
    std::vector<float> v(static_cast<std::size_t>(kSeconds * kFs));
    std::mt19937_64 rng(43);
    std::normal_distribution<double> g(0, 0.5 * std::pow(10.0, -70.0 / 20.0));
    for (float& s : v) s = static_cast<float>(g(rng));
    for (double t = 0.1; t + 0.1 < kSeconds; t += 1.0 / 3.0) {
      const auto n0 = static_cast<std::size_t>(t * kFs), n1 = n0 + static_cast<std::size_t>(0.02 * kFs);
      for (std::size_t j = 0; j < up.size(); ++j) v[n0 + j] += 0.5f * up[j];
      for (std::size_t j = 0; j < down.size(); ++j) v[n1 + j] += 0.005f * down[j];
    }
    return v;
  }();
  return x;
}

void BM_ChirpTumWorking(benchmark::State& state) {
  const std::vector<float>& x = tum_working_audio();
  constexpr std::uint32_t channels = 2;
  test::TestHost host;
  std::unique_ptr<Detector> det(plugins::chirp::descriptor()->create_detector());
  Params p = Params::defaults(plugins::chirp::schema());
  p.set("from_scene", true);
  p.set("cancel_own", state.range(0) != 0);
  DeviceGeometry geometry;
  geometry.mic_count = channels;
  geometry.has_speaker = true;
  const test::TumChirpSignals tum = test::tum_chirp_signals("A", "D");
  geometry.emits = tum.own;
  geometry.scene_emits = tum.scene;
  StreamInfo info;
  info.device = "A";
  info.channels = channels;
  info.sample_rate_hz = kFs;
  info.max_block_frames = 1024;
  HostContext ctx{host.log, host.clock, planner(), host.link, "chirp_bench", "A", &geometry};
  det->configure(info, p, ctx);
  const std::size_t detections = run_passes(state, *det, x, channels);
  const double audio_s = kSeconds * double(state.iterations()) * channels * 2.0;
  state.counters["x_realtime"] = benchmark::Counter(audio_s, benchmark::Counter::kIsRate);
  state.counters["detections_per_pass"] =
      double(detections) / double(std::max<benchmark::IterationCount>(1, state.iterations()));
}
BENCHMARK(BM_ChirpTumWorking)->ArgName("cancel_own")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_CorrelatorOnly(benchmark::State& state) {
  const std::vector<float>& x = audio();
  dsp::Correlator c;
  c.configure({dsp::render_signal(tum_chirp(), kFs)}, planner(), {1, 0, false});
  double sink = 0;
  for (auto _ : state) {
    c.reset(0);
    for (std::size_t pos = 0; pos < x.size();) {
      pos += c.push(0, x.data() + pos, x.size() - pos);
      if (c.full(0)) {
        c.transform(0);
        c.correlate(0);
        sink += c.real(0)[0];
        c.advance(0);
      }
    }
  }
  benchmark::DoNotOptimize(sink);
  state.counters["x_realtime"] = benchmark::Counter(kSeconds * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_CorrelatorOnly)->Unit(benchmark::kMillisecond);

void BM_DirectCorrelation(benchmark::State& state) {
  const std::vector<float>& x = audio();
  const auto h = dsp::render_signal(tum_chirp(), kFs);
  std::vector<float> y(x.size() - h.size() + 1);
  for (auto _ : state) {
    dsp::correlate_direct(x.data(), x.size(), h.data(), h.size(), y.data());
    benchmark::DoNotOptimize(y.data());
    benchmark::ClobberMemory();
  }
  state.counters["x_realtime"] = benchmark::Counter(kSeconds * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DirectCorrelation)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
