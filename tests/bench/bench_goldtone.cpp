// locus_bench_goldtone: throughput of the goldcode (4 codes, Montage parameters) and multitone
// (SpyLoc 10-tone set) detectors on one core. Counter x_realtime = seconds of audio processed per
// second of wall time. The input is 10 s of noise with a coded tone / beep every 0.5 s so that the
// detection paths (refinement, decay features) are part of the cost.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "goldcode/goldcode.hpp"
#include "locus/detector.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "multitone/multitone.hpp"
#include "support/test_host.hpp"

namespace {

constexpr double kFs = 44100.0;

std::vector<float> input(bool gold) {
  std::mt19937 rng(1);
  std::normal_distribution<float> g(0.0f, 0.05f);
  std::vector<float> x(static_cast<std::size_t>(10.0 * kFs));
  for (float& v : x) v = g(rng);
  for (int e = 0; e < 20; ++e) {
    locus::dsp::SignalSpec s;
    if (gold) {
      s.type = "gold";
      s.degree = 7;
      s.index = e % 4;
      s.carrier_hz = 19000.0;
      s.chip_samples = 40;
    } else {
      s.type = "multitone";
      s.tones_hz = {18000, 19250, 19750};
      s.duration_s = 0.05;
      s.fade_s = 0.005;
    }
    s.amplitude = 0.1;
    const auto sig = locus::dsp::render_signal(s, kFs);
    const std::size_t at = static_cast<std::size_t>((0.1 + 0.5 * e) * kFs);
    for (std::size_t i = 0; i < sig.size() && at + i < x.size(); ++i) x[at + i] += sig[i];
  }
  return x;
}

void run(benchmark::State& state, const locus_plugin_descriptor* desc, const locus::ParamSchema& schema, bool gold,
         const char* cycle_choice = nullptr) {
  locus::test::TestHost host;
  locus::FftwPlanner fftw({}, true);
  locus::HostContext ctx{host.log, host.clock, fftw, host.link, "bench", "A"};
  std::unique_ptr<locus::Detector> d(desc->create_detector());
  locus::StreamInfo info;
  info.device = locus::DeviceId("A");
  info.sample_rate_hz = kFs;
  info.max_block_frames = 1024;
  locus::Params params = locus::Params::defaults(schema);
  if (cycle_choice != nullptr) params.set("cycle_choice", std::string(cycle_choice));
  d->configure(info, params, ctx);
  const std::vector<float> x = input(gold);
  locus::test::CollectingSink sink;
  std::uint64_t frame = 0;
  std::size_t events = 0;
  for (auto _ : state) {
    for (std::size_t pos = 0; pos + 1024 <= x.size(); pos += 1024) {
      const float* ch = x.data() + pos;
      locus::AudioBlock b;
      b.channel_data = &ch;
      b.channels = 1;
      b.frames = 1024;
      b.first_frame = frame;
      frame += 1024;
      d->process_audio(b, sink);
    }
    events += sink.events.size();
    sink.events.clear();
  }
  const double seconds = static_cast<double>((x.size() / 1024) * 1024) / kFs;
  state.counters["x_realtime"] = benchmark::Counter(seconds * static_cast<double>(state.iterations()),
                                                    benchmark::Counter::kIsRate);
  state.counters["events_per_pass"] = static_cast<double>(events) / static_cast<double>(state.iterations());
}

// A Montage device (issue 15): its own code at +50 dB through the own-emission canceller, three other
// users walking (±1.2 m/s: Doppler), one round per second; codes from the scene, default parameters
// (Doppler search ±150 Hz in 5 Hz steps, two-path first-arrival model). Per channel.
// gate: with the round gate of config/montage-detect.yaml (round_window_s [0.16, 0.22] s); doppler:
// false = `doppler_max_hz: 0` (one version per code: what the Doppler search costs, same run).
void montage_device(benchmark::State& state, bool gate, bool doppler = true) {
  locus::test::TestHost host;
  locus::FftwPlanner fftw({}, true);
  std::vector<locus::SignalSpec> specs(4);
  std::vector<locus::SceneSignal> scene;
  for (int u = 0; u < 4; ++u) {
    specs[static_cast<std::size_t>(u)].type = "gold";
    specs[static_cast<std::size_t>(u)].degree = 7;
    specs[static_cast<std::size_t>(u)].index = 2 + u;
    specs[static_cast<std::size_t>(u)].carrier_hz = 19000.0;
    specs[static_cast<std::size_t>(u)].chip_samples = 40;
    scene.push_back(locus::SceneSignal{std::string(1, static_cast<char>('A' + u)), specs[static_cast<std::size_t>(u)], false, {}});
  }
  locus::DeviceGeometry g;
  g.mic_count = 1;
  g.has_speaker = true;
  g.emits = std::span<const locus::SignalSpec>(specs.data(), 1);
  g.scene_emits = scene;
  locus::HostContext ctx{host.log, host.clock, fftw, host.link, "bench", "A", &g};
  std::unique_ptr<locus::Detector> d(locus::plugins::goldcode::descriptor()->create_detector());
  locus::StreamInfo info;
  info.device = locus::DeviceId("A");
  info.sample_rate_hz = kFs;
  info.max_block_frames = 1024;
  locus::Params p = locus::Params::defaults(locus::plugins::goldcode::schema());
  p.set("from_scene", true);
  if (gate) p.set("round_window_s", std::vector<double>{0.16, 0.22});
  if (!doppler) p.set("doppler_max_hz", 0.0);
  d->configure(info, p, ctx);
  std::mt19937 rng(3);
  std::normal_distribution<float> g0(0.0f, 1e-4f);
  std::vector<float> x(static_cast<std::size_t>(10.0 * kFs));
  for (float& v : x) v = g0(rng);
  const double speed[4] = {0.0, -1.2, 0.5, 1.2};
  for (int r = 0; r < 10; ++r)
    for (int u = 0; u < 4; ++u) {
      const std::vector<std::uint8_t> chips = locus::dsp::gold_chips(specs[static_cast<std::size_t>(u)]);
      const double start = (0.1 + r) * kFs + 131.0 * u, alpha = 1.0 + speed[u] / 343.0;
      const double a = u == 0 ? 0.3 : 0.3 * std::pow(10.0, -50.0 / 20.0);
      for (std::size_t n = static_cast<std::size_t>(start) + 1; n < x.size(); ++n) {
        const double t = alpha * (static_cast<double>(n) - start);
        const auto k = static_cast<std::size_t>(t / 40.0);
        if (k >= chips.size()) break;
        x[n] += static_cast<float>(a * (chips[k] ? -1.0 : 1.0) * std::cos(2.0 * M_PI * 19000.0 * t / kFs));
      }
    }
  locus::test::CollectingSink sink;
  std::uint64_t frame = 0;
  std::size_t events = 0;
  for (auto _ : state) {
    for (std::size_t pos = 0; pos + 1024 <= x.size(); pos += 1024) {
      const float* ch = x.data() + pos;
      locus::AudioBlock b;
      b.channel_data = &ch;
      b.channels = 1;
      b.frames = 1024;
      b.first_frame = frame + pos;
      d->process_audio(b, sink);
    }
    frame += (x.size() / 1024) * 1024;
    events += sink.events.size();
    sink.events.clear();
  }
  const double seconds = static_cast<double>((x.size() / 1024) * 1024) / kFs;
  state.counters["x_realtime"] = benchmark::Counter(seconds * static_cast<double>(state.iterations()),
                                                    benchmark::Counter::kIsRate);
  state.counters["events_per_pass"] = static_cast<double>(events) / static_cast<double>(state.iterations());
}

void BM_GoldcodeMontageDevice(benchmark::State& s) { montage_device(s, false); }
void BM_GoldcodeMontageDeviceRoundGate(benchmark::State& s) { montage_device(s, true); }
void BM_GoldcodeMontageDeviceNoDoppler(benchmark::State& s) { montage_device(s, false, false); }
void BM_Goldcode4Codes(benchmark::State& s) { run(s, locus::plugins::goldcode::descriptor(), locus::plugins::goldcode::schema(), true); }
void BM_Multitone10Tones(benchmark::State& s) { run(s, locus::plugins::multitone::descriptor(), locus::plugins::multitone::schema(), false); }
// The same with the carrier cycle from the envelope alone (cycle_choice: envelope): the cost of the
// known-phase cycle choice, measured in the same run.
void BM_Multitone10TonesEnvelopeCycle(benchmark::State& s) {
  run(s, locus::plugins::multitone::descriptor(), locus::plugins::multitone::schema(), false, "envelope");
}

BENCHMARK(BM_Goldcode4Codes)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_GoldcodeMontageDevice)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_GoldcodeMontageDeviceRoundGate)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_GoldcodeMontageDeviceNoDoppler)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Multitone10Tones)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Multitone10TonesEnvelopeCycle)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

BENCHMARK_MAIN();
