// The scene simulator engine: a Simulation (what exists, where, on which clock, what it emits and
// when) is rendered by SceneSimulator into a scene directory (docs/scene-format.md) that every
// plugin replays unchanged. Physics model and families: docs/simulator.md.
//
// Acoustics, per received sample (nothing is precomputed as a fixed delay unless both ends are static):
//   * sample k of device D is taken at local time k/fs, i.e. TRUE time t = clock_D.true_from_local(k/fs);
//   * for every emission e of source S (start te0 in true time) and every path p (direct + image
//     sources of a shoebox room up to max_order), the emitted time te solves
//         t − te = |p_mic(t) − image_p(p_spk(te))| / c          (fixed-point iteration)
//     so a moving speaker or microphone gives Doppler by itself;
//   * contribution = level_at_1m · source_level · gain_e · Πwalls β · obstruction_p · (1 m / r)
//                    · s_e(te − te0),     s_e = the emitted signal's closed form (dsp::SignalEvaluator)
//   * each (emission, receiving device) contribution goes through the SOURCE's speaker band-pass,
//     the device's sum of contributions + acoustic noise through its MIC band-pass, then clipping at
//     full scale (±1) and quantisation by the WAV writer.
// A device hears its own emissions (self-recording: near field, loud, possibly clipped).
//
// Clocks: local = true·(1 + skew_ppm·1e-6) + offset_s (scene::ClockTruth). IMU rows are sampled at
// regular LOCAL times; BLE and sync rows are stamped with the receiver's local clock.
//
// Determinism: every random stream is Rng::derive(Simulation::seed, "<stream name>"), the renderer is
// single-threaded and uses no time-dependent state: the same Simulation gives byte-identical files.
//
// Threading: a SceneSimulator is single-threaded [main]. Nothing here is real-time code.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "locus/dsp/signals.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"
#include "locus/sim/rng.hpp"
#include "locus/sim/trajectory.hpp"

namespace locus::sim {

struct Simulation;
struct DeviceModel;

// ------------------------------------------------------------------------------------------ responses

/// One equaliser section of a transducer response (RBJ audio-EQ-cookbook biquads): a peak/dip of
/// gain_db at freq_hz with quality q, or a high shelf of gain_db above freq_hz (slope 1).
struct EqSection {
  enum class Kind { Peaking, HighShelf };
  Kind kind = Kind::Peaking;
  double freq_hz = 1000.0;
  double gain_db = 0.0;
  double q = 1.0;  ///< peaking only
};

/// A speaker or microphone magnitude response: Butterworth band edges (0 disables an edge: {0, 0} =
/// flat, {f, 0} = high-pass, {0, f} = low-pass, {f1, f2} = band-pass) followed by equaliser
/// sections (the per-device ripple and high-frequency roll-off of a real transducer; see
/// response.hpp for random per-device responses).
struct BandLimit {
  BandLimit() = default;
  BandLimit(double low, double high, int order_ = 2, std::vector<EqSection> eq_ = {})
      : low_hz(low), high_hz(high), order(order_), eq(std::move(eq_)) {}
  double low_hz = 0.0;
  double high_hz = 0.0;
  int order = 2;  ///< Butterworth order of each edge
  std::vector<EqSection> eq;
  bool enabled() const noexcept { return low_hz > 0.0 || high_hz > 0.0 || !eq.empty(); }
};

// ------------------------------------------------------------------------------------------ sensors

/// One IMU reading in the body frame (Android conventions, gravity included in accel).
struct ImuReading {
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector3d> mag_ut;
  /// Row-stamp error: the row is written at the nominal local time + this (timestamp jitter; the
  /// reading itself is of the nominal instant). Must stay within ±0.5 sample period (rows in order).
  double stamp_offset_s = 0.0;
};

/// Produces a device's IMU readings. The engine calls sample() at the device's regular LOCAL sample
/// times (k / rate_hz on the device clock), in increasing order, converting to true time first.
/// `rng` is this device's private IMU stream.
class ImuModel {
 public:
  virtual ~ImuModel() = default;
  virtual double rate_hz() const = 0;
  virtual bool has_magnetometer() const { return false; }
  virtual ImuReading sample(const Simulation& sim, const DeviceModel& device, double t_true_s, Rng& rng) = 0;
};

/// Ideal kinematics of the device trajectory (specific force R^T·(a + g·z), body angular velocity,
/// R^T·magnetic field) plus per-device constant biases and white noise. Good enough for gestures and
/// handheld motion; richer models (step impacts, magnetic disturbances) live in the families.
struct KinematicImuConfig {
  double rate_hz = 100.0;
  double accel_noise_mps2 = 0.02;     ///< white noise sigma per sample
  double gyro_noise_radps = 0.002;
  double accel_bias_mps2 = 0.02;      ///< sigma of the constant bias drawn per device and axis
  double gyro_bias_radps = 0.001;
  bool magnetometer = false;          ///< needs Simulation::magnetic_field_world_ut
  double mag_noise_ut = 0.3;
  double gravity_mps2 = 9.80665;
};
class KinematicImu final : public ImuModel {
 public:
  explicit KinematicImu(KinematicImuConfig cfg = {}) : cfg_(cfg) {}
  double rate_hz() const override { return cfg_.rate_hz; }
  bool has_magnetometer() const override { return cfg_.magnetometer; }
  ImuReading sample(const Simulation& sim, const DeviceModel& device, double t_true_s, Rng& rng) override;

 private:
  KinematicImuConfig cfg_;
  bool biased_ = false;
  Eigen::Vector3d accel_bias_ = Eigen::Vector3d::Zero(), gyro_bias_ = Eigen::Vector3d::Zero();
};

/// One BLE advertisement as received (true time; the engine converts to the scanner's local clock).
struct BleReception {
  double t_true_s = 0.0;
  std::array<std::uint8_t, 6> address{};
  double rssi_dbm = 0.0;
  std::optional<double> tx_power_dbm;
  int channel = 0;  ///< 37..39, 0 = unknown
};

/// Produces what a scanning device receives over [t0, t1) of true time (the whole scene: called once).
/// Receptions may come in any order; the engine sorts them by time before writing ble.csv.
class BleScanModel {
 public:
  virtual ~BleScanModel() = default;
  virtual void scan(const Simulation& sim, const DeviceModel& observer, double t0_true_s, double t1_true_s,
                    Rng& rng, const std::function<void(const BleReception&)>& emit) = 0;
};

// ------------------------------------------------------------------------------------------ objects

/// A device: records sound (one channel per mic) and/or senses; may emit.
struct DeviceModel {
  std::string id;                                  ///< [A-Za-z0-9_-]+, unique among devices/emitters
  std::vector<Eigen::Vector3d> mics_body_m;        ///< body frame, channel order; empty = no audio
  std::optional<Eigen::Vector3d> speaker_body_m;   ///< body frame; absent = cannot emit
  std::vector<dsp::SignalSpec> emits;              ///< Emission::signal_index indexes this
  std::shared_ptr<const Trajectory> trajectory;    ///< required
  scene::ClockTruth clock;                         ///< truth; never visible to plugins
  bool record_audio = true;                        ///< write <id>/audio.wav (needs mics)
  double source_level = 1.0;                       ///< speaker loudness (1 = AcousticModel::level_at_1m at 1 m)
  double mic_gain = 1.0;                           ///< linear gain before clipping
  double self_gain = 1.0;                          ///< extra gain of the direct path of its OWN emissions to
                                                   ///< its own mics (coupling through the case: near-far)
  BandLimit speaker_response{300.0, 20000.0, 2};
  BandLimit mic_response{60.0, 20000.0, 2};
  std::shared_ptr<ImuModel> imu;                   ///< write <id>/imu.csv when set
  std::shared_ptr<BleScanModel> ble;               ///< write <id>/ble.csv when set
  bool record_sync = false;                        ///< write <id>/sync.csv (radio sync receptions)
  std::optional<Eigen::Vector3d> anchor_position_m;///< position KNOWN to the system (written to scene.yaml)
};

/// Something that transmits but records nothing (beacon loudspeaker, BLE tag). Its clock does not
/// matter (emission times are in true time); the speaker is at the body origin.
struct EmitterModel {
  std::string id;
  std::vector<dsp::SignalSpec> emits;
  std::shared_ptr<const Trajectory> trajectory;    ///< required
  double source_level = 1.0;
  BandLimit speaker_response{300.0, 20000.0, 2};
  std::optional<Eigen::Vector3d> anchor_position_m;///< known to the system (SpyLoc beacons); else unknown
};

// ------------------------------------------------------------------------------------------ acoustics

/// A shoebox room [0,Lx]×[0,Ly]×[0,Lz] (world frame): image sources up to max_order.
/// reflection = pressure reflection coefficient β of walls x=0, x=Lx, y=0, y=Ly, z=0 (floor), z=Lz.
struct Room {
  Eigen::Vector3d size_m{5.0, 5.0, 3.0};
  std::array<double, 6> reflection{0.7, 0.7, 0.7, 0.7, 0.7, 0.7};
  int max_order = 2;  ///< 0 = direct path only
  /// Diffuse reverberant tail beyond the image sources (off by default): per (emission, receiver,
  /// mic) a sparse random impulse response over [t_s, t_s + 5·τ] after the direct path (t_s =
  /// max_order·L_min/c: where the image sources thin out; τ = RT60/6.91 from Sabine with ᾱ = 1 − mean
  /// β² and the air absorption at the signal's centre frequency). Its taps are the room's reflections:
  /// as many as the echo density 4π c³ t² / V gives over that span (at most `tail_taps`), at times
  /// drawn with that t² density, amplitudes N(0,1)·e^(−t/τ)/(c t), scaled so that the tail's energy is
  /// the late part e^(−2 t_s/τ) of the Sabine diffuse-field energy 16π/A relative to the direct sound
  /// at 1 m (A = S·ᾱ + 4·m·V, the room's absorption area), and none louder than one path of its length
  /// with max_order + 1 reflections can be (β_max^(max_order+1)·e^(−κ c t)/(c t), times √(reflections per
  /// tap) when `tail_taps` caps the count): far from the source
  /// the tail holds more energy than the direct path, but no single late copy outshines it. Integer-sample tap delays: a diffuse field has no
  /// coherent arrival to time.
  bool diffuse_tail = false;
  int tail_taps = 3000;
  void set_reflection(double beta) { reflection.fill(beta); }
};

/// The direct path between a source and a receiving device is attenuated by attenuation_db during
/// [t_begin, t_end) of true emission start time (reflections are kept: NLOS, unless wall_m says which cross the obstacle). Symmetric in a/b.
struct Obstruction {
  std::string a, b;
  double attenuation_db = 20.0;
  double t_begin_s = -std::numeric_limits<double>::infinity();
  double t_end_s = std::numeric_limits<double>::infinity();
  /// The direct path is this much longer while obstructed (diffraction around an edge: the first
  /// path bends over it); 0 = only attenuated. Last, so aggregate initialisers {a, b, dB, t0, t1} keep
  /// their meaning.
  double extra_path_m = 0.0;
  /// The obstacle itself, when known: a partition from floor to ceiling along this horizontal segment
  /// (room coordinates, metres). Then every reflected path (image source) whose route in the room
  /// crosses it is attenuated by attenuation_db as well (a partition between a beacon and the walker
  /// also blocks the floor and ceiling reflections, which travel in the direct path's vertical plane);
  /// reflections that go around it (side walls) pass unchanged. Unset: reflections are never blocked.
  /// The direct path is blocked whenever the obstruction applies (the family decided it), whatever
  /// the segment.
  std::optional<std::array<Eigen::Vector2d, 2>> wall_m = std::nullopt;
};

/// Acoustic background noise at each microphone, relative to the reference level: snr_db is the SNR
/// of a unit-level source at 1 m (RMS of a full sine of amplitude level_at_1m) against the RMS of the
/// stationary noise. Noise is independent per device and channel.
struct NoiseModel {
  double snr_db = 40.0;
  double pink_fraction = 0.0;          ///< 0 = white, 1 = pink (−3 dB/octave), between = mix of powers
  double bursts_per_minute = 0.0;      ///< Poisson bursts of louder noise (clatter, speech, music)
  double burst_db = 12.0;              ///< burst level (RMS) above the stationary noise
  double burst_min_s = 0.05, burst_max_s = 0.4;
  /// What a burst is: White = independent white noise per channel (sine envelope); Babble / Music =
  /// interference.hpp waveforms (talkers with fricatives; notes with hi-hats), energy up to 20 kHz,
  /// the same waveform on every channel of the device; Mixed = babble or music, drawn per burst.
  enum class BurstKind { White, Babble, Music, Mixed };
  BurstKind burst_kind = BurstKind::White;
  /// Microphone self-noise: white, added after the microphone response (electrical), its level as
  /// the SNR of a unit-level source at 1 m like snr_db; nullopt = none.
  std::optional<double> self_noise_snr_db;
  bool enabled = true;
};

struct AcousticModel {
  double speed_of_sound_mps = 343.2;
  std::optional<Room> room;                        ///< none = free field
  std::vector<Obstruction> obstructions;
  NoiseModel noise;
  double level_at_1m = 0.1;                        ///< amplitude (full scale = 1) of a unit source at 1 m
  double min_distance_m = 0.01;                    ///< spreading is clamped below this distance
  bool band_limits = true;                         ///< apply speaker/mic BandLimits (tests turn off)
  /// Air absorption (ISO 9613-1 at temperature_c / humidity_pct, 101.325 kPa) of every path, as a
  /// gain 10^(−α(f_c)·r/20) at the emitted signal's centre frequency f_c (lfm: (f0+f1)/2, multitone:
  /// mean tone, gold: carrier): 0.47 dB/m at 19 kHz, 20 °C, 50 % RH. Off by default.
  bool air_absorption = false;
  double temperature_c = 20.0;
  double humidity_pct = 50.0;
};

/// ISO 9613-1 pure-tone atmospheric absorption in dB per metre at 101.325 kPa.
double air_absorption_db_per_m(double freq_hz, double temperature_c, double humidity_pct);

// ------------------------------------------------------------------------------------------ schedule

/// One emission: the source is told to play at t_command (true time) and the sound leaves the speaker
/// latency_s later (software/audio-stack latency; truth only, revealed by self-recordings).
/// A signal with sync_delay_s (SpyLoc) sends its radio sync at t_start − sync_delay_s.
struct Emission {
  std::string source_id;      ///< a device or emitter id
  int signal_index = 0;       ///< index into the source's emits
  double t_command_true_s = 0.0;
  double latency_s = 0.0;
  double gain = 1.0;          ///< extra linear gain of this emission
  double t_start_true_s() const noexcept { return t_command_true_s + latency_s; }
};

/// Uniform random latency in [min_s, max_s].
struct LatencyModel {
  double min_s = 0.02, max_s = 0.15;
  double draw(Rng& rng) const { return rng.uniform(min_s, max_s); }
};

// ------------------------------------------------------------------------------------------ simulation

/// Everything a scene is made of. A family builds one; SceneSimulator renders it.
struct Simulation {
  std::string name;                       ///< scene name (free text)
  std::uint64_t seed = 1;                 ///< all random streams derive from it
  double sample_rate_hz = 44100.0;
  double duration_s = 10.0;               ///< true-time length; every stream covers [0, duration)
  AcousticModel acoustics;
  std::vector<DeviceModel> devices;
  std::vector<EmitterModel> emitters;
  std::vector<Emission> emissions;        ///< any order
  scene::WavSampleFormat audio_format = scene::WavSampleFormat::Int16;
  double truth_rate_hz = 100.0;           ///< truth.csv rows per second for moving objects
  double radio_latency_s = 200e-6;        ///< sync reception: mean delay after sending
  double radio_jitter_s = 50e-6;          ///< sync reception: uniform ± jitter
  double radio_loss_probability = 0.0;    ///< sync reception: a sync is lost with this probability
  /// Radio messages not tied to an emission (Montage's start signal): (true send time, sender id),
  /// received by every device with record_sync like the emission syncs (latency, jitter, loss).
  std::vector<std::pair<double, std::string>> radio_broadcasts;
  std::optional<Eigen::Vector3d> magnetic_field_world_ut;
  std::string environment_yaml;           ///< extra free-form environment entries (YAML mapping text); the
                                          ///< room size is added automatically
  std::string family;                     ///< the system's name, written as environment.family (picks the eval metric)
  /// Extra evaluation-only files: name (relative to the scene dir) → full text, written verbatim by
  /// SceneSimulator::write (e.g. truth_steps.csv of the walking families, docs/simulator.md).
  std::map<std::string, std::string> extra_files;

  const DeviceModel* find_device(const std::string& id) const;
  const EmitterModel* find_emitter(const std::string& id) const;
};

/// Summary of a rendered scene.
struct WriteReport {
  std::string dir;
  std::uint64_t audio_frames_total = 0;   ///< over all devices
  std::size_t contributions = 0;          ///< (emission, receiving device) pairs rendered
  std::size_t paths = 0;                  ///< acoustic paths rendered (direct + images, all mics)
  std::size_t clipped_samples = 0;        ///< samples that hit full scale (self-recordings, usually)
  double seconds = 0.0;                   ///< wall time of write()
};

/// Renders a Simulation into a scene directory:
///   scene.yaml, <dev>/audio.wav, <dev>/imu.csv, <dev>/ble.csv, <dev>/sync.csv,
///   truth.csv (trajectories), truth_emissions.csv (t_true,id,signal_index,t_command,latency_s: the
///   emission schedule in true time, evaluation only).
class SceneSimulator {
 public:
  /// Validates the simulation (throws std::invalid_argument naming the object and field).
  explicit SceneSimulator(Simulation sim);
  const Simulation& simulation() const noexcept { return sim_; }

  /// Writes the scene into `out_dir` (created; existing files overwritten). Throws on I/O failure.
  WriteReport write(const std::string& out_dir) const;

  /// Renders frames [first_frame, first_frame + frames) of device `device_id`'s recording, planar:
  /// out[ch][i]. Exactly what write() puts in audio.wav (before quantisation), given the same
  /// simulation (the render is stateless across calls only when first_frame == 0; filters and noise
  /// run from frame 0, so this renders from 0 and returns the requested range). For tests.
  std::vector<std::vector<float>> render_audio(const std::string& device_id, std::uint64_t first_frame,
                                               std::size_t frames) const;

  /// Frames of device `d`'s recording: ceil(fs · local duration).
  std::uint64_t audio_frames(const DeviceModel& d) const;

  /// The true arrival time at microphone `mic` of `rx` of a sound leaving the speaker of `source_id`
  /// at true time te via the direct path (solves t − te = |p_mic(t) − p_spk(te)|/c). For tests/tools.
  double direct_arrival_true_s(const std::string& source_id, double te_true_s, const std::string& rx,
                               std::size_t mic) const;

 private:
  Simulation sim_;
};

/// World position of the speaker of source `id` (device speaker or emitter origin) at true time t.
Eigen::Vector3d speaker_position(const Simulation& sim, const std::string& id, double t_true_s);

}  // namespace locus::sim
