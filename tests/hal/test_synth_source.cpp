// The `synth` audio source: pure rendering (closed form, determinism, split invariance), the threaded
// source through a real AudioRing, parameter errors, registration.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"
#include "synth/synth_source.hpp"

namespace locus::hal::synth {
namespace {

SynthConfig silent_config() {
  SynthConfig c;
  c.noise_dbfs = -300.0;
  return c;
}

// The signal definition of scene-format.md, written out independently of the implementation.
double reference_lfm(double tau, double a, double f0, double f1, double d, double fade) {
  if (tau < 0 || tau >= d) return 0.0;
  double w = 1.0;
  if (fade > 0 && tau < fade) w = 0.5 - 0.5 * std::cos(std::numbers::pi * tau / fade);
  if (fade > 0 && tau > d - fade) w = 0.5 - 0.5 * std::cos(std::numbers::pi * (d - tau) / fade);
  return a * w * std::sin(2 * std::numbers::pi * (f0 * tau + (f1 - f0) * tau * tau / (2 * d)));
}

Params synth_params(std::initializer_list<std::pair<std::string, ParamValue>> overrides) {
  Params p = Params::defaults(synth_schema());
  for (const auto& [k, v] : overrides) p.set(k, v);
  return p;
}

TEST(SynthRender, DeterministicForASeed) {
  SynthConfig c;
  c.channels = 2;
  c.noise_dbfs = -30.0;
  c.seed = 42;
  const SynthGenerator a(c), b(c);
  std::vector<float> x(4000 * 2), y(4000 * 2);
  a.render(20000, 4000, x.data());
  b.render(20000, 4000, y.data());
  EXPECT_EQ(0, std::memcmp(x.data(), y.data(), x.size() * sizeof(float)));

  c.seed = 43;
  const SynthGenerator other(c);
  other.render(20000, 4000, y.data());
  EXPECT_NE(0, std::memcmp(x.data(), y.data(), x.size() * sizeof(float)));
  // The two channels get independent noise.
  int same = 0;
  for (std::size_t i = 0; i < 4000; ++i) same += x[2 * i] == x[2 * i + 1];
  EXPECT_LT(same, 10);
}

TEST(SynthRender, LfmEqualsTheClosedFormAtTheExactDelayedSkewedTime) {
  SynthConfig c = silent_config();
  c.channels = 3;
  c.sample_rate_hz = 48000.0;
  c.first_emission_s = 0.01;
  c.period_s = 0.1;
  c.duration_s = 0.3;
  c.f0_hz = 1500;
  c.f1_hz = 9000;
  c.signal_duration_s = 0.03;
  c.fade_s = 0.004;
  c.amplitude = 0.8;
  c.channel_delays_s = {0.0, 0.37 / 48000.0, 0.0021234};  // fractional samples
  c.clock_skew_ppm = 250.0;
  const SynthGenerator g(c);
  const std::uint64_t frames = c.total_frames();
  ASSERT_EQ(frames, 14400u);
  std::vector<float> out(frames * 3);
  g.render(0, frames, out.data());

  const double true_rate = 48000.0 * (1 + 250e-6);
  double max_err = 0.0, energy = 0.0;
  for (std::uint64_t k = 0; k < frames; ++k) {
    const double t = static_cast<double>(k) / true_rate;
    for (std::uint32_t ch = 0; ch < 3; ++ch) {
      double expected = 0.0;
      for (int n = 0; n < 3; ++n)
        expected += reference_lfm(t - c.channel_delays_s[ch] - (0.01 + 0.1 * n), 0.8, 1500, 9000, 0.03, 0.004);
      max_err = std::max(max_err, std::abs(out[k * 3 + ch] - expected));
      energy += expected * expected;
    }
  }
  EXPECT_LT(max_err, 1e-6);  // float rounding of the closed form
  EXPECT_GT(energy, 100.0);  // the emissions are in there

  // The ground truth: emission start = (e_n + delay) * fs * (1 + skew).
  const auto arrivals = expected_arrival_frames(c);
  ASSERT_EQ(arrivals.size(), 3u);
  for (std::uint32_t ch = 0; ch < 3; ++ch) {
    ASSERT_EQ(arrivals[ch].size(), 3u);
    for (int n = 0; n < 3; ++n)
      EXPECT_DOUBLE_EQ(arrivals[ch][n], (0.01 + 0.1 * n + c.channel_delays_s[ch]) * true_rate);
  }
  // A fractional delay really shifts the waveform: channel 1 is channel 0 delayed by 0.37 samples.
  EXPECT_NEAR(arrivals[1][0] - arrivals[0][0], 0.37 * (1 + 250e-6), 1e-9);
}

TEST(SynthRender, ToneAndOverlappingEmissionsAddUp) {
  SynthConfig c = silent_config();
  c.signal = Signal::Tone;
  c.f0_hz = 1000;
  c.fade_s = 0;
  c.signal_duration_s = 0.05;
  c.period_s = 0.02;  // emissions overlap
  c.first_emission_s = 0.0;
  c.duration_s = 0.2;
  const SynthGenerator g(c);
  const std::uint64_t k = 1985;  // t = 45.01 ms: emissions 0, 1 and 2 are all sounding
  const double tk = k / 44100.0;
  double expected = 0;
  for (int n = 0; n < 3; ++n) expected += 0.5 * std::sin(2 * std::numbers::pi * 1000 * (tk - 0.02 * n));
  EXPECT_NEAR(g.sample(0, k), expected, 1e-6);
}

TEST(SynthRender, DifferentBlockSplitsGiveIdenticalOutput) {
  SynthConfig c;
  c.channels = 4;
  c.noise_dbfs = -40;
  c.channel_delays_s = {0.0, 1e-4, 2.5e-4, 7.77e-4};
  c.clock_skew_ppm = -33.0;
  c.first_emission_s = 0.01;
  c.period_s = 0.05;
  c.duration_s = 0.5;
  const SynthGenerator g(c);
  const std::uint64_t frames = c.total_frames();
  std::vector<float> whole(frames * 4), split(frames * 4);
  g.render(0, frames, whole.data());
  for (std::size_t block : {1u, 7u, 256u, 1000u, 4093u}) {
    std::fill(split.begin(), split.end(), -9.0f);
    for (std::uint64_t pos = 0; pos < frames; pos += block) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(block, frames - pos));
      g.render(pos, n, split.data() + pos * 4);
    }
    EXPECT_EQ(0, std::memcmp(whole.data(), split.data(), whole.size() * sizeof(float))) << "block " << block;
  }
  // Random splits too.
  std::mt19937 rng(7);
  std::fill(split.begin(), split.end(), -9.0f);
  for (std::uint64_t pos = 0; pos < frames;) {
    const std::size_t n = std::min<std::uint64_t>(1 + rng() % 600, frames - pos);
    g.render(pos, n, split.data() + pos * 4);
    pos += n;
  }
  EXPECT_EQ(0, std::memcmp(whole.data(), split.data(), whole.size() * sizeof(float)));
}

TEST(SynthRender, NoiseHasTheRequestedLevelAndVeryLowMeansSilent) {
  SynthConfig c;
  c.first_emission_s = 5.0;  // no emission in the rendered range
  c.noise_dbfs = -20.0;
  const SynthGenerator g(c);
  std::vector<float> x(100000);
  g.render(0, x.size(), x.data());
  double sum = 0, sum2 = 0;
  for (float v : x) {
    sum += v;
    sum2 += double(v) * v;
  }
  const double mean = sum / x.size(), rms = std::sqrt(sum2 / x.size());
  EXPECT_NEAR(rms, 0.1, 0.002);
  EXPECT_NEAR(mean, 0.0, 0.002);

  c.noise_dbfs = -200.0;
  const SynthGenerator quiet(c);
  quiet.render(0, x.size(), x.data());
  for (float v : x) ASSERT_EQ(v, 0.0f);
}

TEST(SynthRender, EmissionScheduleAndArrivalsStayInsideTheStream) {
  SynthConfig c = silent_config();
  c.duration_s = 2.0;
  c.first_emission_s = 0.5;
  c.period_s = 0.5;
  EXPECT_EQ(c.emission_count(), 3u);  // 0.5, 1.0, 1.5 (2.0 is not < duration)
  c.channels = 2;
  c.channel_delays_s = {0.0, 0.6};  // the third emission reaches channel 1 after the end
  const auto a = expected_arrival_frames(c);
  EXPECT_EQ(a[0].size(), 3u);
  EXPECT_EQ(a[1].size(), 2u);
  c.period_s = 0.0;  // once
  EXPECT_EQ(c.emission_count(), 1u);
  c.first_emission_s = 3.0;
  EXPECT_EQ(c.emission_count(), 0u);
}

// ---------------------------------------------------------------- the threaded source

TEST(SynthSource, DeliversExactlyDurationTimesRateFramesInOrderThenFinishes) {
  SynthConfig c;
  c.channels = 2;
  c.duration_s = 0.75;
  c.noise_dbfs = -50;
  c.first_emission_s = 0.1;
  c.period_s = 0.2;
  c.channel_delays_s = {0.0, 3.3e-4};
  const std::uint64_t total = c.total_frames();
  ASSERT_EQ(total, 33075u);

  SynthSource src;
  src.open(c);
  EXPECT_FALSE(src.live());
  EXPECT_EQ(src.channels(), 2u);
  AudioRing ring(2, 1024);  // much smaller than the stream: the producer has to wait for us
  src.start(ring);

  std::vector<float> got;
  got.reserve(total * 2);
  std::vector<float> buf(300 * 2);
  std::uint64_t expected_frame = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (std::chrono::steady_clock::now() < deadline) {
    const bool done = src.finished();  // read before draining: all frames are in the ring once true
    std::uint64_t first = 0, lost = 0;
    const std::size_t n = ring.read(buf.data(), 300, &first, &lost);
    if (n > 0) {
      ASSERT_EQ(first, expected_frame);
      ASSERT_EQ(lost, 0u);
      got.insert(got.end(), buf.begin(), buf.begin() + n * 2);
      expected_frame += n;
      // Consume slowly now and then so the ring fills up.
      if (expected_frame % 7 == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));
    } else if (done) {
      break;
    } else {
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  }
  src.stop();
  EXPECT_TRUE(src.finished());
  EXPECT_EQ(expected_frame, total);
  EXPECT_EQ(src.frames_produced(), total);
  EXPECT_EQ(ring.frames_lost(), 0u);
  EXPECT_EQ(ring.producer_frame(), total);

  std::vector<float> ref(total * 2);
  SynthGenerator(c).render(0, total, ref.data());
  ASSERT_EQ(got.size(), ref.size());
  EXPECT_EQ(0, std::memcmp(got.data(), ref.data(), ref.size() * sizeof(float)));
}

TEST(SynthSource, StopIsIdempotentAndDoesNotHangWithoutAConsumer) {
  SynthConfig c;
  c.duration_s = 3600.0;  // would take long to consume; nobody reads
  SynthSource src;
  src.open(c);
  AudioRing ring(1, 512);
  src.start(ring);
  const auto wait_until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (src.frames_produced() < 512 && std::chrono::steady_clock::now() < wait_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  std::this_thread::sleep_for(std::chrono::milliseconds(5));  // now it is waiting for space
  const auto t0 = std::chrono::steady_clock::now();
  src.stop();
  src.stop();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(1));
  EXPECT_FALSE(src.finished());
  EXPECT_EQ(src.frames_produced(), 512u);  // filled the ring, then waited
  EXPECT_EQ(ring.frames_lost(), 0u);
}

TEST(SynthSource, RealtimePaceIsLiveAndPacedByTheClock) {
  SynthConfig c;
  c.duration_s = 0.2;
  c.pace = Pace::Realtime;
  SynthSource src;
  src.open(c);
  EXPECT_TRUE(src.live());
  AudioRing ring(1, 16384);
  const auto t0 = std::chrono::steady_clock::now();
  src.start(ring);
  std::vector<float> buf(1024);
  std::uint64_t frames = 0;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5)) {
    const bool done = src.finished();
    const std::size_t n = ring.read(buf.data(), buf.size());
    frames += n;
    if (n == 0 && done) break;
    if (n == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  src.stop();
  EXPECT_EQ(frames, c.total_frames());
  EXPECT_GE(elapsed, 0.19);  // it took (at least) the stream's duration
  EXPECT_EQ(ring.frames_lost(), 0u);
}

TEST(SynthSource, RealtimePaceReportsLossesWhenTheConsumerIsTooSlow) {
  SynthConfig c;
  c.duration_s = 0.1;
  c.pace = Pace::Realtime;
  SynthSource src;
  src.open(c);
  AudioRing ring(1, 512);  // nobody reads: everything past 512 frames is lost, and counted
  src.start(ring);
  const auto t0 = std::chrono::steady_clock::now();
  while (!src.finished() && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(5))
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  src.stop();
  EXPECT_TRUE(src.finished());
  EXPECT_EQ(ring.producer_frame(), c.total_frames());
  EXPECT_EQ(ring.frames_lost(), c.total_frames() - 512);
}

// ---------------------------------------------------------------- params

TEST(SynthSource, OpensFromParamsAndRejectsBadOnesClearly) {
  test::TestHost host;
  HostContext ctx = host.context("mic", "A");
  {
    SynthSource src;
    src.open(synth_params({{"channels", std::int64_t{3}}, {"channel_delays_s", std::vector<double>{0, 1e-4, 2e-4}},
                           {"pace", std::string("realtime")}}),
             ctx);
    EXPECT_EQ(src.channels(), 3u);
    EXPECT_DOUBLE_EQ(src.sample_rate_hz(), 44100.0);
    EXPECT_TRUE(src.live());
  }
  auto error_of = [&](Params p) -> std::string {
    SynthSource src;
    try {
      src.open(p, ctx);
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "";
  };
  const std::string wrong_len =
      error_of(synth_params({{"channels", std::int64_t{2}}, {"channel_delays_s", std::vector<double>{0, 1e-4, 2e-4}}}));
  EXPECT_NE(wrong_len.find("channel_delays_s has 3 values but channels is 2"), std::string::npos) << wrong_len;
  EXPECT_NE(error_of(synth_params({{"fade_s", 0.03}})).find("fade_s"), std::string::npos);
  EXPECT_NE(error_of(synth_params({{"f1_hz", 30000.0}})).find("f1_hz 30000 must be in [0, 22050)"), std::string::npos);
  EXPECT_NE(error_of(synth_params({{"duration_s", 0.0}})).find("duration_s must be > 0"), std::string::npos);
  EXPECT_NE(error_of(synth_params({{"signal", std::string("gold")}})).find("signal 'gold' is unknown"),
            std::string::npos);
  Params missing = synth_params({});
  missing.set("seed", std::string("x"));
  EXPECT_NE(error_of(missing).find("seed"), std::string::npos);

  // A ring with the wrong channel count is refused at start().
  SynthSource src;
  src.open(SynthConfig{});
  AudioRing ring(2, 1024);
  EXPECT_THROW(src.start(ring), std::runtime_error);
}

TEST(SynthSource, SchemaIsCompleteAndRegisteredAsBuiltin) {
  for (const ParamSpec& s : synth_schema()) {
    EXPECT_FALSE(s.doc.empty()) << s.key;
    EXPECT_FALSE(s.required()) << s.key;
  }
  Registry registry;
  register_builtins(registry);
  const SourceDescriptor* d = registry.find_source("synth");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->schema.size(), synth_schema().size());
  auto src = registry.create_source("synth");
  ASSERT_NE(src, nullptr);
  test::TestHost host;
  HostContext ctx = host.context();
  src->open(Params::defaults(d->schema), ctx);
  EXPECT_EQ(src->channels(), 1u);
}

}  // namespace
}  // namespace locus::hal::synth
