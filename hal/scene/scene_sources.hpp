// Scene replay sources: a scene directory (docs/scene-format.md) played back into the pipeline as if
// the device's microphones, IMU, BLE scanner and radio-sync receiver were live.
//
//   scene_audio  AudioSource   <device>/audio.wav through WavReader, block by block
//   scene_imu    SensorSource  <device>/imu.csv   -> ImuSample
//   scene_ble    SensorSource  <device>/ble.csv   -> BleAdvertisement
//   scene_sync   SensorSource  <device>/sync.csv  -> RadioSync
//
// Params (all four): `scene` (the directory), `device` (its id in scene.yaml), `speed`:
//   max       as fast as the pipeline consumes (live() == false: waits for ring/queue space, loses
//             nothing, and the detector thread interleaves the streams exactly by local time);
//   realtime  paced by the host's steady clock from start(): audio frame k is handed over at k / fs
//             after start (in blocks, like a sound card), a sensor event at t_s after start (t_s < 0:
//             at once); live() == true, so a slow consumer loses frames / events (counted).
//
// Files are streamed (one block or row in memory). open() validates scene.yaml and the file header
// (errors thrown, naming file:line:column or byte offset). A problem found mid-stream (a malformed
// CSV row, an I/O error, a truncated WAV) ends the stream after everything before it was delivered;
// error() then names the file and the line:column / byte offset.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "locus/audio_source.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"

namespace locus::scene {
class WavReader;
}

namespace locus::hal::scene_replay {

enum class Speed : std::uint8_t { Max, Realtime };

/// The parameter schema shared by the four sources.
const ParamSchema& scene_source_schema();

/// What the params name, validated: the resolved stream file of `device` for `stream`
/// ("audio", "imu", "ble", "sync"). Throws std::runtime_error (a SceneError's text included) when the
/// scene is malformed, the device is unknown or does not record that stream.
struct StreamRef {
  std::string scene_dir;
  std::string device;
  std::string path;
  Speed speed = Speed::Max;
  double sample_rate_hz = 0.0;  ///< the scene's sample_rate
  std::size_t mic_count = 0;
};
StreamRef resolve_stream(const Params& params, const std::string& stream);

class SceneAudioSource final : public AudioSource {
 public:
  static constexpr std::size_t kBlockFrames = 1024;
  SceneAudioSource();
  ~SceneAudioSource() override;

  void open(const Params& params, HostContext& ctx) override;
  std::uint32_t channels() const override { return channels_; }
  double sample_rate_hz() const override { return rate_hz_; }
  bool live() const override { return speed_ == Speed::Realtime; }
  void start(AudioRing& ring) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override;

  std::uint64_t frames_produced() const noexcept { return produced_.load(std::memory_order_acquire); }

 private:
  void run(AudioRing& ring);
  void fail(std::string message);

  std::unique_ptr<locus::scene::WavReader> reader_;
  std::uint32_t channels_ = 0;
  double rate_hz_ = 0.0;
  Speed speed_ = Speed::Max;
  std::vector<float> block_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::uint64_t> produced_{0};
  mutable std::mutex error_mutex_;
  std::string error_;
};

/// One CSV stream (imu, ble or sync) of a scene device.
class SceneSensorSource final : public SensorSource {
 public:
  explicit SceneSensorSource(SensorKind kind);
  ~SceneSensorSource() override;

  void open(const Params& params, HostContext& ctx) override;
  SensorKind kind() const override { return kind_; }
  bool live() const override { return speed_ == Speed::Realtime; }
  void start(SensorQueue& queue) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override;

  std::uint64_t events_produced() const noexcept { return produced_.load(std::memory_order_acquire); }

 private:
  struct Reader;  // the typed CSV reader
  void run(SensorQueue& queue);
  void fail(std::string message);

  SensorKind kind_;
  Speed speed_ = Speed::Max;
  std::unique_ptr<Reader> reader_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::uint64_t> produced_{0};
  mutable std::mutex error_mutex_;
  std::string error_;
};

/// Registers scene_audio, scene_imu, scene_ble and scene_sync.
void register_scene_sources(Registry& registry);

}  // namespace locus::hal::scene_replay
