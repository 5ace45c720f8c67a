#include "scene/scene_sources.hpp"

#include <chrono>
#include <stdexcept>

#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"

namespace locus::hal::scene_replay {

namespace {

using Clock = std::chrono::steady_clock;

Clock::time_point at(Clock::time_point t0, double seconds) {
  return t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
}

/// Sleeps until `due` in short slices; false if `stop` was raised meanwhile.
bool wait_until(Clock::time_point due, const std::atomic<bool>& stop) {
  while (Clock::now() < due) {
    if (stop.load(std::memory_order_acquire)) return false;
    std::this_thread::sleep_until(std::min(due, Clock::now() + std::chrono::milliseconds(20)));
  }
  return !stop.load(std::memory_order_acquire);
}

}  // namespace

const ParamSchema& scene_source_schema() {
  static const ParamSchema schema{
      string_param("scene", std::monostate{}, "Scene directory (holding scene.yaml)."),
      string_param("device", std::monostate{}, "Device id in scene.yaml whose stream is replayed."),
      enum_param("speed", std::string("max"), {"max", "realtime"},
                 "max: as fast as the pipeline consumes, lossless and exactly time-ordered; realtime: paced by "
                 "the host clock like live hardware (a slow consumer loses data, counted)."),
  };
  return schema;
}

StreamRef resolve_stream(const Params& params, const std::string& stream) {
  StreamRef ref;
  ref.scene_dir = params.get_string("scene");
  ref.device = params.get_string("device");
  ref.speed = params.get_string("speed") == "realtime" ? Speed::Realtime : Speed::Max;
  locus::scene::Scene sc;
  try {
    sc = locus::scene::load_scene(ref.scene_dir);
  } catch (const locus::scene::SceneError& e) {
    throw std::runtime_error(e.what());
  }
  const locus::scene::DeviceSpec* d = sc.find_device(ref.device);
  if (d == nullptr) {
    std::string ids;
    for (const auto& dev : sc.devices) ids += (ids.empty() ? "" : ", ") + dev.id;
    throw std::runtime_error("scene " + ref.scene_dir + ": no device '" + ref.device + "' (devices: " +
                             (ids.empty() ? std::string("none") : ids) + ")");
  }
  const std::string& rel = stream == "audio" ? d->audio : stream == "imu" ? d->imu : stream == "ble" ? d->ble : d->sync;
  if (rel.empty()) {
    throw std::runtime_error("scene " + ref.scene_dir + ": device '" + ref.device + "' declares no " + stream +
                             " stream");
  }
  ref.path = sc.path(rel);
  ref.sample_rate_hz = sc.sample_rate_hz;
  ref.mic_count = d->mics_m.size();
  return ref;
}

// ------------------------------------------------------------------ audio

SceneAudioSource::SceneAudioSource() = default;
SceneAudioSource::~SceneAudioSource() { stop(); }

void SceneAudioSource::open(const Params& params, HostContext& ctx) {
  if (thread_.joinable()) throw std::runtime_error("scene_audio: open() while running");
  const StreamRef ref = resolve_stream(params, "audio");
  try {
    reader_ = std::make_unique<locus::scene::WavReader>(ref.path);
  } catch (const locus::scene::SceneError& e) {
    throw std::runtime_error(e.what());
  }
  const locus::scene::WavInfo& info = reader_->info();
  if (std::abs(info.sample_rate_hz - ref.sample_rate_hz) > 1e-6) {
    throw std::runtime_error(ref.path + ": sample rate " + std::to_string(info.sample_rate_hz) +
                             " Hz, but scene.yaml says sample_rate " + std::to_string(ref.sample_rate_hz));
  }
  if (ref.mic_count != 0 && static_cast<std::size_t>(info.channels) != ref.mic_count) {
    throw std::runtime_error(ref.path + ": " + std::to_string(info.channels) + " channels, but device '" +
                             ref.device + "' declares " + std::to_string(ref.mic_count) +
                             " mics (one channel per mic expected)");
  }
  channels_ = static_cast<std::uint32_t>(info.channels);
  rate_hz_ = info.sample_rate_hz;
  speed_ = ref.speed;
  block_.assign(kBlockFrames * channels_, 0.0f);
  ctx.log.debug("scene_audio: " + ref.path + ", " + std::to_string(info.frames) + " frames, " +
                std::to_string(channels_) + " ch");
}

std::string SceneAudioSource::error() const {
  std::lock_guard lock(error_mutex_);
  return error_;
}

void SceneAudioSource::fail(std::string message) {
  std::lock_guard lock(error_mutex_);
  if (error_.empty()) error_ = std::move(message);
}

void SceneAudioSource::start(AudioRing& ring) {
  if (!reader_) throw std::runtime_error("scene_audio: start() before open()");
  if (thread_.joinable()) throw std::runtime_error("scene_audio: start() while already running");
  if (ring.channels() != channels_) {
    throw std::runtime_error("scene_audio: ring has " + std::to_string(ring.channels()) + " channels, source has " +
                             std::to_string(channels_));
  }
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  thread_ = std::thread([this, &ring] { run(ring); });
}

void SceneAudioSource::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SceneAudioSource::run(AudioRing& ring) {
  const Clock::time_point t0 = Clock::now();
  std::uint64_t next = 0;
  try {
    for (;;) {
      if (stop_.load(std::memory_order_acquire)) return;  // stopped: not finished, nothing more is written
      const std::size_t n = reader_->read(block_.data(), kBlockFrames);
      if (n == 0) break;
      if (speed_ == Speed::Realtime) {
        // A sound card hands a block over once its last frame has been captured.
        if (!wait_until(at(t0, static_cast<double>(next + n) / rate_hz_), stop_)) return;
        ring.write(block_.data(), n);  // what does not fit is reported lost
      } else {
        std::size_t done = 0;
        while (done < n) {
          AudioRing::WriteSpan span = ring.write_acquire(n - done);
          if (span.frames() == 0) {
            if (stop_.load(std::memory_order_acquire)) return;
            std::this_thread::sleep_for(std::chrono::microseconds(100));
            continue;
          }
          std::size_t k = done * channels_;
          for (const auto& seg : {span.first, span.second}) {
            std::copy_n(block_.data() + k, seg.frames * channels_, seg.data);
            k += seg.frames * channels_;
          }
          ring.write_commit(span.frames());
          done += span.frames();
        }
      }
      next += n;
      produced_.store(next, std::memory_order_release);
    }
    if (reader_->truncated()) fail(reader_->truncation_message());
  } catch (const std::exception& e) {
    fail(e.what());
  }
  finished_.store(true, std::memory_order_release);
}

// ------------------------------------------------------------------ sensors

struct SceneSensorSource::Reader {
  std::unique_ptr<locus::scene::ImuCsvReader> imu;
  std::unique_ptr<locus::scene::BleCsvReader> ble;
  std::unique_ptr<locus::scene::SyncCsvReader> sync;
  /// Next event; false at the end. Throws SceneError.
  bool next(Event& out) {
    if (imu) {
      ImuSample s;
      if (!imu->next(s)) return false;
      out = s;
      return true;
    }
    if (ble) {
      BleAdvertisement a;
      if (!ble->next(a)) return false;
      out = a;
      return true;
    }
    RadioSync r;
    if (!sync->next(r)) return false;
    out = r;
    return true;
  }
};

SceneSensorSource::SceneSensorSource(SensorKind kind) : kind_(kind) {}
SceneSensorSource::~SceneSensorSource() { stop(); }

void SceneSensorSource::open(const Params& params, HostContext& ctx) {
  const std::string name = "scene_" + std::string(sensor_kind_name(kind_));
  if (thread_.joinable()) throw std::runtime_error(name + ": open() while running");
  const StreamRef ref = resolve_stream(params, std::string(sensor_kind_name(kind_)));
  auto reader = std::make_unique<Reader>();
  const DeviceId device(ref.device);
  try {
    switch (kind_) {
      case SensorKind::Imu: reader->imu = std::make_unique<locus::scene::ImuCsvReader>(ref.path, device); break;
      case SensorKind::Ble: reader->ble = std::make_unique<locus::scene::BleCsvReader>(ref.path, device); break;
      case SensorKind::Sync: reader->sync = std::make_unique<locus::scene::SyncCsvReader>(ref.path, device); break;
    }
  } catch (const locus::scene::SceneError& e) {
    throw std::runtime_error(e.what());
  }
  reader_ = std::move(reader);
  speed_ = ref.speed;
  ctx.log.debug(name + ": " + ref.path);
}

std::string SceneSensorSource::error() const {
  std::lock_guard lock(error_mutex_);
  return error_;
}

void SceneSensorSource::fail(std::string message) {
  std::lock_guard lock(error_mutex_);
  if (error_.empty()) error_ = std::move(message);
}

void SceneSensorSource::start(SensorQueue& queue) {
  if (!reader_) throw std::runtime_error("scene sensor source: start() before open()");
  if (thread_.joinable()) throw std::runtime_error("scene sensor source: start() while already running");
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  thread_ = std::thread([this, &queue] { run(queue); });
}

void SceneSensorSource::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
}

void SceneSensorSource::run(SensorQueue& queue) {
  const Clock::time_point t0 = Clock::now();
  std::uint64_t count = 0;
  try {
    Event e;
    while (reader_->next(e)) {
      if (stop_.load(std::memory_order_acquire)) return;
      if (speed_ == Speed::Realtime) {
        if (!wait_until(at(t0, sensor_event_time_s(e)), stop_)) return;
        if (!queue.try_push(e)) queue.count_drop();
      } else {
        while (!queue.try_push(e)) {
          if (stop_.load(std::memory_order_acquire)) return;
          std::this_thread::sleep_for(std::chrono::microseconds(100));
        }
      }
      produced_.store(++count, std::memory_order_release);
    }
  } catch (const std::exception& ex) {
    fail(ex.what());
  }
  finished_.store(true, std::memory_order_release);
}

// ------------------------------------------------------------------ registration

void register_scene_sources(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "scene_audio",
      "scene replay: <device>/audio.wav of a scene directory (speed max: lossless; realtime: paced like a sound card)",
      scene_source_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<SceneAudioSource>()); },
  });
  const std::pair<SensorKind, const char*> kinds[] = {
      {SensorKind::Imu, "scene replay: <device>/imu.csv of a scene directory (ImuSample)"},
      {SensorKind::Ble, "scene replay: <device>/ble.csv of a scene directory (BleAdvertisement)"},
      {SensorKind::Sync, "scene replay: <device>/sync.csv of a scene directory (RadioSync)"},
  };
  for (const auto& [kind, description] : kinds) {
    const SensorKind k = kind;
    registry.add_sensor_source(SensorSourceDescriptor{
        "scene_" + std::string(sensor_kind_name(k)),
        description,
        k,
        scene_source_schema(),
        [k] { return std::unique_ptr<SensorSource>(std::make_unique<SceneSensorSource>(k)); },
    });
  }
}

}  // namespace locus::hal::scene_replay
