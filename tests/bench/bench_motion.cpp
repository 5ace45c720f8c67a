// Throughput of the motion and BLE detector plugins and of the DTW kernel. Each iteration runs one
// plugin instance over a pre-synthesised recording (tests/plugins/steps/walk_sim.hpp: a 105 s mixed
// walk at 100 Hz; 120 s of 10 Hz adverts from 20 tags), so `x_realtime` = seconds of sensor data
// processed per second of CPU: how many devices (or tags) one core could serve.
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>
#include <random>

#include "locus/dsp/dtw.hpp"
#include "locus/registry.hpp"
#include "plugins/steps/walk_sim.hpp"
#include "support/test_host.hpp"

namespace {

using namespace locus;

class CountingSink final : public EventSink {
 public:
  bool emit(const Event&) noexcept override {
    ++count;
    return true;
  }
  std::size_t count = 0;
};

std::unique_ptr<Detector> make(const char* name, test::TestHost& host, const Params& overrides) {
  static Registry* reg = [] {
    auto* r = new Registry();  // lives for the whole benchmark run
    register_builtins(*r);
    return r;
  }();
  const locus_plugin_descriptor* d = reg->find_plugin(name);
  Params p = Params::defaults(*d->schema());
  for (const auto& [k, v] : overrides.values()) p.set(k, v);
  auto det = std::unique_ptr<Detector>(d->create_detector());
  StreamInfo info;
  info.device = "walker";
  HostContext ctx = host.context(name, "walker");
  det->configure(info, p, ctx);
  return det;
}

const std::vector<ImuSample>& walk() {
  static const std::vector<ImuSample> w = [] {
    test::WalkTruth truth;
    test::WalkOptions o;
    o.with_mag = true;
    return test::simulate_walk(test::mixed_walk(), o, truth);
  }();
  return w;
}

void run_imu(benchmark::State& state, const char* plugin, Params p) {
  test::TestHost host;
  const auto& w = walk();
  const double seconds = w.back().t_s - w.front().t_s;
  std::size_t events = 0;
  for (auto _ : state) {
    state.PauseTiming();
    auto det = make(plugin, host, p);
    CountingSink sink;
    state.ResumeTiming();
    for (std::size_t i = 0; i < w.size(); i += 32) det->process_imu(w.data() + i, std::min<std::size_t>(32, w.size() - i), sink);
    events = sink.count;
    benchmark::DoNotOptimize(events);
  }
  state.counters["x_realtime"] = benchmark::Counter(seconds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["samples_per_s"] =
      benchmark::Counter(static_cast<double>(w.size()) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["events"] = static_cast<double>(events);
}

void BM_StepsMontage(benchmark::State& s) {
  Params p;
  p.set("mode", std::string("montage"));
  run_imu(s, "steps", p);
}
void BM_StepsSpyLoc(benchmark::State& s) {
  Params p;
  p.set("mode", std::string("spyloc"));
  run_imu(s, "steps", p);
}
void BM_AttitudeMadgwick(benchmark::State& s) {
  Params p;
  p.set("ahrs", std::string("madgwick"));
  p.set("ahrs_gain", 0.1);
  run_imu(s, "attitude", p);
}
void BM_AttitudeMahony(benchmark::State& s) {
  Params p;
  p.set("ahrs", std::string("mahony"));
  run_imu(s, "attitude", p);
}
void BM_Turns(benchmark::State& s) { run_imu(s, "turns", Params{}); }

void BM_BleRss(benchmark::State& state) {
  test::TestHost host;
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 4.0);
  std::vector<BleAdvertisement> adv;
  const int tags = 20;
  const double duration = 120.0;
  for (double t = 0; t < duration; t += 0.1)
    for (int k = 0; k < tags; ++k) {
      BleAdvertisement a;
      a.t_s = t + 0.001 * k;
      a.address = {1, 2, 3, 4, 5, static_cast<std::uint8_t>(k)};
      a.rssi_dbm = static_cast<float>(-60 - k + noise(rng));
      adv.push_back(a);
    }
  for (auto _ : state) {
    state.PauseTiming();
    auto det = make("ble_rss", host, Params{});
    CountingSink sink;
    state.ResumeTiming();
    for (std::size_t i = 0; i < adv.size(); i += 64) det->process_ble(adv.data() + i, std::min<std::size_t>(64, adv.size() - i), sink);
    benchmark::DoNotOptimize(sink.count);
  }
  // Seconds of the whole 20-tag scan per second; per tag it is `tags` times more.
  state.counters["x_realtime"] = benchmark::Counter(duration * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["adverts_per_s"] =
      benchmark::Counter(static_cast<double>(adv.size()) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_DtwOpenEnd(benchmark::State& state) {
  // SpyLoc's per-window kernel at 100 Hz: a 55-sample template against a 100-sample window.
  std::vector<float> templ(55), x(100);
  for (std::size_t i = 0; i < templ.size(); ++i) templ[i] = static_cast<float>(std::cos(2 * std::numbers::pi * i / 55.0));
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(std::cos(2 * std::numbers::pi * i / 52.0));
  dsp::Dtw dtw(128);
  for (auto _ : state) benchmark::DoNotOptimize(dtw.open_end(templ, x, 25, 100, 10));
  state.SetItemsProcessed(state.iterations());
}

BENCHMARK(BM_StepsMontage)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_StepsSpyLoc)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AttitudeMadgwick)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_AttitudeMahony)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Turns)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BleRss)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_DtwOpenEnd)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
