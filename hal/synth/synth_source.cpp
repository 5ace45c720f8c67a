#include "synth/synth_source.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include "locus/numbers.hpp"
#include "number_text.hpp"

namespace locus::hal::synth {

namespace {

constexpr double kSilentDbfs = -200.0;

[[noreturn]] void fail(const std::string& message) { throw std::runtime_error("synth: " + message); }


constexpr std::uint64_t mix64(std::uint64_t z) noexcept {  // splitmix64 finaliser
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

}  // namespace

// ---------------------------------------------------------------- schema and config

const ParamSchema& synth_schema() {
  static const ParamSchema schema = [] {
    ParamSchema s;
    s.push_back(int_param("channels", std::int64_t{1}, 1, 32, "", "Number of channels (microphones)."));
    s.push_back(float_param("duration_s", 10.0, 1e-6, 1e7, "s",
                     "Length of the stream on the device clock (> 0); the stream has round(duration_s*fs) frames."));
    s.push_back(float_param("period_s", 1.0, 0.0, 1e6, "s",
                     "Emission period (true time); 0 emits once."));
    s.push_back(float_param("first_emission_s", 0.5, 0.0, 1e7, "s", "True time of the first emission."));
    s.push_back(enum_param("signal", std::string("lfm"), {"lfm", "tone"},
                           "Emitted signal: lfm (linear chirp f0 -> f1) or tone (f0)."));
    s.push_back(float_param("f0_hz", 2000.0, 0.0, 1e6, "Hz", "Start frequency (tone: the frequency)."));
    s.push_back(float_param("f1_hz", 8000.0, 0.0, 1e6, "Hz", "End frequency of the lfm chirp."));
    s.push_back(float_param("signal_duration_s", 0.040, 1e-6, 1e4, "s", "Length of one emission (> 0)."));
    s.push_back(float_param("fade_s", 0.005, 0.0, 1e4, "s",
                     "Raised-cosine fade in and out (0 = sharp edges; at most half the signal duration)."));
    s.push_back(float_param("amplitude", 0.5, 0.0, 1.0, "", "Peak amplitude of the signal (full scale = 1)."));
    s.push_back(float_list_param("channel_delays_s", std::vector<double>{}, 0.0, 1e4, "s",
                                 "Extra propagation delay per channel (fractional samples allowed); empty = 0 for "
                                 "every channel, else exactly one value per channel.",
                                 0, 32));
    s.push_back(float_param("noise_dbfs", -60.0, -400.0, 0.0, "dB",
                     "White Gaussian noise RMS in dBFS (full scale 1.0); <= -200 is exactly silent."));
    s.push_back(int_param("seed", std::int64_t{1}, 0, 9.0e18, "", "Noise seed (same seed, same stream)."));
    s.push_back(float_param("clock_skew_ppm", 0.0, -10000.0, 10000.0, "ppm",
                     "Device clock error: sample k is taken at true time k / (fs * (1 + skew * 1e-6))."));
    s.push_back(float_param("sample_rate_hz", 44100.0, 1000.0, 768000.0, "Hz", "Nominal sample rate."));
    s.push_back(enum_param("pace", std::string("max"), {"max", "realtime"},
                           "max: as fast as the consumer reads (never drops); realtime: paced by the steady clock "
                           "like a sound card (a slow consumer loses frames, reported)."));
    return s;
  }();
  return schema;
}

SynthConfig SynthConfig::from_params(const Params& p) {
  SynthConfig c;
  try {
    c.channels = static_cast<std::uint32_t>(std::clamp<std::int64_t>(p.get_int("channels"), 0, 1 << 20));
    c.duration_s = p.get_float("duration_s");
    c.period_s = p.get_float("period_s");
    c.first_emission_s = p.get_float("first_emission_s");
    const std::string& sig = p.get_string("signal");
    if (sig == "lfm") {
      c.signal = Signal::Lfm;
    } else if (sig == "tone") {
      c.signal = Signal::Tone;
    } else {
      fail("signal '" + sig + "' is unknown (expected lfm or tone)");
    }
    c.f0_hz = p.get_float("f0_hz");
    c.f1_hz = p.get_float("f1_hz");
    c.signal_duration_s = p.get_float("signal_duration_s");
    c.fade_s = p.get_float("fade_s");
    c.amplitude = p.get_float("amplitude");
    c.channel_delays_s = p.get_floats("channel_delays_s");
    c.noise_dbfs = p.get_float("noise_dbfs");
    const std::int64_t seed = p.get_int("seed");
    if (seed < 0) fail("seed must be >= 0 (got " + std::to_string(seed) + ")");
    c.seed = static_cast<std::uint64_t>(seed);
    c.clock_skew_ppm = p.get_float("clock_skew_ppm");
    c.sample_rate_hz = p.get_float("sample_rate_hz");
    const std::string& pace = p.get_string("pace");
    if (pace == "max") {
      c.pace = Pace::Max;
    } else if (pace == "realtime") {
      c.pace = Pace::Realtime;
    } else {
      fail("pace '" + pace + "' is unknown (expected max or realtime)");
    }
  } catch (const std::out_of_range& e) {
    fail(std::string("missing or mistyped parameter: ") + e.what());
  }
  c.validate();
  return c;
}

void SynthConfig::validate() const {
  auto finite = [](double v) { return std::isfinite(v); };
  if (channels < 1 || channels > 32) fail("channels must be 1..32 (got " + std::to_string(channels) + ")");
  if (!finite(sample_rate_hz) || sample_rate_hz <= 0) fail("sample_rate_hz must be > 0 (got " + num(sample_rate_hz) + ")");
  if (!finite(duration_s) || duration_s <= 0) fail("duration_s must be > 0 (got " + num(duration_s) + ")");
  if (total_frames() == 0) fail("duration_s " + num(duration_s) + " is shorter than one sample");
  if (!finite(period_s) || period_s < 0) fail("period_s must be >= 0 (got " + num(period_s) + "; 0 = emit once)");
  if (!finite(first_emission_s) || first_emission_s < 0)
    fail("first_emission_s must be >= 0 (got " + num(first_emission_s) + ")");
  if (!finite(signal_duration_s) || signal_duration_s <= 0)
    fail("signal_duration_s must be > 0 (got " + num(signal_duration_s) + ")");
  if (!finite(fade_s) || fade_s < 0) fail("fade_s must be >= 0 (got " + num(fade_s) + ")");
  if (2.0 * fade_s > signal_duration_s)
    fail("fade_s " + num(fade_s) + " is longer than half of signal_duration_s " + num(signal_duration_s));
  if (!finite(amplitude) || amplitude < 0 || amplitude > 1) fail("amplitude must be in 0..1 (got " + num(amplitude) + ")");
  const double nyquist = sample_rate_hz / 2.0;
  if (!finite(f0_hz) || f0_hz < 0 || f0_hz >= nyquist)
    fail("f0_hz " + num(f0_hz) + " must be in [0, " + num(nyquist) + ") Hz (below Nyquist)");
  if (signal == Signal::Lfm && (!finite(f1_hz) || f1_hz < 0 || f1_hz >= nyquist))
    fail("f1_hz " + num(f1_hz) + " must be in [0, " + num(nyquist) + ") Hz (below Nyquist)");
  if (!channel_delays_s.empty() && channel_delays_s.size() != channels)
    fail("channel_delays_s has " + std::to_string(channel_delays_s.size()) + " values but channels is " +
         std::to_string(channels) + " (give none, or exactly one delay per channel)");
  for (std::size_t i = 0; i < channel_delays_s.size(); ++i)
    if (!finite(channel_delays_s[i]) || channel_delays_s[i] < 0)
      fail("channel_delays_s[" + std::to_string(i) + "] must be a delay >= 0 s (got " + num(channel_delays_s[i]) + ")");
  if (!finite(noise_dbfs) || noise_dbfs > 0) fail("noise_dbfs must be <= 0 (got " + num(noise_dbfs) + ")");
  if (!finite(clock_skew_ppm) || std::abs(clock_skew_ppm) >= 1e6)
    fail("clock_skew_ppm must be within +-1e6 (got " + num(clock_skew_ppm) + ")");
}

std::uint64_t SynthConfig::total_frames() const noexcept {
  const double n = std::round(duration_s * sample_rate_hz);
  return n > 0 ? static_cast<std::uint64_t>(n) : 0;
}

std::uint64_t SynthConfig::emission_count() const noexcept {
  if (!(first_emission_s < duration_s)) return 0;
  if (period_s <= 0) return 1;
  auto n = static_cast<std::uint64_t>(std::ceil((duration_s - first_emission_s) / period_s));
  while (n > 0 && emission_time_s(n - 1) >= duration_s) --n;
  while (emission_time_s(n) < duration_s) ++n;
  return n;
}

std::vector<std::vector<double>> expected_arrival_frames(const SynthConfig& config) {
  const double rate = config.true_rate_hz();
  const auto total = static_cast<double>(config.total_frames());
  const std::uint64_t count = config.emission_count();
  std::vector<std::vector<double>> out(config.channels);
  for (std::uint32_t c = 0; c < config.channels; ++c) {
    for (std::uint64_t n = 0; n < count; ++n) {
      const double frame = (config.emission_time_s(n) + config.delay_s(c)) * rate;
      if (frame >= 0 && frame < total) out[c].push_back(frame);
    }
  }
  return out;
}

double signal_value(const SynthConfig& config, double tau) noexcept {
  const double d = config.signal_duration_s;
  if (!(tau >= 0.0 && tau < d)) return 0.0;
  double w = 1.0;
  const double fade = config.fade_s;
  if (fade > 0.0) {
    if (tau < fade) {
      w = 0.5 * (1.0 - std::cos(std::numbers::pi * tau / fade));
    } else if (d - tau < fade) {
      w = 0.5 * (1.0 - std::cos(std::numbers::pi * (d - tau) / fade));
    }
  }
  double phase_cycles = config.f0_hz * tau;
  if (config.signal == Signal::Lfm) phase_cycles += (config.f1_hz - config.f0_hz) * tau * tau / (2.0 * d);
  return config.amplitude * w * std::sin(kTwoPi * phase_cycles);
}

// ---------------------------------------------------------------- generator

SynthGenerator::SynthGenerator(SynthConfig config) : config_(std::move(config)) {
  config_.validate();
  noise_rms_ = config_.noise_dbfs <= kSilentDbfs ? 0.0 : std::pow(10.0, config_.noise_dbfs / 20.0);
  emissions_ = config_.emission_count();
}

double SynthGenerator::gaussian(std::uint64_t seed, std::uint32_t channel, std::uint64_t frame) noexcept {
  const std::uint64_t h1 = mix64(mix64(mix64(seed) ^ (0x632BE59BD9B4E019ull * (channel + 1ull))) ^ frame);
  const std::uint64_t h2 = mix64(h1 ^ 0xD1B54A32D192ED03ull);
  const double u1 = static_cast<double>((h1 >> 11) + 1) * 0x1.0p-53;  // (0, 1]
  const double u2 = static_cast<double>(h2 >> 11) * 0x1.0p-53;        // [0, 1)
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

double SynthGenerator::clean(std::uint32_t channel, double t_true) const noexcept {
  if (emissions_ == 0) return 0.0;
  const double tt = t_true - config_.delay_s(channel) - config_.first_emission_s;  // time since emission 0
  if (tt < 0.0) return 0.0;
  const double d = config_.signal_duration_s;
  if (config_.period_s <= 0.0) return signal_value(config_, tt);
  const double p = config_.period_s;
  const double hi_f = std::floor(tt / p);
  const double lo_f = std::max(0.0, std::floor((tt - d) / p));
  const std::uint64_t hi = std::min<std::uint64_t>(static_cast<std::uint64_t>(hi_f), emissions_ - 1);
  double v = 0.0;
  for (auto n = static_cast<std::uint64_t>(lo_f); n <= hi; ++n) {
    const double tau = t_true - config_.delay_s(channel) - config_.emission_time_s(n);
    v += signal_value(config_, tau);
  }
  return v;
}

float SynthGenerator::sample(std::uint32_t channel, std::uint64_t frame) const noexcept {
  const double t = static_cast<double>(frame) / config_.true_rate_hz();
  double v = clean(channel, t);
  if (noise_rms_ > 0.0) v += noise_rms_ * gaussian(config_.seed, channel, frame);
  return static_cast<float>(v);
}

void SynthGenerator::render(std::uint64_t first_frame, std::size_t frames, float* out) const noexcept {
  const std::uint32_t ch = config_.channels;
  for (std::size_t i = 0; i < frames; ++i)
    for (std::uint32_t c = 0; c < ch; ++c) out[i * ch + c] = sample(c, first_frame + i);
}

// ---------------------------------------------------------------- source

SynthSource::~SynthSource() { stop(); }

void SynthSource::open(const Params& params, HostContext& ctx) {
  open(SynthConfig::from_params(params));
  const SynthConfig& c = gen_->config();
  std::ostringstream os;
  os << "synth: " << c.channels << " ch at " << c.sample_rate_hz << " Hz, " << c.total_frames() << " frames, "
     << c.emission_count() << " emissions, pace " << (c.pace == Pace::Max ? "max" : "realtime");
  ctx.log.debug(os.str());
}

void SynthSource::open(const SynthConfig& config) {
  if (thread_.joinable()) fail("open() while running");
  gen_ = std::make_unique<SynthGenerator>(config);
  finished_.store(false, std::memory_order_release);
  produced_.store(0, std::memory_order_release);
}

std::uint32_t SynthSource::channels() const { return gen_ ? gen_->config().channels : 0; }
double SynthSource::sample_rate_hz() const { return gen_ ? gen_->config().sample_rate_hz : 0.0; }
bool SynthSource::live() const { return gen_ && gen_->config().pace == Pace::Realtime; }

void SynthSource::start(AudioRing& ring) {
  if (!gen_) fail("start() before open()");
  if (thread_.joinable()) fail("start() while already running");
  if (ring.channels() != gen_->config().channels)
    fail("ring has " + std::to_string(ring.channels()) + " channels, source has " +
         std::to_string(gen_->config().channels));
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  produced_.store(0, std::memory_order_release);
  frame_zero_s_.store(std::numeric_limits<double>::quiet_NaN(), std::memory_order_release);
  if (gen_->config().pace == Pace::Realtime) {
    block_.assign(kBlockFrames * gen_->config().channels, 0.0f);
    thread_ = std::thread([this, &ring] { run_realtime(ring); });
  } else {
    thread_ = std::thread([this, &ring] { run_max(ring); });
  }
}

void SynthSource::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SynthSource::run_max(AudioRing& ring) {
  const std::uint64_t total = gen_->config().total_frames();
  std::uint64_t next = 0;
  while (next < total) {
    if (stop_.load(std::memory_order_acquire)) return;
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(kBlockFrames, total - next));
    AudioRing::WriteSpan span = ring.write_acquire(want);
    if (span.frames() == 0) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));
      continue;
    }
    gen_->render(next, span.first.frames, span.first.data);
    gen_->render(next + span.first.frames, span.second.frames, span.second.data);
    ring.write_commit(span.frames());  // never refused: nothing is lost in this mode
    next += span.frames();
    produced_.store(next, std::memory_order_release);
  }
  finished_.store(true, std::memory_order_release);
}

void SynthSource::run_realtime(AudioRing& ring) {
  using clock = std::chrono::steady_clock;
  const std::uint64_t total = gen_->config().total_frames();
  const double rate = gen_->config().true_rate_hz();  // frames per true (steady-clock) second
  const clock::time_point t0 = clock::now();
  std::uint64_t next = 0;
  while (next < total) {
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(kBlockFrames, total - next));
    // A sound card hands a block over once its last frame has been captured.
    const auto due = t0 + std::chrono::duration_cast<clock::duration>(
                              std::chrono::duration<double>(static_cast<double>(next + n) / rate));
    while (clock::now() < due) {
      if (stop_.load(std::memory_order_acquire)) return;
      std::this_thread::sleep_until(std::min(due, clock::now() + std::chrono::milliseconds(20)));
    }
    if (stop_.load(std::memory_order_acquire)) return;
    gen_->render(next, n, block_.data());
    // Frame 0 was taken at t0 (libstdc++'s steady_clock is CLOCK_MONOTONIC); published before the first
    // write, so a consumer that sees frames sees the origin.
    if (next == 0) {
      frame_zero_s_.store(std::chrono::duration<double>(t0.time_since_epoch()).count(), std::memory_order_release);
    }
    ring.write(block_.data(), n);  // reports what does not fit as lost (write_lost)
    next += n;
    produced_.store(next, std::memory_order_release);
  }
  finished_.store(true, std::memory_order_release);
}

}  // namespace locus::hal::synth
