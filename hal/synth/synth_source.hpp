// `synth`: a deterministic signal generator standing in for a microphone array.
//
// Every sample is computed analytically from the closed form of the signal at the exact (fractional)
// true time at which the device's sample clock takes it, so per-channel propagation delays and clock
// skew are exact (no interpolation filters), and any block of the stream can be rendered on its own:
// rendering [a, b) in one call or in many calls gives bit-identical output.
//
// Time model (same as scene-format.md "truth.clocks", with offset 0):
//   - emission n starts at true time e_n = first_emission_s + n * period_s (period_s = 0: once), for
//     every n >= 0 with e_n < duration_s;
//   - channel c hears it from true time e_n + channel_delays_s[c];
//   - the device clock runs at fs * (1 + clock_skew_ppm * 1e-6) true samples per true second, so
//     sample k (local frame k) is taken at true time k / (fs * (1 + skew * 1e-6));
//   - the stream has round(duration_s * fs) frames (duration_s is measured on the device clock).
// Signals (scene-format.md "Signals"), tau = time since the start of the emission at the microphone,
// D = signal_duration_s, w(tau) a raised-cosine fade of fade_s in and out (1 inside, 0 outside [0, D)):
//   lfm : a * w(tau) * sin(2*pi*(f0*tau + (f1 - f0) * tau^2 / (2*D)))
//   tone: a * w(tau) * sin(2*pi*f0*tau)
// Overlapping emissions (D > period) add up. White Gaussian noise of RMS 10^(noise_dbfs/20) (full scale
// = 1.0, so a full-scale sine is -3 dBFS RMS) is added; noise_dbfs <= -200 means exactly silent. The
// noise of (channel, frame) depends only on (seed, channel, frame) (a counter-based generator), which
// is what keeps rendering split-invariant.
#pragma once

#include <atomic>
#include <limits>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "locus/audio_source.hpp"
#include "locus/params.hpp"

namespace locus::hal::synth {

enum class Signal : std::uint8_t { Lfm, Tone };
enum class Pace : std::uint8_t { Max, Realtime };

/// Validated generator settings (what open() derives from its Params).
struct SynthConfig {
  std::uint32_t channels = 1;
  double duration_s = 10.0;
  double period_s = 1.0;
  double first_emission_s = 0.5;
  Signal signal = Signal::Lfm;
  double f0_hz = 2000.0;
  double f1_hz = 8000.0;
  double signal_duration_s = 0.040;
  double fade_s = 0.005;
  double amplitude = 0.5;
  std::vector<double> channel_delays_s;  ///< empty = 0 for every channel, else one per channel
  double noise_dbfs = -60.0;
  std::uint64_t seed = 1;
  double clock_skew_ppm = 0.0;
  double sample_rate_hz = 44100.0;
  Pace pace = Pace::Max;

  /// Reads every key of synth_schema() from `params` and validates the combination. Throws
  /// std::runtime_error naming the parameter and what was expected.
  static SynthConfig from_params(const Params& params);
  /// Throws std::runtime_error ("synth: <key> ...") when a value or a combination is invalid.
  void validate() const;

  /// Frames in the stream: round(duration_s * sample_rate_hz).
  std::uint64_t total_frames() const noexcept;
  /// True sample rate of the device clock: fs * (1 + skew * 1e-6).
  double true_rate_hz() const noexcept { return sample_rate_hz * (1.0 + clock_skew_ppm * 1e-6); }
  /// Delay of channel c (0 when channel_delays_s is empty).
  double delay_s(std::uint32_t channel) const noexcept {
    return channel < channel_delays_s.size() ? channel_delays_s[channel] : 0.0;
  }
  /// Number of emissions (n >= 0 with first_emission_s + n * period_s < duration_s).
  std::uint64_t emission_count() const noexcept;
  /// True time of emission n.
  double emission_time_s(std::uint64_t n) const noexcept { return first_emission_s + double(n) * period_s; }
};

/// The parameter schema of the `synth` source.
const ParamSchema& synth_schema();

/// Ground truth: for each channel, the (fractional) local frame at which each emission starts at that
/// microphone, (e_n + delay_c) * fs * (1 + skew * 1e-6), in emission order, restricted to starts inside
/// the stream ([0, total_frames)).
std::vector<std::vector<double>> expected_arrival_frames(const SynthConfig& config);

/// The noise-free signal of one emission at time `tau` seconds after its start (0 outside [0, D)).
double signal_value(const SynthConfig& config, double tau) noexcept;

/// Pure, thread-free rendering of the stream.
class SynthGenerator {
 public:
  explicit SynthGenerator(SynthConfig config);  ///< validates; throws std::runtime_error
  const SynthConfig& config() const noexcept { return config_; }

  /// [RT] Writes frames [first_frame, first_frame + frames) interleaved (frames * channels floats).
  /// Pure: the output depends only on the config and the frame numbers (any split gives the same).
  /// Frames at or past total_frames() are rendered too (the signal schedule is the same).
  void render(std::uint64_t first_frame, std::size_t frames, float* out_interleaved) const noexcept;

  /// [any] One sample (noise included) of channel `channel` at local frame `frame`.
  float sample(std::uint32_t channel, std::uint64_t frame) const noexcept;

  /// [any] The unit-variance Gaussian noise value of (seed, channel, frame).
  static double gaussian(std::uint64_t seed, std::uint32_t channel, std::uint64_t frame) noexcept;

 private:
  double clean(std::uint32_t channel, double t_true) const noexcept;

  SynthConfig config_;
  double noise_rms_ = 0.0;  // 0 = silent
  std::uint64_t emissions_ = 0;
};

/// The AudioSource: a thread renders blocks of kBlockFrames frames into the ring. pace=max waits for
/// space (never drops, live() == false); pace=realtime is paced by the steady clock at the true device
/// rate and writes like a sound card (live() == true; a full ring means frames reported lost).
class SynthSource final : public AudioSource {
 public:
  static constexpr std::size_t kBlockFrames = 256;

  SynthSource() = default;
  ~SynthSource() override;

  void open(const Params& params, HostContext& ctx) override;
  /// Same as open() from a ready config (tests, tools).
  void open(const SynthConfig& config);
  std::uint32_t channels() const override;
  double sample_rate_hz() const override;
  bool live() const override;
  void start(AudioRing& ring) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override { return {}; }
  /// pace=realtime: the steady clock (CLOCK_MONOTONIC on Linux) at the start of the run, where frame 0
  /// is captured; NaN for pace=max (replay-like) and before the first block is written.
  double frame_zero_monotonic_s() const noexcept override { return frame_zero_s_.load(std::memory_order_acquire); }

  /// Frames produced (committed or, for pace=realtime, reported lost) so far.
  std::uint64_t frames_produced() const noexcept { return produced_.load(std::memory_order_acquire); }

 private:
  void run_max(AudioRing& ring);
  void run_realtime(AudioRing& ring);

  std::unique_ptr<SynthGenerator> gen_;
  std::vector<float> block_;  // pace=realtime staging buffer (sized in start())
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::uint64_t> produced_{0};
  std::atomic<double> frame_zero_s_{std::numeric_limits<double>::quiet_NaN()};
};

}  // namespace locus::hal::synth
