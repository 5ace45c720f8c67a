// The `chirp` detector on simulated audio with exactly known arrival times.
//
// Signals: each chirp is evaluated in continuous time (dsp::SignalEvaluator, the scene format's closed
// form) at t - delay for a random fractional start frame, so the truth is exact, not a sampled shift.
// SNR (stated per test) = 10 log10(Ps / sigma^2): Ps = mean of s^2 over the chirp's duration (its
// round(duration * fs) samples, fades included), sigma^2 = variance of white Gaussian noise over the
// full band 0..fs/2 (i.i.d. samples). Timing error = detected frame - true start frame, in samples.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "chirp/chirp.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

constexpr double kFs = 44100.0;

dsp::SignalSpec lfm(double f0, double f1, double dur, double fade) {
  dsp::SignalSpec s;
  s.type = "lfm";
  s.f0_hz = f0;
  s.f1_hz = f1;
  s.duration_s = dur;
  s.fade_s = fade;
  return s;
}
const dsp::SignalSpec kTum = lfm(2000, 8000, 0.040, 0.005);    // TUM's tone
const dsp::SignalSpec kAmil = lfm(18000, 22000, 0.050, 0.005); // AMIL's inaudible chirp

/// Mean power of the unit-amplitude chirp over its duration.
double chirp_power(const dsp::SignalSpec& s) {
  const auto v = dsp::render_signal(s, kFs);
  double p = 0;
  for (float x : v) p += double(x) * x;
  return p / double(v.size());
}

struct Emission {
  std::size_t channel = 0;
  double start_frame = 0;  // true (fractional) frame of the chirp's first instant
  double amplitude = 1.0;
  std::size_t tmpl = 0;
};

/// Planar audio: the emissions (continuous-time evaluation at n - start) plus white Gaussian noise.
std::vector<std::vector<float>> render(std::size_t channels, std::size_t frames, const std::vector<dsp::SignalSpec>& specs,
                                       const std::vector<Emission>& ems, double noise_sigma, unsigned seed) {
  std::vector<std::vector<float>> x(channels, std::vector<float>(frames, 0.0f));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  if (noise_sigma > 0)
    for (auto& ch : x)
      for (float& v : ch) v = static_cast<float>(noise_sigma * g(rng));
  std::vector<dsp::SignalEvaluator> evs;
  for (const auto& s : specs) evs.emplace_back(s, kFs);
  for (const Emission& e : ems) {
    const dsp::SignalEvaluator& ev = evs[e.tmpl];
    const auto n0 = static_cast<long long>(std::floor(e.start_frame));
    const auto n1 = static_cast<long long>(std::ceil(e.start_frame + ev.duration_s() * kFs)) + 1;
    for (long long n = std::max(0LL, n0); n <= n1 && n < static_cast<long long>(frames); ++n)
      x[e.channel][static_cast<std::size_t>(n)] +=
          static_cast<float>(e.amplitude * ev.value((static_cast<double>(n) - e.start_frame) / kFs));
  }
  return x;
}

struct Harness {
  explicit Harness(std::uint32_t channels, std::initializer_list<std::pair<std::string, ParamValue>> overrides = {},
                   std::uint32_t max_block = 8192, const DeviceGeometry* geometry = nullptr) {
    det.reset(plugins::chirp::descriptor()->create_detector());
    Params p = Params::defaults(plugins::chirp::schema());
    for (const auto& [k, v] : overrides) p.set(k, v);
    StreamInfo info;
    info.device = "A";
    info.channels = channels;
    info.sample_rate_hz = kFs;
    info.max_block_frames = max_block;
    HostContext ctx{host.log, host.clock, fftw, host.link, "chirp_a", "A", geometry};
    det->configure(info, p, ctx);
  }
  std::vector<AudioDetection> run(const std::vector<std::vector<float>>& planar, std::size_t block,
                                  std::uint64_t first_frame = 0) {
    test::feed_planar(*det, planar, block, sink, first_frame);
    det->finish(sink);
    return sink.detections();
  }
  test::TestHost host;
  FftwPlanner fftw{"", false};
  std::unique_ptr<Detector> det;
  test::CollectingSink sink;
};

struct Stats {
  std::size_t n = 0, missed = 0, extra = 0;
  double mean = 0, rms = 0, maxabs = 0;
};

Stats match(const std::vector<AudioDetection>& dets, const std::vector<Emission>& truth, double tol = 20.0,
            std::uint64_t frame_offset = 0) {
  Stats s;
  std::vector<bool> used(dets.size(), false);
  std::vector<double> errs;
  for (const Emission& e : truth) {
    int best = -1;
    const double t = e.start_frame + static_cast<double>(frame_offset);
    for (std::size_t i = 0; i < dets.size(); ++i)
      if (!used[i] && dets[i].channel == e.channel && dets[i].template_index == e.tmpl &&
          std::abs(dets[i].frame - t) <= tol && (best < 0 || std::abs(dets[i].frame - t) < std::abs(dets[best].frame - t)))
        best = static_cast<int>(i);
    if (best < 0) {
      ++s.missed;
      continue;
    }
    used[best] = true;
    errs.push_back(dets[best].frame - t);
  }
  s.n = errs.size();
  s.extra = dets.size() - s.n;
  for (double e : errs) {
    s.mean += e;
    s.rms += e * e;
    s.maxabs = std::max(s.maxabs, std::abs(e));
  }
  if (s.n) {
    s.mean /= double(s.n);
    s.rms = std::sqrt(s.rms / double(s.n));
  }
  return s;
}

/// Chirps every `period_s` on every channel, random fractional start frames.
std::vector<Emission> periodic(std::size_t channels, double duration_s, double period_s, unsigned seed,
                               double amplitude = 1.0, std::size_t tmpl = 0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Emission> out;
  for (std::size_t c = 0; c < channels; ++c)
    for (double t = 0.05; t + period_s < duration_s; t += period_s)
      out.push_back({c, std::floor(t * kFs + 200.0 * u(rng)) + u(rng), amplitude, tmpl});
  return out;
}

struct AccuracyCase {
  const char* name;
  dsp::SignalSpec spec;
  double snr_db;
  double max_rms;
};

void PrintTo(const AccuracyCase& c, std::ostream* os) { *os << c.name << " at " << c.snr_db << " dB"; }

class ChirpAccuracy : public ::testing::TestWithParam<AccuracyCase> {};

TEST_P(ChirpAccuracy, ArrivalRmsErrorWithinBound) {
  const AccuracyCase& c = GetParam();
  constexpr std::size_t kCh = 4;
  const double dur = 10.0;
  const auto ems = periodic(kCh, dur, 0.2, 77 + static_cast<unsigned>(c.snr_db));
  const double a = 0.3;
  const double sigma = a * std::sqrt(chirp_power(c.spec) / std::pow(10.0, c.snr_db / 10.0));
  std::vector<Emission> scaled = ems;
  for (auto& e : scaled) e.amplitude = a;
  const auto x = render(kCh, static_cast<std::size_t>(dur * kFs), {c.spec}, scaled, sigma, 1234);
  Harness h(kCh, {{"f0_hz", c.spec.f0_hz}, {"f1_hz", c.spec.f1_hz}, {"duration_s", c.spec.duration_s},
                  {"fade_s", c.spec.fade_s}});
  const auto dets = h.run(x, 1024);
  const Stats s = match(dets, scaled);
  double snr_mean = 0, amp_mean = 0;
  for (const auto& d : dets) {
    snr_mean += d.snr_db;
    amp_mean += d.amplitude;
  }
  snr_mean /= std::max<std::size_t>(1, dets.size());
  amp_mean /= std::max<std::size_t>(1, dets.size());
  std::printf("[ chirp    ] %s, %.0f dB SNR: %zu/%zu detected, %zu extra; error mean %+.4f rms %.4f max|e| %.4f samples; "
              "mean snr_db %.1f, mean amplitude %.3f (true %.3f)\n",
              c.name, c.snr_db, s.n, ems.size(), s.extra, s.mean, s.rms, s.maxabs, snr_mean, amp_mean, a);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LE(s.rms, c.max_rms);
  // The amplitude estimate is the received chirp's amplitude relative to the template's.
  EXPECT_NEAR(amp_mean, a, 0.1 * a);
  // Expected envelope SNR for white noise: sum s^2 / (2 sigma^2) (processing gain of the matched filter).
  const double expected_snr = 10.0 * std::log10(a * a * chirp_power(c.spec) * std::round(c.spec.duration_s * kFs) /
                                                (2.0 * sigma * sigma));
  EXPECT_NEAR(snr_mean, expected_snr, 1.5);
}

INSTANTIATE_TEST_SUITE_P(Bands, ChirpAccuracy,
                         ::testing::Values(AccuracyCase{"lfm 2-8 kHz 40 ms", kTum, 20.0, 0.05},
                                           AccuracyCase{"lfm 2-8 kHz 40 ms", kTum, 0.0, 0.5},
                                           AccuracyCase{"lfm 18-22 kHz 50 ms", kAmil, 20.0, 0.05},
                                           AccuracyCase{"lfm 18-22 kHz 50 ms", kAmil, 0.0, 0.5}),
                         [](const auto& info) {
                           return std::string(info.param.spec.f0_hz < 10000 ? "Tum" : "Amil") +
                                  (info.param.snr_db > 10 ? "20dB" : "0dB");
                         });

TEST(ChirpDetector, EnvelopeOnlyRefinementIsWorseThanPhaseAt18To22kHz) {
  // The carrier phase is what makes 0.05 samples possible; the envelope fit alone is much coarser.
  const auto ems = periodic(2, 6.0, 0.2, 5);
  const double sigma = std::sqrt(chirp_power(kAmil) / 100.0);
  const auto x = render(2, static_cast<std::size_t>(6.0 * kFs), {kAmil}, ems, sigma, 99);
  Harness phase(2, {{"f0_hz", 18000.0}, {"f1_hz", 22000.0}, {"duration_s", 0.05}, {"refine", std::string("phase")}});
  Harness gauss(2, {{"f0_hz", 18000.0}, {"f1_hz", 22000.0}, {"duration_s", 0.05}, {"refine", std::string("gaussian")}});
  Harness para(2, {{"f0_hz", 18000.0}, {"f1_hz", 22000.0}, {"duration_s", 0.05}, {"refine", std::string("parabolic")}});
  const Stats sp = match(phase.run(x, 512), ems), sg = match(gauss.run(x, 512), ems), sq = match(para.run(x, 512), ems);
  std::printf("[ chirp    ] 18-22 kHz, 20 dB: rms error phase %.4f, gaussian envelope %.4f, parabolic envelope %.4f samples\n",
              sp.rms, sg.rms, sq.rms);
  EXPECT_EQ(sp.missed + sg.missed + sq.missed, 0u);
  EXPECT_LT(sp.rms, sg.rms);
  EXPECT_LT(sg.rms, 0.5);
  EXPECT_LT(sq.rms, 0.5);
}

// The range-Doppler coupling of a chirp (dsp::doppler_timing_instant_s): a source whose range grows at
// rdot is heard time-scaled, y(t) = s((t - tau0) / (1 + rdot/c)); the phase-timed detector reports the
// start rdot/c * instant late, instant = 0.60 of TUM's up chirp and 0.40 of its down chirp (not the
// envelope's f1/k: +6.9 and -1.7 samples per m/s). TUM's network solve corrects its arrivals by it.
// Beyond ~1.1 m/s the envelope (which picks the carrier cycle) and the phase part by more than half a
// carrier period and the cycle slips (at 1.5 m/s: +13.2 / -5.5 samples instead of +4.4 / +3.3): a
// limit of the detector for fast movers (docs/tum.md, "Limits").
TEST(ChirpDetector, DopplerCouplingIsTheSignalsTimingInstant) {
  constexpr double kC = 343.0;
  const dsp::SignalSpec down = lfm(8000, 2000, 0.040, 0.005);
  for (const dsp::SignalSpec& spec : {kTum, down}) {
    const double instant_s = dsp::doppler_timing_instant_s(spec, kFs);
    for (double rdot : {-0.8, -0.3, 0.3, 0.8}) {
      std::vector<Emission> ems = periodic(1, 4.0, 0.2, 11);
      const double sigma = std::sqrt(chirp_power(spec) / std::pow(10.0, 3.0));  // 30 dB per sample
      std::vector<std::vector<float>> x = render(1, static_cast<std::size_t>(4.0 * kFs), {spec}, {}, sigma, 5);
      const dsp::SignalEvaluator ev(spec, kFs);
      const double scale = 1.0 + rdot / kC;
      for (const Emission& e : ems)
        for (long long n = static_cast<long long>(e.start_frame); n < static_cast<long long>(e.start_frame + 0.05 * kFs); ++n)
          x[0][static_cast<std::size_t>(n)] += static_cast<float>(ev.value((static_cast<double>(n) - e.start_frame) / kFs / scale));
      Harness run(1, {{"f0_hz", spec.f0_hz}, {"f1_hz", spec.f1_hz}, {"duration_s", 0.04}, {"fade_s", 0.005}});
      const Stats st = match(run.run(x, 1024), ems);
      const double predicted = rdot / kC * instant_s * kFs;
      std::printf("[ chirp    ] %.0f->%.0f Hz, rdot %+.1f m/s: mean error %+.3f samples, predicted %+.3f (instant %.4f s)\n",
                  spec.f0_hz, spec.f1_hz, rdot, st.mean, predicted, instant_s);
      EXPECT_EQ(st.missed, 0u);
      EXPECT_NEAR(st.mean, predicted, 0.1) << spec.f0_hz << " Hz, " << rdot << " m/s";
      if (std::abs(rdot) > 0.5) {
        EXPECT_GT(std::abs(st.mean), 1.0) << "the coupling is there to be corrected";
      }
    }
  }
}

TEST(ChirpDetector, LaterStrongerEchoDoesNotHideTheDirectPath) {
  // Direct path at amplitude 0.5, an echo twice as strong 1.2..4 ms later (0.4..1.4 m more path).
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Emission> direct, all;
  for (int i = 0; i < 30; ++i) {
    const double t0 = 0.05 * kFs + i * 0.25 * kFs + 100 * u(rng) + u(rng);
    const double echo_delay = (0.0012 + 0.0028 * u(rng)) * kFs;
    direct.push_back({0, t0, 0.5, 0});
    all.push_back({0, t0, 0.5, 0});
    all.push_back({0, t0 + echo_delay, 1.0, 0});
  }
  const double sigma = 0.5 * std::sqrt(chirp_power(kTum) / 100.0);  // 20 dB for the direct path
  const auto x = render(1, static_cast<std::size_t>(7.7 * kFs), {kTum}, all, sigma, 8);

  Harness earliest(1);
  const Stats s = match(earliest.run(x, 333), direct, 5.0);
  std::printf("[ chirp    ] multipath (direct 0.5, echo 1.0 +1.2..4 ms): %zu/%zu direct paths, %zu extra, rms %.4f samples\n",
              s.n, direct.size(), s.extra, s.rms);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.rms, 0.2);

  // The strongest-peak rule (ratio 1) reports the echoes instead: the test can tell the two apart.
  Harness strongest(1, {{"earliest_ratio", 1.0}});
  const Stats s2 = match(strongest.run(x, 333), direct, 5.0);
  EXPECT_EQ(s2.n, 0u);
}

/// Direct paths (amplitude 1) each followed by one reflection of amplitude in [amp_lo, amp_hi] and a
/// random sign, delayed by [delay_lo, delay_hi] samples, at 18-22 kHz, `snr_db` for the direct path.
Stats reflection_case(double delay_lo, double delay_hi, double amp_lo, double amp_hi, double snr_db, unsigned seed,
                      std::size_t* cycle_slips, double* mean_confidence = nullptr) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Emission> direct, all;
  for (int i = 0; i < 40; ++i) {
    const double t0 = 0.05 * kFs + i * 0.15 * kFs + 100 * u(rng) + u(rng);
    const double a = (amp_lo + (amp_hi - amp_lo) * u(rng)) * (u(rng) < 0.5 ? -1.0 : 1.0);
    direct.push_back({0, t0, 1.0, 0});
    all.push_back({0, t0, 1.0, 0});
    all.push_back({0, t0 + delay_lo + (delay_hi - delay_lo) * u(rng), a, 0});
  }
  const double sigma = std::sqrt(chirp_power(kAmil) / std::pow(10.0, snr_db / 10.0));
  const auto x = render(1, static_cast<std::size_t>(6.2 * kFs), {kAmil}, all, sigma, seed + 100);
  Harness h(1, {{"f0_hz", 18000.0}, {"f1_hz", 22000.0}, {"duration_s", 0.05}});
  const auto dets = h.run(x, 512);
  const Stats s = match(dets, direct, 5.0);
  std::size_t slips = 0;
  double conf = 0;
  for (const auto& d : dets) {
    conf += d.confidence;
    for (const Emission& e : direct)
      if (std::abs(d.frame - e.start_frame) < 5.0 && std::abs(d.frame - e.start_frame) > 1.0) ++slips;
  }
  if (cycle_slips) *cycle_slips = slips;
  if (mean_confidence) *mean_confidence = dets.empty() ? 0.0 : conf / double(dets.size());
  return s;
}

TEST(ChirpDetector, ReflectionsWithinTwoMainlobesDoNotSlipTheCarrierCycle) {
  // A room: side-wall / floor reflections 12-30 samples after the direct path (their mainlobe skirts
  // and first range sidelobes overlap the direct peak), 0.5-0.9 of its amplitude, 40 dB SNR. Without
  // the multipath fit the composite envelope peak moves by > half a carrier cycle (1.1 samples at
  // 20 kHz) and the phase snaps to the neighbouring cycle (errors of +-2.2 samples).
  std::size_t slips = 0;
  double conf = 0;
  const Stats s = reflection_case(12.0, 30.0, 0.5, 0.9, 40.0, 21, &slips, &conf);
  std::printf("[ chirp    ] reflection +12..30 samples, 0.5-0.9, 40 dB: %zu/40 found, %zu slips, rms %.4f max %.3f, conf %.3f\n",
              s.n, slips, s.rms, s.maxabs, conf);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_EQ(slips, 0u);
  EXPECT_LT(s.rms, 0.1);
}

TEST(ChirpDetector, ReflectionsInsideTheMainlobeAreResolvedOrFlagged) {
  // 2-10 samples (inside one mainlobe, fs/B = 11 samples): not fully separable. Measured, bounded:
  // most detections keep the right cycle and a slip costs confidence.
  std::size_t slips = 0;
  double conf = 0;
  const Stats s = reflection_case(2.0, 10.0, 0.5, 0.9, 40.0, 22, &slips, &conf);
  std::printf("[ chirp    ] reflection +2..10 samples, 0.5-0.9, 40 dB: %zu/40 found, %zu slips, rms %.4f max %.3f, conf %.3f\n",
              s.n, slips, s.rms, s.maxabs, conf);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_LE(slips, 4u);
}

TEST(ChirpDetector, SidelobesOfASinglePathAreNotReportedAsEarlierPaths) {
  // One strong path at 40 dB: its range sidelobes cross the threshold well before the mainlobe, but
  // stay under earliest_ratio, so the detection is the mainlobe itself.
  const auto ems = periodic(1, 5.0, 0.25, 11);
  const auto x = render(1, static_cast<std::size_t>(5.0 * kFs), {kTum}, ems, std::sqrt(chirp_power(kTum) / 1e4), 12);
  Harness h(1);
  const Stats s = match(h.run(x, 256), ems, 100.0);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.maxabs, 0.05);
}

TEST(ChirpDetector, BlockAndWindowBoundariesFindEachChirpExactlyOnce) {
  // Chirps placed across the overlap-save window boundaries (multiples of hop) and block boundaries.
  const std::size_t n = 8192, hop = n - static_cast<std::size_t>(std::round(0.04 * kFs)) + 1;  // auto fft size
  std::vector<Emission> ems;
  for (int i = 1; i < 16; ++i) ems.push_back({0, double(i * hop) - 3.0 + 0.37 * i, 1.0, 0});
  for (auto& e : ems) e.start_frame = std::max(e.start_frame, 10.0);
  const auto x = render(1, 16 * hop + 4000, {kTum}, ems, std::sqrt(chirp_power(kTum) / 100.0), 21);
  std::vector<AudioDetection> ref;
  for (std::size_t block : {1u, 7u, 64u, 256u, 1000u, 4096u, 8192u}) {
    Harness h(1, {}, 8192);
    const auto dets = h.run(x, block);
    const Stats s = match(dets, ems);
    EXPECT_EQ(s.missed, 0u) << "block " << block;
    EXPECT_EQ(s.extra, 0u) << "block " << block;
    EXPECT_LT(s.maxabs, 0.1) << "block " << block;
    if (ref.empty()) {
      ref = dets;
    } else {
      ASSERT_EQ(dets.size(), ref.size()) << "block " << block;
      for (std::size_t i = 0; i < dets.size(); ++i) EXPECT_DOUBLE_EQ(dets[i].frame, ref[i].frame) << "block " << block;
    }
  }
}

TEST(ChirpDetector, FramesAreOnTheStreamsFrameCounter) {
  const auto ems = periodic(1, 2.0, 0.3, 4);
  const auto x = render(1, static_cast<std::size_t>(2.0 * kFs), {kTum}, ems, std::sqrt(chirp_power(kTum) / 100.0), 5);
  Harness h(1);
  const std::uint64_t first = 123456789012ull;
  const Stats s = match(h.run(x, 512, first), ems, 20.0, first);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.maxabs, 0.1);
}

TEST(ChirpDetector, MultiChannelDelaysArePerChannel) {
  // Same chirps, different sub-sample delays per microphone (a 4-mic array), one detection each.
  const double delays[4] = {0.0, 3.217, 7.75, 12.031};
  std::vector<Emission> ems;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 20; ++i) {
    const double t0 = 0.05 * kFs + i * 0.2 * kFs + 50 * u(rng) + u(rng);
    for (std::size_t c = 0; c < 4; ++c) ems.push_back({c, t0 + delays[c], 0.2, 0});
  }
  const auto x = render(4, static_cast<std::size_t>(4.3 * kFs), {kTum}, ems, 0.2 * std::sqrt(chirp_power(kTum) / 100.0), 10);
  Harness h(4);
  const auto dets = h.run(x, 480);
  const Stats s = match(dets, ems);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.rms, 0.05);
  // TDoA between channels 0 and 3 per emission.
  for (int i = 0; i < 20; ++i) {
    std::vector<double> f(4, -1);
    for (const auto& d : dets)
      for (std::size_t c = 0; c < 4; ++c)
        if (d.channel == c && std::abs(d.frame - ems[i * 4 + c].start_frame) < 5) f[c] = d.frame;
    EXPECT_NEAR(f[3] - f[0], delays[3] - delays[0], 0.1);
  }
}

TEST(ChirpDetector, SeveralTemplatesAreToldApart) {
  // TUM's two devices use different sweeps (up 2-8 kHz, down 8-2 kHz), possibly overlapping in time.
  const dsp::SignalSpec up = kTum, down = lfm(8000, 2000, 0.040, 0.005);
  std::vector<Emission> ems;
  for (int i = 0; i < 15; ++i) {
    ems.push_back({0, 2205.0 + i * 0.25 * kFs + 0.3, 0.5, 0});
    ems.push_back({0, 2205.0 + i * 0.25 * kFs + 700.61, 0.4, 1});  // overlaps the first by 24 ms
  }
  const auto x = render(1, static_cast<std::size_t>(4.0 * kFs), {up, down}, ems, 0.4 * std::sqrt(chirp_power(kTum) / 100.0), 13);
  Harness h(1, {{"templates", std::vector<double>{2000, 8000, 0.04, 0.005, 8000, 2000, 0.04, 0.005}}});
  const auto dets = h.run(x, 1024);
  const Stats s = match(dets, ems);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.rms, 0.1);
}

TEST(ChirpDetector, TemplatesFromTheScenesLfmSignals) {
  // A listener's config need not repeat the player's beep: with from_scene the detector uses every
  // distinct lfm of the scene (here a TUM sweep and the AMIL beep; duplicates and non-lfm skipped).
  const dsp::SignalSpec amil = lfm(18000, 22000, 0.05, 0.005);
  DeviceGeometry g;
  const std::vector<SceneSignal> scene = {
      {"A", parse_signal(R"({"type":"lfm","f0":2000,"f1":8000,"duration":0.04,"fade":0.005,"amplitude":1})")},
      {"P", parse_signal(R"({"type":"lfm","f0":18000,"f1":22000,"duration":0.05,"fade":0.005,"amplitude":1})")},
      {"Q", parse_signal(R"({"type":"lfm","f0":18000,"f1":22000,"duration":0.05,"fade":0.005,"amplitude":1})")},
      {"T", parse_signal(R"({"type":"ble","address":"AA:BB:CC:DD:EE:FF","tx_power_dbm":-59,"interval_s":0.1})")}};
  g.scene_emits = scene;
  std::vector<Emission> ems;
  for (int i = 0; i < 6; ++i) ems.push_back({0, 3000.0 + i * 0.3 * kFs + 0.37, 0.5, 1});
  const auto x = render(1, static_cast<std::size_t>(2.2 * kFs), {kTum, amil}, ems, 0.5 * std::sqrt(chirp_power(amil) / 100.0), 5);
  Harness from_scene(1, {{"from_scene", true}}, 8192, &g);
  const Stats s = match(from_scene.run(x, 1024), ems);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.rms, 0.05);
  // The same config on a node that knows no scene falls back to f0_hz..fade_s (the 2-8 kHz default),
  // which does not hear the AMIL beep at all.
  Harness no_scene(1, {{"from_scene", true}});
  EXPECT_TRUE(no_scene.run(x, 1024).empty());
}

TEST(ChirpDetector, DigitalSilenceIsNotANoiseFloor) {
  // Exact zeros before and between chirps (a JACK dummy port, a zero-padded file): the FFT's round-off
  // must not be reported, and the first chirp must be found at its frame.
  std::vector<Emission> ems;
  for (int i = 0; i < 3; ++i) ems.push_back({0, 4410.0 + i * 22050.0, 0.5, 0});
  const auto x = render(1, static_cast<std::size_t>(1.5 * kFs), {kTum}, ems, 0.0, 1);
  Harness h(1);
  const Stats s = match(h.run(x, 1024), ems);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u);
  EXPECT_LT(s.maxabs, 0.05);
}

TEST(ChirpDetector, GapResetsStateAndCutChirpIsNotReported) {
  // Frames [0, A) then a gap of G frames (lost), then frames [A+G, ...). A chirp straddles the gap.
  const std::size_t A = 50000, G = 3000, total = 150000;
  std::vector<Emission> ems = {{0, 10000.4, 1.0, 0}, {0, 45000.25, 1.0, 0},  // before the gap (second ends at 46764)
                               {0, A - 800.5, 1.0, 0},                       // cut by the gap
                               {0, 80000.7, 1.0, 0}, {0, 120000.1, 1.0, 0}};
  const auto x = render(1, total, {kTum}, ems, std::sqrt(chirp_power(kTum) / 100.0), 17);
  Harness h(1);
  std::vector<std::vector<float>> part1{std::vector<float>(x[0].begin(), x[0].begin() + A)};
  std::vector<std::vector<float>> part2{std::vector<float>(x[0].begin() + A + G, x[0].end())};
  test::feed_planar(*h.det, part1, 1024, h.sink, 0);
  test::feed_planar(*h.det, part2, 1024, h.sink, A + G, G);
  h.det->finish(h.sink);
  const auto dets = h.sink.detections();
  const std::vector<Emission> expected = {ems[0], ems[1], ems[3], ems[4]};
  const Stats s = match(dets, expected);
  EXPECT_EQ(s.missed, 0u);
  EXPECT_EQ(s.extra, 0u) << "the chirp cut by the gap must not be reported";
  EXPECT_LT(s.maxabs, 0.1);
  // A discontinuous first_frame without lost_before is treated as a gap too.
  Harness h2(1);
  test::feed_planar(*h2.det, part1, 1024, h2.sink, 0);
  test::feed_planar(*h2.det, part2, 1024, h2.sink, A + G, 0);
  h2.det->finish(h2.sink);
  EXPECT_EQ(match(h2.sink.detections(), expected).extra, 0u);
  EXPECT_EQ(match(h2.sink.detections(), expected).missed, 0u);
}

TEST(ChirpDetector, PrescreenSkipsQuietWindowsWithoutChangingDetections) {
  // 20 s of noise with 8 chirps at 0 dB: most windows are skipped, the detections are identical.
  std::vector<Emission> ems;
  for (int i = 0; i < 8; ++i) ems.push_back({0, (1.0 + 2.3 * i) * kFs + 0.123 * i, 1.0, 0});
  const auto x = render(1, static_cast<std::size_t>(20.0 * kFs), {kTum}, ems, std::sqrt(chirp_power(kTum)), 23);
  Harness on(1, {{"prescreen", true}}), off(1, {{"prescreen", false}});
  const auto d_on = on.run(x, 1024), d_off = off.run(x, 1024);
  const Stats s_on = match(d_on, ems), s_off = match(d_off, ems);
  EXPECT_EQ(s_on.missed, 0u);
  EXPECT_EQ(s_on.extra, 0u);
  EXPECT_EQ(s_off.missed, 0u);
  ASSERT_EQ(d_on.size(), d_off.size());
  for (std::size_t i = 0; i < d_on.size(); ++i) EXPECT_DOUBLE_EQ(d_on[i].frame, d_off[i].frame);
  // finish() logs "<w> windows, <s> template correlations skipped by the pre-screen".
  unsigned long windows = 0, skipped = 0;
  for (const auto& e : on.host.log.entries())
    if (std::sscanf(e.message.c_str(), "chirp: %lu windows, %lu template", &windows, &skipped) == 2) break;
  std::printf("[ chirp    ] pre-screen: %lu of %lu windows skipped (8 chirps in 20 s, 0 dB)\n", skipped, windows);
  EXPECT_GT(windows, 100u);
  EXPECT_GT(skipped, windows * 6 / 10);
}

TEST(ChirpDetector, NoFalseAlarmsInNoise) {
  const auto x = render(2, static_cast<std::size_t>(30.0 * kFs), {kTum}, {}, 0.05, 31);
  Harness h(2, {{"prescreen", false}});
  EXPECT_TRUE(h.run(x, 1024).empty());
  // Digital silence neither.
  const std::vector<std::vector<float>> zeros(1, std::vector<float>(static_cast<std::size_t>(3 * kFs), 0.0f));
  Harness z(1);
  EXPECT_TRUE(z.run(zeros, 1024).empty());
}

TEST(ChirpDetector, BadConfigurationsAreClearErrors) {
  auto configure = [](std::initializer_list<std::pair<std::string, ParamValue>> overrides) -> std::string {
    try {
      Harness h(1, overrides);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(configure({{"templates", std::vector<double>{2000, 8000, 0.04}}}).find("quadruples"), std::string::npos);
  EXPECT_NE(configure({{"f1_hz", 30000.0}}).find("Nyquist"), std::string::npos);
  EXPECT_NE(configure({{"f1_hz", 2000.0}}).find("differ"), std::string::npos);
  EXPECT_NE(configure({{"fade_s", 0.03}}).find("fade_s"), std::string::npos);
  EXPECT_NE(configure({{"fft_size", std::int64_t{1000}}}).find("power of two"), std::string::npos);
  EXPECT_NE(configure({{"fft_size", std::int64_t{1024}}}).find("fft_size"), std::string::npos);
}

TEST(ChirpDetector, IsRegisteredAsABuiltin) {
  Registry r;
  register_builtins(r);
  auto d = r.create_detector("chirp");
  ASSERT_NE(d, nullptr);
}

}  // namespace
}  // namespace locus
