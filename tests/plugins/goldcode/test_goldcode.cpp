// goldcode detector: four overlapping users at -5 dB per-user SNR, noise only, block-size invariance,
// overruns, bad parameters.
//
// SNR definition used here: per-user SNR = (a_u² / 2) / σ², the mean power of user u's tone over its
// duration divided by the variance of white Gaussian noise over the FULL band 0..fs/2 (not only the
// receiver's band, which would read 10·log10((fs/2) / band_width) ≈ 9.6 dB higher with the defaults).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "goldcode/goldcode.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

constexpr double kFs = 44100.0;

struct Fixture {
  test::TestHost host;
  FftwPlanner fftw{{}, false};
  HostContext ctx() { return HostContext{host.log, host.clock, fftw, host.link, "gold", "A"}; }
};

std::unique_ptr<Detector> make(Fixture& f, const Params& p, std::uint32_t max_block = 1024, std::uint32_t channels = 1,
                               const DeviceGeometry* geometry = nullptr) {
  std::unique_ptr<Detector> d(plugins::goldcode::descriptor()->create_detector());
  StreamInfo info;
  info.device = DeviceId("A");
  info.channels = channels;
  info.sample_rate_hz = kFs;
  info.max_block_frames = max_block;
  HostContext ctx = f.ctx();
  ctx.geometry = geometry;
  d->configure(info, p, ctx);
  return d;
}

dsp::SignalSpec gold(int index) {
  dsp::SignalSpec s;
  s.type = "gold";
  s.degree = 7;
  s.index = index;
  s.carrier_hz = 19000.0;
  s.chip_samples = 40;
  s.amplitude = 1.0;
  return s;
}

// Adds a·s(n − delay) with a band-limited fractional delay: the rendered signal (integer grid)
// interpolated by a Kaiser-windowed sinc (±64 taps). (SignalEvaluator at fractional times holds the
// chips on the sample grid: its chip edges move in whole samples while the carrier moves by the
// fraction, which no physical, band-limited delay does.)
// Device A of a four-user Montage scene: it emits gold(0), the scene's gold emitters A-D emit gold(0..3)
// (the geometry goldcode's from_scene and cancel_own read).
struct MontageDevice {
  std::vector<SignalSpec> mine = {gold(0)};
  std::vector<SceneSignal> scene;
  DeviceGeometry g;
  MontageDevice() {
    for (int u = 0; u < 4; ++u) scene.push_back(SceneSignal{std::string(1, static_cast<char>('A' + u)), gold(u), false, {}});
    g.mic_count = 1;
    g.has_speaker = true;
    g.emits = mine;
    g.scene_emits = scene;
  }
  MontageDevice(const MontageDevice&) = delete;
  MontageDevice& operator=(const MontageDevice&) = delete;
};

void add_signal(std::vector<float>& x, const dsp::SignalSpec& spec, double delay_frames, double a) {
  const std::vector<float> s = dsp::render_signal(spec, kFs);
  const auto base = static_cast<std::int64_t>(std::floor(delay_frames));
  const double frac = delay_frames - static_cast<double>(base);
  constexpr int kHalf = 64;
  const double beta = 8.0;
  auto i0 = [](double v) {
    double sum = 1.0, term = 1.0;
    for (int k = 1; k < 60; ++k) {
      term *= (v / 2) * (v / 2) / (k * k);
      sum += term;
    }
    return sum;
  };
  std::vector<double> h(2 * kHalf + 1);
  for (int j = -kHalf; j <= kHalf; ++j) {
    const double t = j - frac;  // x[base + j'] gets s[k]·h(base + j' − delay − k)
    const double r = t / (kHalf + 1);
    const double w = std::abs(r) < 1 ? i0(beta * std::sqrt(1 - r * r)) / i0(beta) : 0.0;
    h[j + kHalf] = (t == 0.0 ? 1.0 : std::sin(M_PI * t) / (M_PI * t)) * w;
  }
  for (std::size_t k = 0; k < s.size(); ++k)
    for (int j = -kHalf; j <= kHalf; ++j) {
      const std::int64_t n = base + static_cast<std::int64_t>(k) + j;
      if (n >= 0 && n < static_cast<std::int64_t>(x.size())) x[static_cast<std::size_t>(n)] += static_cast<float>(a * s[k] * h[j + kHalf]);
    }
}

struct Result {
  std::vector<AudioDetection> det;
};

Result run(Detector& d, const std::vector<float>& x, std::size_t block) {
  test::CollectingSink sink;
  test::feed_planar(d, {x}, block, sink);
  d.finish(sink);
  return {sink.detections()};
}

TEST(Goldcode, FourOverlappingUsersAllDetectedAtMinus5dB) {
  Fixture f;
  // Codes 0,1,2,3, degree 7, 19 kHz, 40 chips; stationary users: no Doppler search (each Doppler
  // version is one more hypothesis the noise can match; MovingUsersFoundWithDopplerSearch covers it).
  Params p = Params::defaults(plugins::goldcode::schema());
  p.set("doppler_max_hz", 0.0);
  const std::vector<double> amp_rel = {1.0, 0.75, 0.55, 0.4};  // weakest user is at -5 dB
  const double weakest_snr_db = -5.0;
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> offset(0.0, 0.005 * kFs);
  int trials = 30, found = 0, total = 0, spurious = 0;
  double max_err = 0.0, sum_err2 = 0.0;
  for (int trial = 0; trial < trials; ++trial) {
    const double sigma = 0.05;
    const double a_weak = std::sqrt(2.0 * sigma * sigma * std::pow(10.0, weakest_snr_db / 10.0));
    std::vector<float> x(static_cast<std::size_t>(1.2 * kFs));
    std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
    for (float& v : x) v = noise(rng);
    const double t0 = 0.3 * kFs + trial * 17.3;
    std::vector<double> truth(4);
    for (int u = 0; u < 4; ++u) {
      truth[u] = t0 + offset(rng);
      add_signal(x, gold(u), truth[u], a_weak * amp_rel[u] / amp_rel[3]);
    }
    auto d = make(f, p);
    const Result r = run(*d, x, 512);
    std::vector<int> hits(4, 0);
    for (const AudioDetection& det : r.det) {
      ASSERT_LT(det.template_index, 4);
      const double err = det.frame - truth[det.template_index];
      if (std::abs(err) > 40.0) {
        ++spurious;
        continue;
      }
      ++hits[det.template_index];
      max_err = std::max(max_err, std::abs(err));
      sum_err2 += err * err;
      EXPECT_LE(std::abs(err), 1.0) << "trial " << trial << " user " << det.template_index;
      EXPECT_GT(det.confidence, 0.2f);
      EXPECT_GT(det.amplitude, 0.0f);
    }
    for (int u = 0; u < 4; ++u) {
      EXPECT_EQ(hits[u], 1) << "trial " << trial << " user " << u;
      found += hits[u] == 1;
      ++total;
    }
  }
  EXPECT_EQ(spurious, 0);
  EXPECT_EQ(found, total);
  const double rms = std::sqrt(sum_err2 / std::max(found, 1));
  RecordProperty("max_abs_error_frames", std::to_string(max_err));
  RecordProperty("rms_error_frames", std::to_string(rms));
  std::printf("goldcode 4 users, weakest -5 dB: found %d/%d, spurious %d, max |err| %.3f, rms %.3f frames\n",
              found, total, spurious, max_err, rms);
}

// The gold code of `spec` from a source closing in at v m/s (c = 343 m/s): time-compressed by
// alpha = 1 + v/c (carrier and chips), first sample at `start` frames, amplitude a.
void add_moving(std::vector<float>& x, const dsp::SignalSpec& spec, double start, double v, double a) {
  const std::vector<std::uint8_t> chips = dsp::gold_chips(spec);
  const double alpha = 1.0 + v / 343.0;
  for (std::size_t n = static_cast<std::size_t>(std::ceil(start)); n < x.size(); ++n) {
    const double u = alpha * (static_cast<double>(n) - start);
    const auto k = static_cast<std::size_t>(u / spec.chip_samples);
    if (k >= chips.size()) break;
    x[n] += static_cast<float>(a * (chips[k] ? -1.0 : 1.0) * std::cos(2.0 * M_PI * spec.carrier_hz * u / kFs));
  }
}

// Walking users: 19 kHz shifted by up to ±83 Hz (±1.5 m/s), i.e. ~9.6 carrier cycles of phase rotation
// over the 115 ms code, and the chips stretched by up to 22 samples. A correlation with the unshifted
// code loses them; the Doppler search (default ±150 Hz) must find every user within 2 frames.
TEST(Goldcode, MovingUsersFoundWithDopplerSearch) {
  Fixture f;
  const Params p = Params::defaults(plugins::goldcode::schema());
  const std::vector<double> speed = {-1.5, -0.6, 0.7, 1.5};
  std::mt19937 rng(99);
  std::uniform_real_distribution<double> offset(0.0, 0.005 * kFs);
  int found = 0, total = 0, found_plain = 0;
  double max_err = 0.0;
  for (int trial = 0; trial < 6; ++trial) {
    const double sigma = 0.05;
    const double a = std::sqrt(2.0 * sigma * sigma);  // 0 dB per user (full band)
    std::vector<float> x(static_cast<std::size_t>(1.2 * kFs));
    std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma));
    for (float& v : x) v = noise(rng);
    std::vector<double> truth(4);
    for (int u = 0; u < 4; ++u) {
      truth[u] = 0.3 * kFs + trial * 31.7 + offset(rng);
      add_moving(x, gold(u), truth[u], speed[static_cast<std::size_t>(u)] * (trial % 2 ? 1.0 : -1.0), a);
    }
    auto d = make(f, p);
    const Result r = run(*d, x, 1024);
    std::vector<int> hits(4, 0);
    for (const AudioDetection& det : r.det) {
      const double err = det.frame - truth[det.template_index];
      if (std::abs(err) <= 2.0) {
        ++hits[det.template_index];
        max_err = std::max(max_err, std::abs(err));
      }
    }
    for (int u = 0; u < 4; ++u) {
      EXPECT_EQ(hits[u], 1) << "trial " << trial << " user " << u << " speed " << speed[static_cast<std::size_t>(u)];
      found += hits[u] == 1;
      ++total;
    }
    if (trial == 0) {  // the same audio without the Doppler search: the fast users are lost
      Params q = p;
      q.set("doppler_max_hz", 0.0);
      auto d0 = make(f, q);
      for (const AudioDetection& det : run(*d0, x, 1024).det)
        if (std::abs(det.frame - truth[det.template_index]) <= 2.0) ++found_plain;
    }
  }
  EXPECT_LE(found_plain, 2) << "without the Doppler search the ±1.5 m/s users should not be found";
  std::printf("goldcode 4 moving users (±1.5 m/s), 0 dB: found %d/%d within 2 frames, max |err| %.2f; without "
              "Doppler search %d/4 in trial 0\n", found, total, max_err, found_plain);
}

// Own emission 50 dB above three other users (a device hears itself a few cm away), through a short
// speaker-to-mic response (direct path, a 6-sample ringing tap and an echo 150 samples later): with the
// scene geometry the detector cancels it (dsp::EmissionCanceller) and finds the others within 2 frames;
// the own arrival is reported from the canceller's fit.
TEST(Goldcode, CancelsOwnEmissionAndFindsTheOthers) {
  Fixture f;
  const MontageDevice dev;
  Params p = Params::defaults(plugins::goldcode::schema());
  p.set("from_scene", true);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> offset(0.0, 0.004 * kFs);
  int found = 0, total = 0, own_ok = 0, found_uncancelled = 0;
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<float> x(static_cast<std::size_t>(1.5 * kFs));
    std::normal_distribution<float> noise(0.0f, 2e-4f);
    for (float& v : x) v = noise(rng);
    const double own_at = 0.4 * kFs + 13.0 * trial;
    add_signal(x, gold(0), own_at, 0.3);
    add_signal(x, gold(0), own_at + 6.0, -0.09);
    add_signal(x, gold(0), own_at + 150.0, 0.02);
    std::vector<double> truth(4, own_at);
    for (int u = 1; u < 4; ++u) {
      truth[u] = own_at + offset(rng);
      add_signal(x, gold(u), truth[u], 0.3 * std::pow(10.0, -50.0 / 20.0));
    }
    for (int cancel = 1; cancel >= 0; --cancel) {
      if (!cancel && trial > 0) break;
      Params q = p;
      q.set("cancel_own", cancel == 1);
      auto d = make(f, q, 1024, 1, &dev.g);
      const Result r = run(*d, x, 1024);
      std::vector<int> hits(4, 0);
      for (const AudioDetection& det : r.det)
        if (std::abs(det.frame - truth[det.template_index]) <= (det.template_index == 0 ? 1.0 : 2.0))
          ++hits[det.template_index];
      if (cancel) {
        own_ok += hits[0] == 1;
        for (int u = 1; u < 4; ++u) {
          EXPECT_EQ(hits[u], 1) << "trial " << trial << " user " << u;
          found += hits[u] == 1;
          ++total;
        }
      } else {
        for (int u = 1; u < 4; ++u) found_uncancelled += hits[u] == 1;
      }
    }
  }
  EXPECT_EQ(own_ok, 4);
  EXPECT_LE(found_uncancelled, 1) << "without cancellation the others should be buried under the own code";
  std::printf("goldcode own code +50 dB: others found %d/%d within 2 frames (without cancellation %d/3), own %d/4\n",
              found, total, found_uncancelled, own_ok);
}

// Round gate (round_window_s): three rounds of a Montage device (own code +50 dB, cancelled); in each,
// the other users arrive within the window around the own emission and are found; the same codes
// played between rounds, far outside every window (a replayed tone, a stray emitter), are found
// without the gate and not with it. A gate without an own emission to place the rounds is refused.
TEST(Goldcode, RoundGateSearchesOnlyAroundTheOwnEmissions) {
  Fixture f;
  const MontageDevice dev;
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 2e-4f);
  std::vector<float> x(static_cast<std::size_t>(3.6 * kFs));
  for (float& v : x) v = noise(rng);
  std::vector<std::vector<double>> inside(4), outside(4);
  for (int r = 0; r < 3; ++r) {
    const double own_at = (0.3 + 1.0 * r) * kFs;
    add_signal(x, gold(0), own_at, 0.3);
    for (int u = 1; u < 4; ++u) {
      const double at = own_at + (r == 1 ? -0.04 : 0.03 * u) * kFs;  // before and after the own emission
      add_signal(x, gold(u), at, 0.3 * std::pow(10.0, -40.0 / 20.0));
      inside[u].push_back(at);
      if (r < 2) {
        const double stray = own_at + (0.5 + 0.05 * u) * kFs;  // between rounds
        add_signal(x, gold(u), stray, 0.3 * std::pow(10.0, -40.0 / 20.0));
        outside[u].push_back(stray);
      }
    }
  }
  auto count = [&](const Result& res, const std::vector<std::vector<double>>& where) {
    int n = 0;
    for (const AudioDetection& det : res.det)
      for (double t : where[det.template_index]) n += std::abs(det.frame - t) <= 2.0;
    return n;
  };
  int found[2] = {0, 0}, stray[2] = {0, 0};
  for (int gate = 0; gate < 2; ++gate) {
    Params p = Params::defaults(plugins::goldcode::schema());
    p.set("from_scene", true);
    if (gate) p.set("round_window_s", std::vector<double>{0.06, 0.14});
    auto d = make(f, p, 1024, 1, &dev.g);
    const Result res = run(*d, x, 1024);
    found[gate] = count(res, inside);
    stray[gate] = count(res, outside);
  }
  EXPECT_EQ(found[1], 9) << "every other user inside the rounds' windows";
  EXPECT_EQ(stray[1], 0) << "nothing outside the windows";
  EXPECT_EQ(stray[0], 6) << "without the gate the stray codes are found (the test's control)";
  std::printf("goldcode round gate: in-window users %d/9 (ungated %d/9), stray codes %d/6 (ungated %d/6)\n", found[1],
              found[0], stray[1], stray[0]);

  // No own emission to place the rounds: refused at configure time with the parameter's name.
  Params p = Params::defaults(plugins::goldcode::schema());
  p.set("round_window_s", std::vector<double>{0.06, 0.14});
  try {
    make(f, p);
    ADD_FAILURE() << "round_window_s without an own emission was accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("round_window_s"), std::string::npos) << e.what();
  }
  p.set("round_window_s", std::vector<double>{0.06});
  EXPECT_THROW(make(f, p), std::exception);
}

TEST(Goldcode, AmplitudeEstimateAndNoiseOnlyIsQuiet) {
  Fixture f;
  const Params p = Params::defaults(plugins::goldcode::schema());
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.1f);
  std::vector<float> x(static_cast<std::size_t>(6.0 * kFs));
  for (float& v : x) v = noise(rng);
  auto d = make(f, p);
  EXPECT_TRUE(run(*d, x, 1024).det.empty()) << "false detections on 6 s of noise";
  // A clean code: amplitude estimate close to the emitted amplitude, high Pearson.
  std::vector<float> y(static_cast<std::size_t>(0.8 * kFs), 0.0f);
  std::normal_distribution<float> small(0.0f, 0.01f);
  for (float& v : y) v = small(rng);
  add_signal(y, gold(2), 10000.25, 0.3);
  auto d2 = make(f, p);
  const Result r = run(*d2, y, 1024);
  ASSERT_EQ(r.det.size(), 1u);
  EXPECT_EQ(r.det[0].template_index, 2);
  EXPECT_NEAR(r.det[0].frame, 10000.25, 0.3);
  EXPECT_NEAR(r.det[0].amplitude, 0.3, 0.03);
  EXPECT_GT(r.det[0].confidence, 0.9f);
}

TEST(Goldcode, BlockSizeDoesNotChangeResults) {
  Fixture f;
  const Params p = Params::defaults(plugins::goldcode::schema());
  std::mt19937 rng(99);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<float> x(static_cast<std::size_t>(1.0 * kFs));
  for (float& v : x) v = noise(rng);
  add_signal(x, gold(0), 5000.0, 0.1);
  add_signal(x, gold(3), 5100.5, 0.05);
  auto a = make(f, p, 1024);
  auto b = make(f, p, 1024);
  const Result ra = run(*a, x, 1024), rb = run(*b, x, 37);
  ASSERT_EQ(ra.det.size(), 2u);
  ASSERT_EQ(ra.det.size(), rb.det.size());
  for (std::size_t i = 0; i < ra.det.size(); ++i) {
    EXPECT_EQ(ra.det[i].template_index, rb.det[i].template_index);
    EXPECT_NEAR(ra.det[i].frame, rb.det[i].frame, 1e-6);
  }
}

TEST(Goldcode, RecoversAfterOverrunAndKeepsStreamFrames) {
  Fixture f;
  const Params p = Params::defaults(plugins::goldcode::schema());
  std::vector<float> x(static_cast<std::size_t>(0.8 * kFs), 0.0f);
  add_signal(x, gold(1), 12000.0, 0.2);
  auto d = make(f, p);
  test::CollectingSink sink;
  // The stream starts at frame 1'000'000 after a reported overrun.
  test::feed_planar(*d, {x}, 256, sink, 1'000'000, 5000);
  d->finish(sink);
  const auto det = sink.detections();
  ASSERT_EQ(det.size(), 1u);
  EXPECT_NEAR(det[0].frame, 1'012'000.0, 0.5);
  EXPECT_EQ(det[0].template_index, 1);
}

TEST(Goldcode, RejectsBadParameters) {
  Fixture f;
  Params p = Params::defaults(plugins::goldcode::schema());
  p.set("codes", std::vector<double>{0.0, 300.0});
  try {
    make(f, p);
    FAIL() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("code index 300"), std::string::npos) << e.what();
  }
  Params q = Params::defaults(plugins::goldcode::schema());
  q.set("carrier_hz", 21500.0);
  q.set("band_width_hz", 2000.0);
  EXPECT_THROW(make(f, q), std::runtime_error);
}

}  // namespace
}  // namespace locus
