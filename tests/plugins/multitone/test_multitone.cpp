// multitone detector: beacon identity from the MAC bits, arrival accuracy at stated SNRs, decay
// features monotone and longer with more reverberation, decay_times on exact envelopes.
//
// SNR here: beep power (a²/2 · (1/K) for K equal tones of total amplitude a: each tone has amplitude
// a/K, the beep's mean power is K·(a/K)²/2 = a²/(2K)) over the variance of white noise over the full
// band 0..fs/2.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "locus/dsp/signals.hpp"
#include "locus/fftw_planner.hpp"
#include "multitone/multitone.hpp"
#include "support/test_host.hpp"

namespace locus {
namespace {

constexpr double kFs = 44100.0;

struct Fixture {
  test::TestHost host;
  FftwPlanner fftw{{}, false};
};

std::unique_ptr<Detector> make(Fixture& f, const Params& p) {
  std::unique_ptr<Detector> d(plugins::multitone::descriptor()->create_detector());
  StreamInfo info;
  info.device = DeviceId("U");
  info.channels = 1;
  info.sample_rate_hz = kFs;
  info.max_block_frames = 1024;
  HostContext ctx{f.host.log, f.host.clock, f.fftw, f.host.link, "beep", "U"};
  d->configure(info, p, ctx);
  return d;
}

std::vector<double> tones_of(std::uint32_t mask) {
  std::vector<double> t;
  for (int k = 0; k < 10; ++k)
    if (mask & (1u << k)) t.push_back(18000.0 + 250.0 * k);
  return t;
}

// MAC C4:2C:03:3A:2C:A1 → low ten bits 0b0010100001 → tones f0, f5, f7 (the paper's example).
std::uint32_t mac_bits(const std::array<std::uint8_t, 6>& mac) { return ((mac[4] << 8) | mac[5]) & 0x3FFu; }

void add_beep(std::vector<float>& x, std::uint32_t mask, double delay, double a) {
  dsp::SignalSpec s;
  s.type = "multitone";
  s.tones_hz = tones_of(mask);
  s.duration_s = 0.05;
  s.fade_s = 0.005;
  s.amplitude = a;
  dsp::SignalEvaluator ev(s, kFs);
  const auto first = static_cast<std::size_t>(std::floor(delay));
  for (std::size_t n = first; n < std::min(x.size(), first + static_cast<std::size_t>(0.05 * kFs) + 2); ++n)
    x[n] += static_cast<float>(ev.value((static_cast<double>(n) - delay) / kFs));
}

struct Out {
  std::vector<AudioDetection> det;
  std::vector<DecayFeatures> feat;
};

Out run(Detector& d, const std::vector<float>& x) {
  test::CollectingSink sink;
  test::feed_planar(d, {x}, 1024, sink);
  d.finish(sink);
  Out o;
  for (const Event& e : sink.events) {
    if (const auto* a = std::get_if<AudioDetection>(&e)) o.det.push_back(*a);
    if (const auto* b = std::get_if<DecayFeatures>(&e)) o.feat.push_back(*b);
  }
  return o;
}

// Three beacons' identities (a SpyLoc scene's candidates) and the default parameters with them.
constexpr std::uint32_t kThreeIds[3] = {0b1100010001u, 0b1111010010u, 0b1010111100u};
Params with_three_identities() {
  Params p = Params::defaults(plugins::multitone::schema());
  p.set("identities", std::vector<double>{double(kThreeIds[0]), double(kThreeIds[1]), double(kThreeIds[2])});
  return p;
}

// Per true beep, the smallest |error| (samples) of a detection with its identity; 1e9 when none.
std::vector<double> best_errors(const Out& o, const std::vector<double>& truth, const std::vector<std::uint32_t>& masks) {
  std::vector<double> err(truth.size(), 1e9);
  for (std::size_t i = 0; i < truth.size(); ++i)
    for (const AudioDetection& a : o.det)
      if (a.template_index == masks[i]) err[i] = std::min(err[i], std::abs(a.frame - truth[i]));
  return err;
}

TEST(Multitone, MacBitsOfThePaperExample) {
  EXPECT_EQ(mac_bits({0xC4, 0x2C, 0x03, 0x3A, 0x2C, 0xA1}), 0b0010100001u);
}

// The first path comes from the beep's onset (its first 3 ms, the fade-in: ~1 % of its energy), not
// from a full-length matched filter (useless under Doppler and a 4 ms-periodic envelope): the
// arrival needs in-band SNR. Bars per SNR (16 random identities each): identities all right at every
// SNR; arrival within 2 samples for all at +20 dB, for >= 12 at +10 dB (the misses are 4 ms-grid
// envelope lobes, ~20 samples off); at 0 dB (the old full-length
// matched filter's regime) only the identity is asked for.
TEST(Multitone, IdentityAndArrivalAtStatedSnrs) {
  Fixture f;
  const Params p = Params::defaults(plugins::multitone::schema());
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> id(1, 1023);
  for (double snr_db : {20.0, 10.0, 0.0}) {
    int ok = 0, id_ok = 0, n = 0;
    double max_err = 0.0, sum2 = 0.0;
    for (int trial = 0; trial < 16; ++trial) {
      std::uint32_t mask = trial == 0 ? mac_bits({0xC4, 0x2C, 0x03, 0x3A, 0x2C, 0xA1}) : static_cast<std::uint32_t>(id(rng));
      const int k = std::popcount(mask);
      const double a = 0.5;
      const double sigma = std::sqrt(a * a / (2.0 * k) / std::pow(10.0, snr_db / 10.0));
      std::vector<float> x(static_cast<std::size_t>(0.6 * kFs));
      std::normal_distribution<float> g(0.0f, static_cast<float>(sigma));
      for (float& v : x) v = g(rng);
      const double truth = 0.2 * kFs + trial * 13.37;
      add_beep(x, mask, truth, a);
      auto d = make(f, p);
      const Out o = run(*d, x);
      ++n;
      ASSERT_EQ(o.det.size(), 1u) << "snr " << snr_db << " trial " << trial;
      ASSERT_EQ(o.feat.size(), 1u);
      id_ok += o.det[0].template_index == mask;
      if (o.det[0].template_index != mask) std::printf("  snr %+.0f trial %d: identity %u, emitted %u\n", snr_db, trial, o.det[0].template_index, mask);
      const double err = o.det[0].frame - truth;
      max_err = std::max(max_err, std::abs(err));
      sum2 += err * err;
      // within 1 sample (a lone tone has no envelope to choose its carrier cycle: 30)
      if (o.det[0].template_index == mask && std::abs(err) <= (k >= 2 ? 1.0 : 30.0)) ++ok;
      EXPECT_EQ(o.feat[0].frame, o.det[0].frame);
    }
    std::printf("multitone SNR %+.0f dB: %d/%d identity, %d/%d identity+arrival ok, max |err| %.2f, rms %.2f frames\n",
                snr_db, id_ok, n, ok, n, max_err, std::sqrt(sum2 / n));
    EXPECT_EQ(id_ok, n) << "snr " << snr_db;
    if (snr_db >= 20.0) {
      EXPECT_EQ(ok, n) << "snr " << snr_db;
      EXPECT_LT(max_err, 0.25) << "snr " << snr_db;  // carrier phase: measured 0.00
    } else if (snr_db >= 10.0) {
      EXPECT_GE(ok, n - 3) << "snr " << snr_db;  // measured 14/16 (single-path fit: 4/16)
    }
  }
}

TEST(Multitone, NoiseOnlyIsQuiet) {
  Fixture f;
  auto d = make(f, Params::defaults(plugins::multitone::schema()));
  std::mt19937 rng(3);
  std::normal_distribution<float> g(0.0f, 0.05f);
  std::vector<float> x(static_cast<std::size_t>(5.0 * kFs));
  for (float& v : x) v = g(rng);
  EXPECT_TRUE(run(*d, x).det.empty());
}

// Beep + a diffuse reverberant tail: the beep convolved with exponentially decaying noise of
// reverberation time rt60 (energy −60 dB after rt60).
std::vector<float> reverberant(double rt60, std::uint32_t mask, double at, std::mt19937& rng) {
  std::vector<float> dry(static_cast<std::size_t>(0.7 * kFs), 0.0f);
  add_beep(dry, mask, at, 0.5);
  const std::size_t ir_len = static_cast<std::size_t>(std::min(0.25, rt60) * kFs);
  std::vector<float> ir(ir_len);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const double decay = 3.0 * std::log(10.0) / (rt60 * kFs);  // amplitude e-folding per sample
  for (std::size_t i = 0; i < ir_len; ++i) ir[i] = static_cast<float>(0.02 * g(rng) * std::exp(-decay * i));
  std::vector<float> y(dry);
  const std::size_t start = static_cast<std::size_t>(at), end = start + static_cast<std::size_t>(0.05 * kFs) + 2;
  for (std::size_t n = start; n < end; ++n)
    for (std::size_t i = 0; i < ir_len && n + i + 40 < y.size(); ++i) y[n + i + 40] += dry[n] * ir[i];
  std::normal_distribution<float> noise(0.0f, 1e-4f);
  for (float& v : y) v += noise(rng);
  return y;
}

TEST(Multitone, DecayFeaturesMonotoneAndLongerWithMoreReverberation) {
  Fixture f;
  Params p = Params::defaults(plugins::multitone::schema());
  p.set("tail_s", 0.3);
  std::mt19937 rng(5);
  std::vector<std::array<float, 6>> feats;
  for (double rt60 : {0.1, 0.3, 0.6}) {
    auto d = make(f, p);
    const Out o = run(*d, reverberant(rt60, 0b0010100001, 0.2 * kFs, rng));
    ASSERT_EQ(o.feat.size(), 1u) << rt60;
    const auto& t = o.feat[0].decay_s;
    std::printf("rt60 %.1f s: T5..T30 =", rt60);
    for (float v : t) std::printf(" %.4f", v);
    std::printf(" s, margin %.1f dB\n", o.feat[0].noise_margin_db);
    for (int k = 0; k < 6; ++k) ASSERT_TRUE(std::isfinite(t[k])) << "rt60 " << rt60 << " T" << 5 * (k + 1);
    for (int k = 1; k < 6; ++k) EXPECT_GE(t[k], t[k - 1]);
    feats.push_back(t);
  }
  for (std::size_t r = 1; r < feats.size(); ++r)
    for (int k = 2; k < 6; ++k) EXPECT_GT(feats[r][k], feats[r - 1][k]) << "rt60 step " << r << " T" << 5 * (k + 1);
}

TEST(DecayTimes, ExactOnAnExponentialEnvelope) {
  // Energy flat at 1 for 100 samples, then −60 dB per 1000 samples: x dB is reached x/60·1000 after.
  std::vector<double> e(3000);
  for (std::size_t i = 0; i < e.size(); ++i) e[i] = i < 100 ? 1.0 : std::pow(10.0, -6.0 * (i - 100) / 1000.0);
  const auto t = plugins::multitone::decay_times(e, 0, 100, 100, 1000.0);
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(t[k], 5.0 * (k + 1) / 60.0, 1.5e-3) << k;
  std::vector<double> shallow(200, 1.0);
  for (std::size_t i = 100; i < 200; ++i) shallow[i] = 0.5;  // only −3 dB: nothing reached
  for (float v : plugins::multitone::decay_times(shallow, 0, 100, 100, 1000.0)) EXPECT_TRUE(std::isnan(v));
}

// SpyLoc's schedule (issue 16): beacons beep in turn every 0.25-0.35 s, each beep on top of the
// previous one's reverberant tail; every beep must be opened, with its identity and its first path.
TEST(Multitone, CloseSuccessiveBeepsAllFound) {
  Fixture f;
  Params p = Params::defaults(plugins::multitone::schema());
  std::mt19937 rng(11);
  const std::uint32_t ids[3] = {0b1100010001u, 0b1111010010u, 0b1010111100u};
  std::vector<float> x(static_cast<std::size_t>(4.0 * kFs), 0.0f);
  std::vector<double> truth;
  std::vector<std::uint32_t> masks;
  double t = 0.3 * kFs;
  std::uniform_real_distribution<double> gap(0.25, 0.35);
  for (int i = 0; t < x.size() - 0.4 * kFs; ++i) {
    add_beep(x, ids[i % 3], t, 0.3);
    // Tail: a decaying echo train after each beep (RT60 0.3 s, 30 echoes 2..80 ms later).
    std::uniform_real_distribution<double> d(0.002 * kFs, 0.08 * kFs);
    for (int e = 0; e < 30; ++e) {
      const double at = t + d(rng);
      add_beep(x, ids[i % 3], at, 0.3 * 0.5 * std::exp(-6.9 * (at - t) / kFs / 0.3));
    }
    truth.push_back(t);
    masks.push_back(ids[i % 3]);
    t += gap(rng) * kFs + 0.37;
  }
  std::normal_distribution<float> g(0.0f, 1e-4f);
  for (float& v : x) v += g(rng);
  auto d = make(f, p);
  const Out o = run(*d, x);
  int found = 0, within1 = 0;
  for (std::size_t i = 0; i < truth.size(); ++i)
    for (const AudioDetection& a : o.det)
      if (std::abs(a.frame - truth[i]) < 0.03 * kFs) {
        found += a.template_index == masks[i];
        within1 += a.template_index == masks[i] && std::abs(a.frame - truth[i]) <= 1.0;
      }
  std::printf("close beeps: %zu beeps, %zu detections, %d found with identity, %d within 1 sample\n", truth.size(),
              o.det.size(), found, within1);
  EXPECT_EQ(found, static_cast<int>(truth.size()));
  EXPECT_EQ(o.det.size(), truth.size());
  EXPECT_GE(within1, static_cast<int>(truth.size()) - 1);
}

// An interferer's blip (5 ms of white noise, ~14 dB over the floor in the tone band) 30 ms before
// each beep opens a body that goes quiet at once. The beep must still open its own body (spyloc-104
// lost two LoS beeps, 15 and 33 dB over the floor, behind babble blips 2000 samples earlier: a new
// body could open only a beep's length after the last one), and its leading edge must not be the
// blip's, which lies in the search window (a first path needs the beep's energy after it).
TEST(Multitone, BeepRightAfterANoiseBlipIsFound) {
  Fixture f;
  const std::uint32_t* ids = kThreeIds;
  const Params p = with_three_identities();
  std::mt19937 rng(5);
  std::vector<float> x(static_cast<std::size_t>(4.0 * kFs), 0.0f);
  std::normal_distribution<float> blip(0.0f, 5e-4f), g(0.0f, 1e-4f);
  std::vector<double> truth;
  std::vector<std::uint32_t> masks;
  for (int i = 0; i < 9; ++i) {
    const double t = (0.35 + 0.4 * i) * kFs;
    const auto b0 = static_cast<std::size_t>(t - 1300.0);
    for (std::size_t n = b0; n < b0 + static_cast<std::size_t>(0.005 * kFs); ++n) x[n] += blip(rng);
    add_beep(x, ids[i % 3], t, 0.05);
    truth.push_back(t);
    masks.push_back(ids[i % 3]);
  }
  for (float& v : x) v += g(rng);
  auto d = make(f, p);
  const Out o = run(*d, x);
  int found = 0, within1 = 0;
  for (double e : best_errors(o, truth, masks)) {
    found += e < 0.03 * kFs;
    within1 += e <= 1.0;
  }
  std::printf("beeps after blips: %zu beeps, %zu detections, %d found with identity, %d within 1 sample\n", truth.size(),
              o.det.size(), found, within1);
  EXPECT_EQ(found, static_cast<int>(truth.size()));
  EXPECT_EQ(within1, static_cast<int>(truth.size()));
  // Some blips pass for a beep of their own (their weak tones fit a candidate): not more than one each.
  EXPECT_LE(o.det.size(), 2 * truth.size());
}

// An interferer's burst (babble, music: energy up to 20 kHz) keeps every tone of the set active for
// seconds: bodies open on the burst back to back, and a beep falls into one that opened up to a beep's
// length before it (its identity, a median over the body, is mostly burst) or into one the burst
// opened during the beep. On the simulator with babble and music bursts (bursts=mixed, 6 per minute)
// 5 % of LoS beeps were lost that way, 15-30 dB over the burst in their own tones. Here: 16 beeps of
// three identities 0.25-0.35 s apart; a babble-like burst (white, its level modulated at 4 Hz like
// syllables, ~25 dB under the beeps per tone at its loudest) starts 25 ms into beep 2 and covers
// beeps 3-12 (2.8 s). Every beep must be found with its identity; timed within 2 samples all but
// one. The detector before this (2026-11-29) found 12 of 16 (burst sigma 0.003 / 0.005 / 0.008:
// 13 / 12 / 12; now 16 / 16 / 16, within 2 samples 16 / 15 / 14).
TEST(Multitone, BeepsInsideAnInterferersBurstAreFound) {
  Fixture f;
  const std::uint32_t* ids = kThreeIds;
  const Params p = with_three_identities();
  std::mt19937 rng(11);
  std::vector<float> x(static_cast<std::size_t>(5.5 * kFs), 0.0f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  std::vector<double> truth;
  std::vector<std::uint32_t> masks;
  std::uniform_real_distribution<double> gap(0.25, 0.35);
  double t = 0.35 * kFs;
  for (int i = 0; i < 16; ++i) {
    add_beep(x, ids[i % 3], t, 0.05);
    truth.push_back(t);
    masks.push_back(ids[i % 3]);
    t += gap(rng) * kFs;
  }
  // Babble-like: syllables (a 4 Hz rectified modulation with a random phase per 0.25 s) over a floor.
  const double b0 = truth[2] + 0.025 * kFs, b1 = truth[12] + 0.2 * kFs, ramp = 0.02 * kFs;
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  double ph = phase(rng);
  for (std::size_t n = 0; n < x.size(); ++n) {
    const double u = static_cast<double>(n);
    if (n % 11025 == 0) ph = phase(rng);
    const double env = std::clamp(std::min(u - b0, b1 - u) / ramp, 0.0, 1.0) *
                       (0.3 + 0.7 * std::fabs(std::sin(2.0 * std::numbers::pi * 4.0 * u / kFs + ph)));
    x[n] += 1e-4f * g(rng) + static_cast<float>(0.005 * env) * g(rng);
  }
  auto d = make(f, p);
  const Out o = run(*d, x);
  int found = 0, within2 = 0;
  const std::vector<double> err = best_errors(o, truth, masks);
  for (std::size_t i = 0; i < err.size(); ++i) {
    found += err[i] < 0.03 * kFs;
    within2 += err[i] <= 2.0;
    std::printf("beep %zu (%s): error %.2f samples\n", i, i >= 3 && i <= 12 ? "in the burst" : (i == 2 ? "burst starts in it" : "quiet"),
                err[i]);
  }
  std::printf("beeps in a burst: %zu beeps, %zu detections, %d found with identity, %d within 2 samples\n", truth.size(),
              o.det.size(), found, within2);
  EXPECT_EQ(found, static_cast<int>(truth.size()));
  EXPECT_GE(within2, static_cast<int>(truth.size()) - 1);
  EXPECT_LE(o.det.size(), truth.size() + 2);  // the burst itself is not a beep
}

// A live stream that starts before its source is connected (JACK delivers zeros until the room's
// port is linked): the floors must not learn that digital silence. They did, sat at 0, and with the
// burst handling's clipped learning (+6 dB per hop-time-constant) never caught up: a live walker under
// load found 19 of 39 beeps. Here: 1.5 s of exact zeros, then noise and 8 beeps (a long activity
// follows the silence: every tone is "on" against a zero floor).
TEST(Multitone, DigitalSilenceBeforeTheSourceIsNotANoiseFloor) {
  Fixture f;
  const std::uint32_t* ids = kThreeIds;
  const Params p = with_three_identities();
  std::mt19937 rng(3);
  const double start = 1.5 * kFs;
  std::vector<float> x(static_cast<std::size_t>(start + 3.0 * kFs), 0.0f);
  std::normal_distribution<float> g(0.0f, 1e-4f);
  for (std::size_t n = static_cast<std::size_t>(start); n < x.size(); ++n) x[n] = g(rng);
  std::vector<double> truth;
  std::vector<std::uint32_t> masks;
  for (int i = 0; i < 8; ++i) {
    const double t = start + (0.3 + 0.33 * i) * kFs;
    add_beep(x, ids[i % 3], t, 0.05);
    truth.push_back(t);
    masks.push_back(ids[i % 3]);
  }
  auto d = make(f, p);
  const Out o = run(*d, x);
  int found = 0;
  for (double e : best_errors(o, truth, masks)) found += e <= 2.0;
  std::printf("after digital silence: %zu beeps, %zu detections, %d found within 2 samples\n", truth.size(), o.det.size(), found);
  EXPECT_EQ(found, static_cast<int>(truth.size()));
}

// NLoS: the first path is diffracted, 25 dB under a reflection 2.5 ms later; the detector must
// report the weak first path (it clears the noise), not the strong echo.
TEST(Multitone, WeakFirstPathBeforeStrongEcho) {
  Fixture f;
  Params p = Params::defaults(plugins::multitone::schema());
  std::mt19937 rng(12);
  int ok = 0;
  for (int trial = 0; trial < 8; ++trial) {
    std::vector<float> x(static_cast<std::size_t>(0.6 * kFs), 0.0f);
    const double first = 0.2 * kFs + 7.31 * trial;
    add_beep(x, 0b0110010011u, first, 0.5 * std::pow(10.0, -25.0 / 20.0));
    add_beep(x, 0b0110010011u, first + 0.0025 * kFs, 0.5);
    add_beep(x, 0b0110010011u, first + 0.0061 * kFs, 0.3);
    std::normal_distribution<float> g(0.0f, 2e-5f);
    for (float& v : x) v += g(rng);
    auto d = make(f, p);
    const Out o = run(*d, x);
    ASSERT_EQ(o.det.size(), 1u) << trial;
    EXPECT_EQ(o.det[0].template_index, 0b0110010011u);
    const double err = o.det[0].frame - first;
    std::printf("weak first path trial %d: error %.2f samples\n", trial, err);
    ok += std::abs(err) <= 1.0;
  }
  EXPECT_GE(ok, 7);  // measured 8/8 within 0.01 (the single-path fit: +2.0..+2.9)
}

// Issue 16's failure mode: indoors the floor or ceiling image arrives 30-60 samples after the direct
// path, only 2-3 dB weaker, while the direct path's fade-in (5 ms) is still rising; at a modest SNR a
// single-path onset fit was pulled towards it (on simulated walks up to the echo's delay) or biased
// by a few samples. Here: direct path + one image (+30..60 samples, 0.8), white noise with the beep
// 10 dB over it (full band), 16 random identities of >= 3 tones (40 trials). The multipath fit with the carrier
// phase must time the direct path within 1 sample; the single-path fit alone (max_paths 1,
// carrier_phase false: the detector before) runs on the same audio for comparison.
// (Two images 12-20 samples apart, the floor and ceiling pair, are harder: 7-9/16 at +10..+20 dB;
// docs/spyloc.md "Limits".)
TEST(Multitone, DirectPathWithinOneSampleBeforeEarlyEchoAtLowSnr) {
  Fixture f;
  const Params p = Params::defaults(plugins::multitone::schema());
  Params single = p;
  single.set("max_paths", std::int64_t{1});
  single.set("carrier_phase", false);
  std::mt19937 rng(2026);
  std::uniform_int_distribution<int> id(1, 1023);
  std::uniform_real_distribution<double> delay(30.0, 60.0), frac(0.0, 1.0);
  const int n = 40;
  int ok = 0, ok_single = 0, echo = 0, echo_single = 0;
  double max_err = 0.0;
  for (int trial = 0; trial < n; ++trial) {
    std::uint32_t mask = 0;
    while (std::popcount(mask) < 3) mask = static_cast<std::uint32_t>(id(rng));
    const int k = std::popcount(mask);
    const double a = 0.5, first = 0.2 * kFs + 100.0 * frac(rng);
    const double d1 = delay(rng);
    std::vector<float> x(static_cast<std::size_t>(0.6 * kFs), 0.0f);
    add_beep(x, mask, first, a);
    add_beep(x, mask, first + d1, 0.8 * a);
    const double sigma = std::sqrt(a * a / (2.0 * k) / std::pow(10.0, 10.0 / 10.0));
    std::normal_distribution<float> g(0.0f, static_cast<float>(sigma));
    for (float& v : x) v += g(rng);
    auto d = make(f, p);
    const Out o = run(*d, x);
    auto ds = make(f, single);
    const Out os = run(*ds, x);
    ASSERT_EQ(o.det.size(), 1u) << trial;
    ASSERT_EQ(os.det.size(), 1u) << trial;
    EXPECT_EQ(o.det[0].template_index, mask) << trial;
    const double err = o.det[0].frame - first, err_single = os.det[0].frame - first;
    std::printf("early echo trial %2d: echo +%.1f samples, %d tones: multipath %+.2f (confidence %.2f), single path %+.2f\n",
                trial, d1, k, err, o.det[0].confidence, err_single);
    ok += std::abs(err) <= 1.0;
    ok_single += std::abs(err_single) <= 1.0;
    echo += err > 15.0;
    echo_single += err_single > 15.0;
    max_err = std::max(max_err, std::abs(err));
  }
  std::printf("early echo: multipath %d/%d within 1 sample (max |err| %.2f, %d on the echo), single path %d/%d (%d on the echo)\n",
              ok, n, max_err, echo, ok_single, n, echo_single);
  EXPECT_GE(ok, 24);    // measured 27/40 (single path: 17/40); the misses are carrier-cycle slips (±2.3 samples)
  EXPECT_EQ(echo, 0);   // never on the echo (single path: 3/40); 2 of 40 three-tone beeps are timed 35-49 samples early
}

TEST(Multitone, RejectsBadParameters) {
  Fixture f;
  Params p = Params::defaults(plugins::multitone::schema());
  p.set("tones_hz", std::vector<double>{18000.0, 17000.0});
  try {
    make(f, p);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("strictly increasing"), std::string::npos) << e.what();
  }
  Params q = Params::defaults(plugins::multitone::schema());
  q.set("identities", std::vector<double>{3.0, 4096.0});  // 4096 needs tone 12 of a 10-tone grid
  try {
    make(f, q);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("identities"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace locus
