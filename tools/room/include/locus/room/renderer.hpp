// The acoustics of a hardware-in-the-loop room (`locus room`, docs/room.md): every device's speaker
// signal (what its node plays into the room's JACK input port) rendered into every device's
// microphones (the room's output ports, which the nodes capture), block by block, in the JACK process
// callback.
//
// Model, per (speaker s, receiving device d, microphone m, path p = direct or a first-order image of a
// shoebox room):
//   * room time t_r = k / fs for room frame k (frame 0 = the room's first cycle); the speaker plays on
//     it: the sample the room receives at frame i left the speaker at true time i / fs;
//   * device d's microphone sample at room frame k is the air at true time t_d = r_d·t_r + c_d:
//     r_d = 1 / (1 + skew_d) resamples a device whose clock runs skew_d fast (clock skew), and c_d < 0
//     is a fixed latency (half the interpolator, and the headroom a slow clock needs to stay causal);
//   * the emission time te solves t_d − te = |p_mic(t_d) − image_p(p_spk(te))| / c (two fixed-point
//     steps), positions from the layout's trajectories at layout time t − layout_start (before the
//     layout starts every device holds its first pose): moving ends give Doppler by themselves;
//   * contribution = gain_p · level_at_1m / max(r, min_distance) · x_s(te), x_s read from the speaker's
//     history with a 64-tap Kaiser-windowed sinc interpolator (1024 phases): a fractional delay, and
//     the converters' anti-aliasing low-pass (−6 dB at 0.88·fs/2, the same for every delay; why: renderer.cpp);
//     te and the gain are computed every 32 frames and interpolated linearly in between;
//   * plus white noise per microphone, then clipping at full scale (±1).
// A speaker silent for longer than the longest path is skipped (most speakers are silent most of the
// time: the cost follows the sound, not the number of paths).
//
// Threads: construction and every [main] method on one thread; process() on the JACK process thread
// ([RT]: no allocation, lock, log or system call — tests/alloc/rt_room.cpp); start_layout_at() and
// the counters are atomics, readable from any thread. Positions come from tables computed in the
// constructor (1 ms steps over the layout's time range, linear in between), never from the
// trajectories on the RT thread.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "locus/room/layout.hpp"

namespace locus::room {

struct RendererConfig {
  double level_at_1m = 0.1;           ///< amplitude (full scale 1) of a unit speaker signal at 1 m (the simulator's)
  double min_distance_m = 0.01;       ///< spreading clamped below this distance
  double self_gain = 1.0;             ///< extra gain of a device's own speaker into its own mics (direct
                                      ///< path; the simulator's DeviceModel::self_gain: coupling through the case)
  double noise_rms = 7.07e-4;         ///< white noise per microphone (RMS, full scale 1); 0 = none
  int reflection_order = 0;           ///< 0 = direct path only, 1 = plus the six first-order images
  double reflection = 0.7;            ///< pressure reflection coefficient of every wall (order 1)
  std::optional<Eigen::Vector3d> room_size_m;  ///< the shoebox [0,x]×[0,y]×[0,z]; needed for reflections
  std::vector<double> skew_ppm;       ///< per layout device (empty = none): its microphones run this fast
  double max_duration_s = 600.0;      ///< longest run; a slow clock (skew < 0) is causal up to it
  std::uint32_t max_block_frames = 8192;  ///< largest process() block
  double table_step_s = 1e-3;         ///< position table resolution
  std::uint64_t seed = 1;             ///< noise
};

/// A burst of sound starting on a speaker port after >= 0.1 s of silence (what the truth's emissions are).
struct Onset {
  std::uint32_t device = 0;  ///< layout device index
  std::uint64_t frame = 0;   ///< room frame of its first non-silent sample
};

class RoomRenderer {
 public:
  static constexpr int kTaps = 64;         ///< interpolator length
  static constexpr int kPhases = 1024;     ///< fractional-delay resolution (1/1024 sample)
  static constexpr std::uint32_t kControl = 32;  ///< frames between geometry updates

  /// [main] Precomputes everything process() needs. Throws std::invalid_argument for a bad config
  /// (reflections without a room, skew list of the wrong size, |skew| > 1000 ppm...).
  RoomRenderer(const Layout& layout, RendererConfig cfg);
  RoomRenderer(const RoomRenderer&) = delete;
  RoomRenderer& operator=(const RoomRenderer&) = delete;

  std::size_t device_count() const noexcept { return devices_.size(); }
  /// Microphone outputs of device d are mics[mic_offset(d) .. mic_offset(d) + mic_count(d)) in process().
  std::size_t mic_offset(std::size_t d) const noexcept { return devices_[d].mic_offset; }
  std::size_t mic_count(std::size_t d) const noexcept { return devices_[d].mics.size(); }
  std::size_t total_mics() const noexcept { return total_mics_; }
  double sample_rate_hz() const noexcept { return fs_; }

  /// [any] Layout time 0 is room time `t_room_s` from now on (once; later calls are ignored).
  void start_layout_at(double t_room_s) noexcept;
  /// [any] Room time of layout time 0; +inf until started.
  double layout_start_s() const noexcept { return layout_start_s_.load(std::memory_order_acquire); }

  /// [RT] Renders one block: speakers[d] = device d's speaker input (n frames; nullptr = silent),
  /// mics[i] = the outputs (n frames each, overwritten). n <= max_block_frames.
  void process(const float* const* speakers, float* const* mics, std::uint32_t n) noexcept;

  /// [RT] `n` frames the server ran without the room (an xrun skipped its cycles): its speakers are
  /// taken as silent there and the room's clock moves on, so that room frames stay server frames.
  void skip(std::uint64_t n) noexcept;

  /// [any] Frames processed so far (the next block's first room frame).
  std::uint64_t frames() const noexcept { return frames_.load(std::memory_order_acquire); }
  /// [any] Output samples clipped at full scale; path-blocks rendered; onsets lost (queue full).
  std::uint64_t clipped() const noexcept { return clipped_.load(std::memory_order_relaxed); }
  std::uint64_t path_blocks() const noexcept { return path_blocks_.load(std::memory_order_relaxed); }
  std::uint64_t onsets_dropped() const noexcept { return onsets_dropped_.load(std::memory_order_relaxed); }
  /// [main] The next onset found by process() (single consumer); false when none is waiting.
  bool pop_onset(Onset& out) noexcept;

  /// Device d's microphone clock: its sample at room time t_r is the air at true time rate·t_r + offset.
  double clock_rate(std::size_t d) const noexcept { return devices_[d].rate; }
  double clock_offset_s(std::size_t d) const noexcept { return devices_[d].offset_s; }
  double skew_ppm(std::size_t d) const noexcept { return devices_[d].skew_ppm; }

  /// [main] True time (room clock) at which a sound leaving device `src`'s speaker at true time
  /// `te_s` reaches microphone `mic` of device `rx` by the direct path (same model as process()).
  double direct_arrival_s(std::size_t src, double te_s, std::size_t rx, std::size_t mic) const noexcept;
  /// [main] Straight-line distance (m) between that speaker and microphone at true time t_s.
  double distance_m(std::size_t src, std::size_t rx, std::size_t mic, double t_s) const noexcept;
  /// The longest delay a path can have (s), the history's reach.
  double max_delay_s() const noexcept { return max_delay_s_; }

 private:
  /// Positions of one point of a device over layout time (one entry = static).
  struct Track {
    std::vector<Eigen::Vector3d> p;
    Eigen::Vector3d at(double tau, double t0, double step) const noexcept;
  };
  struct Device {
    Track speaker;
    std::vector<Track> mics;
    std::size_t mic_offset = 0;
    double rate = 1.0, offset_s = 0.0, skew_ppm = 0.0;
  };
  struct Path {
    std::uint32_t src, rx, mic;
    int image;      ///< -1 direct, 0..5 the wall mirrored
    float gain;     ///< reflection coefficient (1 direct)
  };
  struct Noise {
    std::uint32_t state;
  };

  Eigen::Vector3d image_of(const Eigen::Vector3d& p, int image) const noexcept;
  /// Room frame index (fractional) of the speaker sample heard at room frame k on `path`, and the gain.
  void geometry(const Path& path, double k, double start, double& src_index, double& gain) const noexcept;

  double fs_, c_;
  RendererConfig cfg_;
  double t0_ = 0.0, step_ = 1e-3;
  std::vector<Device> devices_;
  std::vector<Path> paths_;
  std::size_t total_mics_ = 0;
  std::vector<float> table_;            // kPhases + 1 rows of kTaps weights
  std::vector<float> history_;          // devices × history_len_, ring per speaker
  std::uint64_t history_len_ = 0, history_mask_ = 0;
  std::vector<std::uint64_t> last_loud_;  // per speaker: room frame of its latest non-silent sample + 1 (0 = never)
  std::vector<std::uint64_t> silent_run_; // per speaker: silent frames in a row
  std::vector<Noise> noise_;
  std::vector<double> ctrl_src_, ctrl_gain_;  // control points of one path and block
  double max_delay_s_ = 0.0;
  std::uint64_t reach_frames_ = 0;
  float noise_amp_ = 0.0f;

  std::atomic<double> layout_start_s_{std::numeric_limits<double>::infinity()};
  std::atomic<std::uint64_t> frames_{0}, clipped_{0}, path_blocks_{0}, onsets_dropped_{0};
  static constexpr std::size_t kOnsetCapacity = 1024;
  std::array<Onset, kOnsetCapacity> onsets_{};
  std::atomic<std::uint64_t> onset_write_{0}, onset_read_{0};
};

}  // namespace locus::room
