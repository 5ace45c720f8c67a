// locus_bench_amil: CPU cost of locating the 12 listeners of one AMIL gesture (issue 6: < 50 ms of CPU;
// the paper's phone needed 3.1 s for the beep detection of one recording alone, Table II).
//
//   BM_AmilDetectOneDevice      the chirp detector (18-22 kHz, 50 ms AMIL beep) over one device's
//                               gesture recording (7 s at 44.1 kHz, 5 beeps, noise): what each phone
//                               does for itself (the paper's Table II figure)
//   BM_AmilSolve/method:M       positioning of 12 listeners from their arrivals (solver.hpp), M =
//                               0 paper, 1 paper_joint_skew, 2 joint, 3 robust; /gestures 1 or 3
//   BM_AmilWholeGesture         detection on all 13 recordings (player + 12 listeners) + pairing +
//                               robust positioning of the 12 listeners, sequentially on one core: the
//                               total CPU of the whole gesture, as if one machine did everything
// Detectors are configured once, outside the timing (a node plans its FFTs at start-up), and see
// the recordings as one continuous stream per device.
// Audio: white noise at 25 dB SNR (the `normal` simulator profile) with the beep at integer-sample
// delays: the detector's cost does not depend on the fractional part. CPU time is the measure
// (benchmark's CPU column; single-threaded).
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "amil/solver.hpp"
#include "chirp/chirp.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "support/test_host.hpp"

namespace {

using namespace locus;
namespace amil = locus::plugins::amil;

constexpr double kFs = 44100.0;
constexpr double kSeconds = 7.0;
constexpr double kC = 343.2;
constexpr double kSide = 0.305;

dsp::SignalSpec amil_beep() {
  dsp::SignalSpec s;
  s.type = "lfm";
  s.f0_hz = 18000;
  s.f1_hz = 22000;
  s.duration_s = 0.050;
  s.fade_s = 0.005;
  return s;
}

std::vector<Eigen::Vector2d> beep_positions(int gestures) {
  std::vector<Eigen::Vector2d> p{{0, 0}};
  for (int g = 0; g < gestures; ++g) {
    p.emplace_back(-kSide, 0.0);
    p.emplace_back(0.0, kSide);
    p.emplace_back(kSide, 0.0);
    p.emplace_back(0.0, 0.0);
  }
  return p;
}

std::vector<Eigen::Vector2d> listeners() {
  std::vector<Eigen::Vector2d> v;
  for (int row = 1; row <= 4; ++row)
    for (int col = -1; col <= 1; ++col) v.emplace_back(1.22 * col, 1.22 * row);
  return v;
}

/// One device's recording of the 5 beeps of one gesture, heard from `at` (nullptr = the player).
std::vector<float> recording(const Eigen::Vector2d* at, unsigned seed) {
  const auto h = dsp::render_signal(amil_beep(), kFs);
  std::vector<float> v(static_cast<std::size_t>(kSeconds * kFs));
  std::mt19937_64 rng(seed);
  const double amp = at ? 1.0 / std::max(1.0, at->norm()) : 0.9;
  std::normal_distribution<double> g(0, amp / std::sqrt(2.0) / std::pow(10.0, 25.0 / 20.0));
  for (float& s : v) s = static_cast<float>(g(rng));
  const auto pos = beep_positions(1);
  for (std::size_t k = 0; k < pos.size(); ++k) {
    const double t = 0.5 + 1.3 * static_cast<double>(k) + (at ? (*at - pos[k]).norm() / kC : 0.0);
    const auto n0 = static_cast<std::size_t>(t * kFs);
    for (std::size_t j = 0; j < h.size() && n0 + j < v.size(); ++j) v[n0 + j] += static_cast<float>(amp * h[j]);
  }
  return v;
}

FftwPlanner& planner() {
  static FftwPlanner p("", true);
  return p;
}

/// One device's chirp detector, configured once (as a node does at start-up: FFTW plans, templates),
/// then fed recording after recording as one continuous stream.
struct DeviceDetector {
  explicit DeviceDetector(test::TestHost& host) : det(plugins::chirp::descriptor()->create_detector()) {
    Params p = Params::defaults(plugins::chirp::schema());
    p.set("f0_hz", 18000.0);
    p.set("f1_hz", 22000.0);
    p.set("duration_s", 0.05);
    p.set("fade_s", 0.005);
    StreamInfo info;
    info.device = "bench";
    info.channels = 1;
    info.sample_rate_hz = kFs;
    info.max_block_frames = 1024;
    HostContext ctx{host.log, host.clock, planner(), host.link, "amil_bench", "bench"};
    det->configure(info, p, ctx);
  }
  /// Runs one recording through the detector; returns the arrival times (s, from the recording's start).
  std::vector<double> detect(const std::vector<float>& x) {
    sink.events.clear();
    const float* ptr = nullptr;
    for (std::size_t pos = 0; pos < x.size(); pos += 1024) {
      const std::size_t n = std::min<std::size_t>(1024, x.size() - pos);
      ptr = x.data() + pos;
      AudioBlock b;
      b.channel_data = &ptr;
      b.channels = 1;
      b.frames = static_cast<std::uint32_t>(n);
      b.first_frame = base + pos;
      det->process_audio(b, sink);
    }
    std::vector<double> t;
    for (const auto& e : sink.events)
      if (const auto* d = std::get_if<AudioDetection>(&e)) t.push_back((d->frame - static_cast<double>(base)) / kFs);
    base += x.size() + 44100;  // the next recording comes later on the same stream
    return t;
  }
  std::unique_ptr<Detector> det;
  test::CollectingSink sink{1 << 12};
  std::uint64_t base = 0;
};

struct Gesture {
  std::vector<std::vector<float>> audio;  ///< [0] = player, [1..12] = listeners
  Gesture() {
    audio.push_back(recording(nullptr, 1));
    unsigned seed = 2;
    for (const auto& l : listeners()) audio.push_back(recording(&l, seed++));
  }
};

const Gesture& gesture() {
  static const Gesture g;
  return g;
}

void BM_AmilDetectOneDevice(benchmark::State& state) {
  const auto& x = gesture().audio[5];
  test::TestHost host;
  DeviceDetector device(host);
  std::size_t found = 0;
  for (auto _ : state) found = device.detect(x).size();
  state.counters["beeps_found"] = static_cast<double>(found);
  state.counters["x_realtime"] = benchmark::Counter(kSeconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_AmilDetectOneDevice)->Unit(benchmark::kMillisecond);

void BM_AmilSolve(benchmark::State& state) {
  const auto method = static_cast<amil::Method>(state.range(0));
  const int gestures = static_cast<int>(state.range(1));
  const auto pos = beep_positions(gestures);
  std::vector<amil::Beep> beeps;
  for (std::size_t k = 0; k < pos.size(); ++k) {
    amil::Beep b;
    b.position_m = pos[k];
    b.player_time_s = 3.0 + 1.3 * static_cast<double>(k);
    beeps.push_back(b);
  }
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n(0, 1.5e-6);
  std::vector<amil::ListenerArrivals> arr;
  for (const auto& l : listeners()) {
    amil::ListenerArrivals a;
    a.arrival_s = amil::exact_arrivals(beeps, l, 30e-6, 1.7, kC);
    for (double& t : a.arrival_s) t += n(rng);
    arr.push_back(a);
  }
  amil::SolverConfig cfg;
  cfg.method = method;
  cfg.position_std_m = 0.003;
  int located = 0;
  for (auto _ : state) {
    located = 0;
    for (const auto& a : arr) located += amil::solve(beeps, a, cfg).located() ? 1 : 0;
  }
  state.counters["listeners_with_position"] = located;
  state.SetLabel(amil::to_string(method));
}
BENCHMARK(BM_AmilSolve)->ArgNames({"method", "gestures"})->ArgsProduct({{0, 1, 2, 3}, {1, 3}})->Unit(benchmark::kMicrosecond);

void BM_AmilWholeGesture(benchmark::State& state) {
  const Gesture& g = gesture();
  test::TestHost host;
  const auto pos = beep_positions(1);
  amil::SolverConfig cfg;
  cfg.position_std_m = 0.003;
  std::vector<std::unique_ptr<DeviceDetector>> devices;
  for (std::size_t d = 0; d < g.audio.size(); ++d) devices.push_back(std::make_unique<DeviceDetector>(host));
  int located = 0;
  for (auto _ : state) {
    const std::vector<double> e = devices[0]->detect(g.audio[0]);
    std::vector<amil::Beep> beeps;
    for (std::size_t k = 0; k < pos.size(); ++k) {
      amil::Beep b;
      b.position_m = pos[k];
      b.player_time_s = k < e.size() ? e[k] : std::nan("");
      beeps.push_back(b);
    }
    located = 0;
    for (std::size_t l = 1; l < g.audio.size(); ++l) {
      const std::vector<double> a = devices[l]->detect(g.audio[l]);
      amil::ListenerArrivals arr;
      // pairing: the k-th arrival is the k-th beep (beeps 1.3 s apart, no clock offset here)
      for (std::size_t k = 0; k < pos.size(); ++k) arr.arrival_s.push_back(k < a.size() ? a[k] : std::nan(""));
      located += amil::solve(beeps, arr, cfg).located() ? 1 : 0;
    }
  }
  state.counters["listeners_with_position"] = located;
  state.counters["recordings"] = static_cast<double>(g.audio.size());
}
BENCHMARK(BM_AmilWholeGesture)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
