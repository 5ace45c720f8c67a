// SpyLoc position update, localizer side (docs/spyloc.md, "Speed"): what the `spyloc` localizer does
// for one beep of a walking user — pair it with its sync, classify its decay features (naive-Bayes
// GMM), and update the dead-reckoning filter bank (12 heading hypotheses) after the step that covers
// it — on synthetic events after a 20 s warm-up walk. The beep's detection is the multitone
// detector's (locus_bench_goldtone BM_Multitone*). Issue 16: a position update < 5 ms of CPU.
#include <benchmark/benchmark.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <vector>

#include "locus/events.hpp"
#include "spyloc/classifier.hpp"
#include "spyloc/spyloc.hpp"
#include "support/spyloc_beacons.hpp"
#include "support/test_host.hpp"

namespace {

using namespace locus;
namespace sp = locus::plugins::spyloc;

struct NullPublisher final : Publisher {
  std::size_t n = 0;
  void publish(const Event&) override { ++n; }
};

/// A walker on a loop around three beacons: an attitude sample every 50 ms, a step every 0.55 s, a
/// sync + beep + decay features every 0.333 s (beacons in turn).
class Walk {
 public:
  Walk(Localizer& loc, const test::SpyLocBeacons& beacons) : loc_(loc), beacons_(beacons) {}
  /// Feeds events up to time t; returns the number of beeps fed.
  int until(double t) {
    int beeps = 0;
    for (; now_ < t; now_ += 0.01) {
      const double phi = 0.3 * now_;  // a slow circle
      if (now_ >= next_att_) {
        Attitude a;
        a.device = DeviceId("W");
        a.t_s = now_;
        a.heading_rad = static_cast<float>(phi + M_PI / 2);
        loc_.on_event(Event{a}, out_);
        next_att_ += 0.05;
      }
      if (now_ >= next_step_) {
        Step s;
        s.device = DeviceId("W");
        s.t_s = now_;
        s.stride_m = 0.66f;
        s.frequency_hz = 1.8f;
        loc_.on_event(Event{s}, out_);
        next_step_ += 0.55;
      }
      if (now_ >= next_beep_) {
        const std::size_t i = static_cast<std::size_t>(beep_++ % 3);
        const auto& a = beacons_.anchors_m[i];
        const double x = 12.0 + 4.0 * std::cos(phi), y = 8.0 + 4.0 * std::sin(phi);
        const double r = std::sqrt(std::pow(x - a[0], 2) + std::pow(y - a[1], 2) + std::pow(1.2 - a[2], 2));
        RadioSync s;
        s.device = DeviceId("W");
        s.t_s = now_;
        s.source = NameTag(test::SpyLocBeacons::id(i));
        loc_.on_event(Event{s}, out_);
        AudioDetection d;
        d.device = DeviceId("W");
        d.sample_rate_hz = 44100.0;
        d.frame = (now_ + 0.05 + r / 343.0) * 44100.0;
        d.template_index = beacons_.mask(i);
        loc_.on_event(Event{d}, out_);
        DecayFeatures f;
        f.device = d.device;
        f.frame = d.frame;
        for (std::size_t q = 0; q < sp::kDecayFeatures; ++q) f.decay_s[q] = static_cast<float>(0.003 * (q + 1));
        loc_.on_event(Event{f}, out_);
        next_beep_ += 0.333;
        ++beeps;
      }
    }
    return beeps;
  }
  double now() const { return now_; }
  std::size_t estimates() const { return out_.n; }

 private:
  Localizer& loc_;
  const test::SpyLocBeacons& beacons_;
  NullPublisher out_;
  double now_ = 0.0, next_att_ = 0.0, next_step_ = 0.55, next_beep_ = 0.2;
  int beep_ = 0;
};

void BM_SpyLocUpdatePerBeep(benchmark::State& state) {
  test::TestHost host;
  const test::SpyLocBeacons beacons;
  // A LoS/NLoS model as `locus train spyloc` writes it (two well-separated classes).
  std::vector<sp::DecayVector> los(40), nlos(40);
  std::mt19937 rng(9);
  std::normal_distribution<double> nz(0.0, 0.002);
  for (auto& v : los)
    for (std::size_t k = 0; k < sp::kDecayFeatures; ++k) v[k] = static_cast<float>(0.003 * (k + 1) + nz(rng));
  for (auto& v : nlos)
    for (std::size_t k = 0; k < sp::kDecayFeatures; ++k) v[k] = static_cast<float>(0.03 * (k + 1) + nz(rng));
  sp::LosClassifier c;
  c.train(los, nlos, 4);
  const std::string model = (std::filesystem::temp_directory_path() / "locus_bench_spyloc_model.yaml").string();
  c.save(model, "bench");
  std::unique_ptr<Localizer> loc(sp::descriptor()->create_localizer());
  Params p = Params::defaults(sp::schema());
  p.set("los_model", model);
  p.set("speed_of_sound_mps", 343.0);
  HostContext ctx{host.log, host.clock, host.fft, host.link, "spyloc", "W", &beacons.geometry};
  loc->configure(p, ctx);
  Walk walk(*loc, beacons);
  walk.until(20.0);  // warm-up: fix, dead reckoning started, hypotheses weighed
  int beeps = 0;
  for (auto _ : state) beeps += walk.until(walk.now() + 1.0);
  state.counters["per_beep"] = benchmark::Counter(static_cast<double>(beeps), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.SetLabel(std::to_string(walk.estimates()) + " estimates");
  std::filesystem::remove(model);
}
BENCHMARK(BM_SpyLocUpdatePerBeep)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
