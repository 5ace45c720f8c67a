// The recorder behind `locus record` (see record.hpp for the design, docs/record.md for the user view).
#include "record/record.hpp"

#include <pthread.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <mutex>
#include <set>
#include <thread>

#include "app.hpp"
#include "locus/fftw_planner.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/logging.hpp"
#include "locus/build_options.hpp"
#include "scene/scene_sources.hpp"
#if LOCUS_HAVE_ALSA
#include "alsa/alsa_source.hpp"
#endif

namespace fs = std::filesystem;

namespace locus::app {

namespace {

constexpr std::size_t kBlockFrames = 4096;  // frames per WAV write
constexpr std::size_t kEventsPerPass = 512;  // sensor events per queue per writer pass

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

double steady_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Prepares `dir` for a new scene: created if absent; an existing empty directory is used; an existing
/// scene directory is emptied only with `overwrite`; anything else is refused.
void prepare_out_dir(const std::string& dir, bool overwrite) {
  std::error_code ec;
  const fs::path p(dir);
  if (!fs::exists(p, ec)) {
    fs::create_directories(p, ec);
    if (ec) throw std::runtime_error(dir + ": cannot create the scene directory: " + ec.message());
    return;
  }
  if (!fs::is_directory(p, ec)) throw std::runtime_error(dir + ": exists and is not a directory");
  if (fs::is_empty(p, ec)) return;
  if (!overwrite) {
    throw std::runtime_error(dir + ": exists and is not empty (pass --overwrite to replace a previous recording)");
  }
  if (!fs::exists(p / "scene.yaml", ec)) {
    throw std::runtime_error(dir + ": refusing to overwrite a directory that is not a scene (it has no scene.yaml)");
  }
  for (const auto& entry : fs::directory_iterator(p, ec)) {
    fs::remove_all(entry.path(), ec);
    if (ec) throw std::runtime_error(entry.path().string() + ": cannot remove: " + ec.message());
  }
  if (ec) throw std::runtime_error(dir + ": cannot list: " + ec.message());
}

}  // namespace

bool parse_sample_format(const std::string& s, scene::WavSampleFormat& out) {
  if (s == "float32") out = scene::WavSampleFormat::Float32;
  else if (s == "int16") out = scene::WavSampleFormat::Int16;
  else if (s == "int24") out = scene::WavSampleFormat::Int24;
  else if (s == "int32") out = scene::WavSampleFormat::Int32;
  else return false;
  return true;
}

scene::WavSampleFormat native_sample_format(const std::string& source, const Params& params,
                                            const AudioSource* opened) {
#if LOCUS_HAVE_ALSA
  if (const auto* alsa = dynamic_cast<const hal::alsa::AlsaSource*>(opened); alsa != nullptr) {
    // What the PCM was actually configured to (format: auto negotiates).
    switch (alsa->setup().format) {
      case hal::alsa::SampleFormat::S16: return scene::WavSampleFormat::Int16;
      case hal::alsa::SampleFormat::S24:
      case hal::alsa::SampleFormat::S24_3: return scene::WavSampleFormat::Int24;
      case hal::alsa::SampleFormat::S32: return scene::WavSampleFormat::Int32;
      case hal::alsa::SampleFormat::Float: return scene::WavSampleFormat::Float32;
    }
  }
#else
  (void)opened;  // no ALSA source can have been opened
#endif
  if (source == "scene_audio") {
    // The scene's own file: keep its encoding (a replayed int16 recording stays int16, bit-exact).
    try {
      const auto ref = hal::scene_replay::resolve_stream(params, "audio");
      return scene::read_wav_info(ref.path).sample_format;
    } catch (const std::exception&) {
      return scene::WavSampleFormat::Float32;  // open() reports the problem with the source's own message
    }
  }
  for (const char* key : {"sample_format", "format"}) {
    const auto it = params.values().find(std::string_view(key));
    if (it == params.values().end() || !std::holds_alternative<std::string>(it->second)) continue;
    const std::string f = lower(std::get<std::string>(it->second));
    if (f.find("float") != std::string::npos || f == "f32" || f.rfind("f32", 0) == 0) return scene::WavSampleFormat::Float32;
    if (f.find("16") != std::string::npos) return scene::WavSampleFormat::Int16;
    if (f.find("24") != std::string::npos) return scene::WavSampleFormat::Int24;
    if (f.find("32") != std::string::npos) return scene::WavSampleFormat::Int32;
  }
  return scene::WavSampleFormat::Float32;
}

// ---------------------------------------------------------------------------------------------------

/// The host services a source's open() gets (the recorder runs no plugins: nothing is published).
struct Recorder::Host {
  SteadyClock clock;
  FftwPlanner fft{"", false};
  InProcessLink link;
};

struct Recorder::Device {
  std::string id;
  std::string dir;  // OUT/<id>
  std::optional<GeometryConfig> geometry;

  // audio
  std::string audio_name;
  std::unique_ptr<SpdLogger> audio_log;
  std::unique_ptr<AudioSource> audio;
  std::unique_ptr<AudioRing> ring;
  std::unique_ptr<scene::WavWriter> wav;
  std::unique_ptr<scene::CsvWriter> gaps_csv;
  scene::WavSampleFormat format = scene::WavSampleFormat::Float32;
  std::uint32_t channels = 0;
  double rate_hz = 0.0;
  std::uint64_t limit = UINT64_MAX;  // frames kept (--duration)
  // writer-thread state, read by the main thread only after the join (or through the atomics)
  std::uint64_t next_frame = 0;      // frames in the WAV = stream frame of the next frame to write
  std::uint64_t lost = 0;
  std::uint64_t discarded = 0;
  std::vector<RecordedGap> gaps;
  std::atomic<std::uint64_t> frames_written{0};
  std::atomic<bool> limit_reached{false};

  /// How a sensor stream's times reach the file (pipeline.hpp, "Time base"): as the source stamps
  /// them, or moved from CLOCK_MONOTONIC onto the audio timeline (t - frame_zero_monotonic_s()).
  enum class TimeBase : std::uint8_t { AsIs, Pending, Audio, Monotonic };

  struct Sensor {
    SensorKind kind = SensorKind::Imu;
    TimeBase time_base = TimeBase::AsIs;
    std::vector<Event> held;          // Pending: popped before the audio knew its origin
    std::uint64_t untranslated = 0;   // written on CLOCK_MONOTONIC because the audio never gave an origin
    std::string name;
    std::unique_ptr<SpdLogger> log;
    std::unique_ptr<SensorSource> source;
    std::unique_ptr<SensorQueue> queue;
    std::unique_ptr<scene::ImuCsvWriter> imu;
    std::unique_ptr<scene::BleCsvWriter> ble;
    std::unique_ptr<scene::SyncCsvWriter> sync;
    std::uint64_t rows = 0;
    double last_t = -1e300;
    std::uint64_t out_of_order = 0;
  };
  std::vector<Sensor> sensors;

  std::thread thread;
  std::atomic<bool> inputs_stopped{false};  // every source of the device is stopped (release)
  std::atomic<bool> done{false};            // the writer drained everything and closed the files
  mutable std::mutex error_mutex;
  std::string writer_error;

  std::vector<float> zeros;  // kBlockFrames · channels

  void set_error(const std::string& e) {
    std::lock_guard lock(error_mutex);
    if (writer_error.empty()) writer_error = e;
  }
  std::string get_error() const {
    std::lock_guard lock(error_mutex);
    return writer_error;
  }

  /// Zeros for `frames` lost frames starting at stream frame `frame` (clipped to the limit).
  void write_gap(std::uint64_t frame, std::uint64_t frames) {
    if (next_frame >= limit) {
      discarded += frames;
      return;
    }
    if (frame < next_frame) {
      throw std::logic_error(dir + "/audio.wav: the stream went back from frame " + std::to_string(next_frame) +
                             " to " + std::to_string(frame));
    }
    if (frame > next_frame) write_gap(next_frame, frame - next_frame);  // a loss nobody reported
    const std::uint64_t keep = std::min(frames, limit - std::min(limit, next_frame));
    discarded += frames - keep;
    if (keep == 0) return;
    gaps.push_back({next_frame, keep});
    gaps_csv->row({std::to_string(next_frame), std::to_string(keep)});
    lost += keep;
    for (std::uint64_t left = keep; left > 0;) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, kBlockFrames));
      wav->write(zeros.data(), n);
      left -= n;
    }
    next_frame += keep;
    publish_progress();
  }

  /// Frames [frame, frame + n) as delivered by the ring (clipped to the limit).
  void write_frames(std::uint64_t frame, const float* data, std::size_t n) {
    if (next_frame >= limit) {
      discarded += n;
      return;
    }
    if (frame < next_frame) {
      throw std::logic_error(dir + "/audio.wav: the stream went back from frame " + std::to_string(next_frame) +
                             " to " + std::to_string(frame));
    }
    if (frame > next_frame) write_gap(next_frame, frame - next_frame);  // a loss nobody reported
    if (next_frame >= limit) {
      discarded += n;
      return;
    }
    const std::uint64_t keep = std::min<std::uint64_t>(n, limit - next_frame);
    discarded += n - keep;
    wav->write(data, static_cast<std::size_t>(keep));
    next_frame += keep;
    publish_progress();
  }

  void publish_progress() {
    frames_written.store(next_frame, std::memory_order_relaxed);
    if (next_frame >= limit) limit_reached.store(true, std::memory_order_release);
  }

  /// One pass over the ring; true if anything moved.
  bool drain_audio() {
    if (!ring) return false;
    bool moved = false;
    for (int pass = 0; pass < 16; ++pass) {
      const AudioRing::ReadSpan span = ring->read_acquire(kBlockFrames);
      if (span.lost_before != 0) {
        write_gap(span.first_frame - span.lost_before, span.lost_before);
        moved = true;
      }
      const std::size_t n = span.frames();
      if (n == 0) break;
      write_frames(span.first_frame, span.first.data, span.first.frames);
      if (span.second.frames != 0) write_frames(span.first_frame + span.first.frames, span.second.data, span.second.frames);
      ring->read_release(n);
      moved = true;
    }
    return moved;
  }

  /// Events held longer than this while the audio has no origin are written on CLOCK_MONOTONIC.
  static constexpr std::size_t kMaxHeldEvents = std::size_t{1} << 20;

  double audio_origin_s() const noexcept { return audio ? audio->frame_zero_monotonic_s() : kNaN; }

  void write_event(Sensor& s, Event& e) {
    if (s.time_base == TimeBase::Audio) shift_sensor_event_time(e, -audio_origin_s());
    if (s.time_base == TimeBase::Monotonic) ++s.untranslated;
    if (const auto* imu = std::get_if<ImuSample>(&e); imu != nullptr && s.imu) {
      if (imu->t_s < s.last_t) ++s.out_of_order;
      s.last_t = imu->t_s;
      s.imu->write(*imu);
    } else if (const auto* ble = std::get_if<BleAdvertisement>(&e); ble != nullptr && s.ble) {
      s.ble->write(*ble);
    } else if (const auto* sync = std::get_if<RadioSync>(&e); sync != nullptr && s.sync) {
      s.sync->write(*sync);
    } else {
      throw std::runtime_error("sensor source '" + s.name + "' pushed a " + std::string(event_type_name(type_of(e))) +
                               " event into its " + std::string(sensor_kind_name(s.kind)) + " stream");
    }
    ++s.rows;
  }

  /// A Pending stream whose audio now has an origin (or never will: `give_up`) writes what it held.
  void settle_time_base(Sensor& s, bool give_up) {
    if (s.time_base != TimeBase::Pending) return;
    if (std::isfinite(audio_origin_s())) {
      s.time_base = TimeBase::Audio;
    } else if (give_up || s.held.size() >= kMaxHeldEvents) {
      s.time_base = TimeBase::Monotonic;
    } else {
      return;
    }
    for (Event& e : s.held) write_event(s, e);
    s.held.clear();
    s.held.shrink_to_fit();
  }

  bool drain_sensors() {
    bool moved = false;
    for (Sensor& s : sensors) {
      settle_time_base(s, false);
      Event e;
      for (std::size_t i = 0; i < kEventsPerPass && s.queue->try_pop(e); ++i) {
        moved = true;
        if (s.time_base == TimeBase::Pending) {
          s.held.push_back(e);
          settle_time_base(s, false);
        } else {
          write_event(s, e);
        }
      }
    }
    return moved;
  }

  bool all_finished() const noexcept {
    if (audio && !audio->finished()) return false;
    for (const Sensor& s : sensors) {
      if (!s.source->finished()) return false;
    }
    return true;
  }

  /// After the sources stopped or finished: frames the producer counted but never reported (a loss
  /// still pending in the ring when the stream ended) become a trailing gap.
  void write_trailing_loss() {
    if (!ring) return;
    const std::uint64_t produced = ring->producer_frame();
    if (produced > next_frame && next_frame < limit) write_gap(next_frame, produced - next_frame);
  }

  void close_files() {
    if (wav) wav->close();
    if (gaps_csv) gaps_csv->close();
    for (Sensor& s : sensors) {
      if (s.imu) s.imu->close();
      if (s.ble) s.ble->close();
      if (s.sync) s.sync->close();
    }
  }
};

void Recorder::run_writer(Device& d) {
  try {
    for (;;) {
      // Snapshot the end conditions first: whatever was handed over before them is drained below.
      const bool stopped = d.inputs_stopped.load(std::memory_order_acquire);
      const bool finished = d.all_finished();
      const bool moved_audio = d.drain_audio();
      const bool moved_sensors = d.drain_sensors();
      if (moved_audio || moved_sensors) continue;
      if (stopped || finished) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    d.write_trailing_loss();
    for (auto& s : d.sensors) d.settle_time_base(s, true);
    d.close_files();
  } catch (const std::exception& e) {
    d.set_error(e.what());
    try {
      d.close_files();  // keep what was written readable
    } catch (const std::exception&) {
    }
  }
  d.done.store(true, std::memory_order_release);
}

Recorder::Recorder(const Config& config, const Registry& registry, RecorderSettings settings)
    : settings_(std::move(settings)), host_(std::make_unique<Host>()) {
  if (settings_.out_dir.empty()) throw std::runtime_error("no output directory given");
  if (settings_.duration_s && !(*settings_.duration_s > 0.0 && std::isfinite(*settings_.duration_s))) {
    throw std::runtime_error("--duration must be a positive number of seconds");
  }
  // Open every source first: a bad device fails before anything touches the disk.
  std::optional<double> rate;
  std::string rate_device;
  for (const DeviceConfig& dc : config.devices) {
    if (dc.is_template()) continue;
    auto d = std::make_unique<Device>();
    d->id = dc.id;
    d->geometry = dc.geometry;
    if (dc.audio) {
      const AudioConfig& ac = *dc.audio;
      d->audio_name = ac.source;
      d->audio_log = std::make_unique<SpdLogger>(dc.id + "/" + ac.source);
      HostContext ctx{*d->audio_log, host_->clock, host_->fft, host_->link, ac.source, dc.id, nullptr};
      try {
        d->audio = registry.create_source(ac.source);
        d->audio->open(ac.params, ctx);
      } catch (const std::exception& e) {
        throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "': " + e.what());
      }
      d->channels = d->audio->channels();
      d->rate_hz = d->audio->sample_rate_hz();
      if (d->channels == 0) throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "' has 0 channels");
      if (!(d->rate_hz > 0.0) || d->rate_hz != std::floor(d->rate_hz)) {
        throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "' runs at " +
                                 scene::format_double(d->rate_hz) + " Hz; a WAV file needs a whole number of Hz");
      }
      if (std::abs(d->rate_hz - config.sample_rate_hz) > 1e-6) {
        throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "' runs at " +
                                 scene::format_double(d->rate_hz) + " Hz but the node is configured for " +
                                 scene::format_double(config.sample_rate_hz) + " Hz (sample_rate_hz)");
      }
      if (rate && *rate != d->rate_hz) {
        throw std::runtime_error("device '" + dc.id + "' records at " + scene::format_double(d->rate_hz) +
                                 " Hz but device '" + rate_device + "' at " + scene::format_double(*rate) +
                                 " Hz; a scene has one sample rate");
      }
      if (dc.geometry && !dc.geometry->mics_m.empty() && dc.geometry->mics_m.size() != d->channels) {
        throw std::runtime_error("device '" + dc.id + "': geometry.mics_m places " +
                                 std::to_string(dc.geometry->mics_m.size()) + " microphones but audio source '" +
                                 ac.source + "' delivers " + std::to_string(d->channels) +
                                 " channels (expected one x y z triple per channel)");
      }
      rate = d->rate_hz;
      rate_device = dc.id;
      d->format = settings_.sample_format ? *settings_.sample_format : native_sample_format(ac.source, ac.params, d->audio.get());
      d->ring = std::make_unique<AudioRing>(d->channels, std::max<std::size_t>(ac.ring_frames, settings_.min_ring_frames));
      if (settings_.duration_s) d->limit = static_cast<std::uint64_t>(std::llround(*settings_.duration_s * d->rate_hz));
    }
    for (const SensorKind kind : {SensorKind::Imu, SensorKind::Ble, SensorKind::Sync}) {
      const std::optional<SensorConfig>& sc = dc.sensor(kind);
      if (!sc) continue;
      Device::Sensor s;
      s.kind = kind;
      s.name = sc->source;
      s.log = std::make_unique<SpdLogger>(dc.id + "/" + sc->source);
      HostContext ctx{*s.log, host_->clock, host_->fft, host_->link, sc->source, dc.id, nullptr};
      try {
        s.source = registry.create_sensor_source(sc->source);
        if (s.source->kind() != kind) {
          throw std::runtime_error("produces " + std::string(sensor_kind_name(s.source->kind())) + " events");
        }
        s.source->open(sc->params, ctx);
      } catch (const std::exception& e) {
        throw std::runtime_error("device '" + dc.id + "': " + std::string(sensor_kind_name(kind)) + " source '" +
                                 sc->source + "': " + e.what());
      }
      s.queue = std::make_unique<SensorQueue>(sc->queue_capacity);
      // Live sensors stamp CLOCK_MONOTONIC; next to live audio the scene wants the audio's timeline.
      if (s.source->monotonic_time() && d->audio && d->audio->live()) s.time_base = Device::TimeBase::Pending;
      d->sensors.push_back(std::move(s));
    }
    if (!d->audio && d->sensors.empty()) {
      host_logger()->warn("device '{}' has no stream (audio, imu, ble or sync): nothing to record for it", dc.id);
      continue;
    }
    devices_.push_back(std::move(d));
  }
  if (devices_.empty()) {
    throw std::runtime_error("the config has no device with a stream (audio, imu, ble or sync): nothing to record");
  }

  // The scene directory and its files.
  prepare_out_dir(settings_.out_dir, settings_.overwrite);
  scene_.dir = settings_.out_dir;
  scene_.name = settings_.name.empty() ? fs::path(settings_.out_dir).lexically_normal().filename().string()
                                       : settings_.name;
  if (scene_.name.empty() || scene_.name == ".") scene_.name = fs::absolute(settings_.out_dir).lexically_normal().parent_path().filename().string();
  scene_.sample_rate_hz = rate ? *rate : config.sample_rate_hz;
  for (auto& dp : devices_) {
    Device& d = *dp;
    d.dir = (fs::path(settings_.out_dir) / d.id).string();
    std::error_code ec;
    fs::create_directories(d.dir, ec);
    if (ec) throw std::runtime_error(d.dir + ": cannot create: " + ec.message());
    scene::DeviceSpec spec;
    spec.id = d.id;
    if (d.geometry) {
      if (d.geometry->speaker_m) spec.speaker_m = *d.geometry->speaker_m;
      if (d.geometry->anchor_m) spec.anchor_position_m = *d.geometry->anchor_m;
    }
    if (d.audio) {
      // The config's geometry.mics_m; without it, every channel at the body origin (docs/record.md).
      if (d.geometry && !d.geometry->mics_m.empty()) {
        spec.mics_m.assign(d.geometry->mics_m.begin(), d.geometry->mics_m.end());
      } else {
        spec.mics_m.assign(d.channels, scene::Vec3{0.0, 0.0, 0.0});
        host_logger()->info("device '{}': no geometry.mics_m in the config: its {} channel(s) are written as mics at "
                            "the body origin", d.id, d.channels);
      }
      spec.audio = d.id + "/audio.wav";
      d.wav = std::make_unique<scene::WavWriter>(scene_.path(spec.audio), static_cast<int>(d.channels), d.rate_hz, d.format);
      d.gaps_csv = std::make_unique<scene::CsvWriter>(d.dir + "/gaps.csv", std::vector<std::string>{"frame", "frames"});
      d.zeros.assign(kBlockFrames * d.channels, 0.0f);
    }
    for (Device::Sensor& s : d.sensors) {
      const std::string rel = d.id + "/" + std::string(sensor_kind_name(s.kind)) + ".csv";
      const std::string path = scene_.path(rel);
      switch (s.kind) {
        case SensorKind::Imu:
          spec.imu = rel;
          s.imu = std::make_unique<scene::ImuCsvWriter>(path, true);
          break;
        case SensorKind::Ble:
          spec.ble = rel;
          s.ble = std::make_unique<scene::BleCsvWriter>(path);
          break;
        case SensorKind::Sync:
          spec.sync = rel;
          s.sync = std::make_unique<scene::SyncCsvWriter>(path);
          break;
      }
    }
    scene_.devices.push_back(std::move(spec));
  }
  scene::write_scene_yaml(scene_);
}

Recorder::~Recorder() {
  try {
    stop("destroyed");
  } catch (...) {
  }
}

void Recorder::start() {
  if (started_) return;
  started_ = true;
  started_utc_ = utc_now();
  start_s_ = steady_s();
  for (auto& dp : devices_) {
    Device* d = dp.get();
    d->thread = std::thread([this, d] { run_writer(*d); });
  }
  for (auto& dp : devices_) {
    if (dp->audio) dp->audio->start(*dp->ring);
    for (auto& s : dp->sensors) s.source->start(*s.queue);
  }
}

double Recorder::elapsed_s() const { return started_ ? steady_s() - start_s_ : 0.0; }

std::string Recorder::completion_reason() const {
  if (!started_) return {};
  bool all_done = true;
  for (const auto& d : devices_) all_done = all_done && d->done.load(std::memory_order_acquire);
  if (all_done) return "end of streams";
  if (!settings_.duration_s) return {};
  bool any_audio = false;
  bool all_reached = true;
  for (const auto& d : devices_) {
    if (!d->audio) continue;
    any_audio = true;
    const bool ended = d->done.load(std::memory_order_acquire) || d->audio->finished();
    all_reached = all_reached && (ended || d->limit_reached.load(std::memory_order_acquire));
  }
  if (any_audio ? all_reached : elapsed_s() >= *settings_.duration_s) return "duration";
  return {};
}

bool Recorder::complete() const { return !completion_reason().empty(); }

std::string Recorder::error() const {
  for (const auto& d : devices_) {
    if (d->audio) {
      const std::string e = d->audio->error();
      if (!e.empty()) return "device '" + d->id + "': audio source '" + d->audio_name + "': " + e;
    }
    for (const auto& s : d->sensors) {
      const std::string e = s.source->error();
      if (!e.empty()) {
        return "device '" + d->id + "': " + std::string(sensor_kind_name(s.kind)) + " source '" + s.name + "': " + e;
      }
    }
    const std::string w = d->get_error();
    if (!w.empty()) return "device '" + d->id + "': writing the recording: " + w;
  }
  return {};
}

void Recorder::stop(const std::string& reason) {
  if (stopped_) return;
  stopped_ = true;
  // 1. Sources first: after stop() returns nothing writes to a ring or queue any more.
  for (auto& d : devices_) {
    if (started_ && d->audio) d->audio->stop();
    for (auto& s : d->sensors) {
      if (started_) s.source->stop();
    }
    d->inputs_stopped.store(true, std::memory_order_release);
  }
  // 2. The writers drain what was handed over, then close their files.
  for (auto& d : devices_) {
    if (d->thread.joinable()) {
      d->thread.join();
    } else {
      try {
        d->close_files();  // never started: the files hold their headers
      } catch (const std::exception& e) {
        d->set_error(e.what());
      }
    }
  }
  // 3. The scene description (rewritten: same content, now complete) and the side file.
  scene::write_scene_yaml(scene_);
  write_recording_yaml(reason);
  for (const auto& d : devices_) {
    const std::string e = d->get_error();
    if (!e.empty()) throw std::runtime_error("device '" + d->id + "': " + e);
  }
}

std::vector<RecordedDevice> Recorder::devices() const {
  std::vector<RecordedDevice> out;
  for (const auto& dp : devices_) {
    const Device& d = *dp;
    RecordedDevice r;
    r.id = d.id;
    if (d.audio) {
      r.audio_source = d.audio_name;
      r.channels = d.channels;
      r.sample_rate_hz = d.rate_hz;
      r.sample_format = d.format;
      r.frames = d.frames_written.load(std::memory_order_relaxed);
      r.ring_overruns = d.ring->overruns();
      if (d.done.load(std::memory_order_acquire)) {
        r.lost_frames = d.lost;
        r.gaps = d.gaps;
        r.discarded_frames = d.discarded;
      }
    }
    const bool done = d.done.load(std::memory_order_acquire);
    for (const auto& s : d.sensors) {
      const auto k = static_cast<std::size_t>(s.kind);
      r.sensor_source[k] = s.name;
      r.dropped_events[k] = s.queue->dropped();
      if (done) {
        r.time_base[k] = s.time_base == Device::TimeBase::Audio       ? "audio"
                         : s.time_base == Device::TimeBase::Monotonic ? "monotonic"
                                                                       : "source";
        r.events[k] = s.rows;
        if (s.kind == SensorKind::Imu) r.imu_out_of_order = s.out_of_order;
      }
    }
    r.error = d.get_error();
    if (d.audio && r.error.empty()) r.error = d.audio->error();
    for (const auto& s : d.sensors) {
      if (r.error.empty()) r.error = s.source->error();
    }
    out.push_back(std::move(r));
  }
  return out;
}

void Recorder::write_recording_yaml(const std::string& reason) const {
  YAML::Emitter y;
  y << YAML::Comment("written by locus record: where the streams of this scene came from and what was lost "
                     "(a side file: not part of locus-scene/1, scene readers ignore it; docs/record.md)");
  y << YAML::BeginMap;
  y << YAML::Key << "tool" << YAML::Value << "locus record";
  if (!settings_.config_file.empty()) y << YAML::Key << "config" << YAML::Value << settings_.config_file;
  y << YAML::Key << "started_utc" << YAML::Value << started_utc_;
  y << YAML::Key << "stopped_utc" << YAML::Value << utc_now();
  y << YAML::Key << "stopped_by" << YAML::Value << reason;
  y << YAML::Key << "devices" << YAML::Value << YAML::BeginSeq;
  for (const RecordedDevice& r : devices()) {
    y << YAML::BeginMap << YAML::Key << "id" << YAML::Value << r.id;
    if (!r.audio_source.empty()) {
      y << YAML::Key << "audio" << YAML::Value << YAML::BeginMap;
      y << YAML::Key << "source" << YAML::Value << r.audio_source;
      y << YAML::Key << "channels" << YAML::Value << r.channels;
      y << YAML::Key << "sample_rate_hz" << YAML::Value << r.sample_rate_hz;
      y << YAML::Key << "sample_format" << YAML::Value << scene::to_string(r.sample_format);
      y << YAML::Key << "frames" << YAML::Value << r.frames;
      y << YAML::Key << "lost_frames" << YAML::Value << r.lost_frames;
      y << YAML::Key << "gaps" << YAML::Value << r.gaps.size();
      y << YAML::Key << "gaps_file" << YAML::Value << r.id + "/gaps.csv";
      y << YAML::Key << "ring_overruns" << YAML::Value << r.ring_overruns;
      y << YAML::Key << "frames_after_duration" << YAML::Value << r.discarded_frames;
      y << YAML::EndMap;
    }
    for (std::size_t k = 0; k < 3; ++k) {
      if (r.sensor_source[k].empty()) continue;
      y << YAML::Key << std::string(sensor_kind_name(static_cast<SensorKind>(k))) << YAML::Value << YAML::BeginMap;
      y << YAML::Key << "source" << YAML::Value << r.sensor_source[k];
      y << YAML::Key << "events" << YAML::Value << r.events[k];
      y << YAML::Key << "dropped_events" << YAML::Value << r.dropped_events[k];
      if (!r.time_base[k].empty()) y << YAML::Key << "time_base" << YAML::Value << r.time_base[k];
      if (k == 0) y << YAML::Key << "out_of_order_rows" << YAML::Value << r.imu_out_of_order;
      y << YAML::EndMap;
    }
    if (!r.error.empty()) y << YAML::Key << "error" << YAML::Value << r.error;
    y << YAML::EndMap;
  }
  y << YAML::EndSeq << YAML::EndMap;
  const std::string path = scene_.path("recording.yaml");
  std::ofstream f(path, std::ios::trunc);
  f << y.c_str() << "\n";
  f.close();
  if (!f) throw std::runtime_error(path + ": cannot write");
}

// ---------------------------------------------------------------------------------------------------

int run_record(const RecordOptions& opts) {
  const sigset_t stop_signals = app::block_stop_signals();  // inherited by every thread started below

  RecorderSettings settings;
  settings.out_dir = opts.out_dir;
  settings.duration_s = opts.duration_s;
  settings.overwrite = opts.overwrite;
  settings.name = opts.name.value_or("");
  std::error_code ec;
  settings.config_file = fs::absolute(opts.config_path, ec).lexically_normal().string();
  if (opts.sample_format != "auto") {
    scene::WavSampleFormat f{};
    if (!parse_sample_format(opts.sample_format, f)) {
      std::cerr << "--sample-format: expected auto, float32, int16, int24 or int32, got '" << opts.sample_format << "'\n";
      return kExitBadConfig;
    }
    settings.sample_format = f;
  }
  if (opts.duration_s && !(*opts.duration_s > 0.0 && std::isfinite(*opts.duration_s))) {
    std::cerr << "--duration: expected a positive number of seconds\n";
    return kExitBadConfig;
  }

  Registry registry;
  register_builtins(registry);
  Config config;
  try {
    config = load_config(opts.config_path, registry);
  } catch (const ConfigErrors& e) {
    for (const ConfigError& err : e.errors()) std::cerr << err.format() << "\n";
    std::cerr << e.errors().size() << (e.errors().size() == 1 ? " error" : " errors")
              << " in the config; nothing was recorded\n";
    return kExitBadConfig;
  }
  LogLevel level = config.log_level;
  if (opts.log_level) parse_log_level(*opts.log_level, level);
  set_log_level(level);
  auto log = host_logger();

  std::unique_ptr<Recorder> rec;
  try {
    rec = std::make_unique<Recorder>(config, registry, settings);
  } catch (const std::exception& e) {
    log->error("{}", e.what());
    std::cerr << "nothing was recorded\n";
    return kExitBadConfig;
  }
  log->info("recording {} device(s) into {}{}", rec->scene().devices.size(), opts.out_dir,
            opts.duration_s ? " for " + scene::format_double(*opts.duration_s) + " s" : std::string(" until Ctrl-C"));
  rec->start();

  std::string reason;
  std::string failure;
  double warned_at = 0.0;
  for (;;) {
    failure = rec->error();
    if (!failure.empty()) {
      reason = "error";
      break;
    }
    reason = rec->completion_reason();
    if (!reason.empty()) break;
    if (opts.duration_s) {
      // A live stream that stalls (a device that stopped delivering without saying so) would keep the
      // recording waiting for its frames: warn, and give up well past the requested duration.
      const double over = rec->elapsed_s() - *opts.duration_s;
      const double grace = std::max(5.0, 0.5 * *opts.duration_s);
      if (over > grace) {
        for (const RecordedDevice& d : rec->devices()) {
          if (!d.audio_source.empty()) {
            log->warn("device {}: {} of {} frames after {:.1f} s", d.id, d.frames,
                      std::llround(*opts.duration_s * d.sample_rate_hz), rec->elapsed_s());
          }
        }
        failure = "the audio streams did not deliver " + scene::format_double(*opts.duration_s) +
                  " s of frames within " + scene::format_double(*opts.duration_s + grace) + " s";
        reason = "stalled";
        break;
      }
      if (over > 1.0 && rec->elapsed_s() - warned_at > 5.0) {
        warned_at = rec->elapsed_s();
        log->warn("the audio streams are late: {:.1f} s elapsed for {} s of audio", rec->elapsed_s(),
                  scene::format_double(*opts.duration_s));
      }
    }
    timespec timeout{0, 20'000'000};
    const int sig = sigtimedwait(&stop_signals, nullptr, &timeout);
    if (sig > 0) {
      reason = sig == SIGINT ? "SIGINT" : "SIGTERM";
      log->info("{} received: stopping the recording", reason);
      break;
    }
  }

  int status = kExitOk;
  try {
    rec->stop(reason);
  } catch (const std::exception& e) {
    if (failure.empty()) failure = e.what();
  }
  if (failure.empty()) failure = rec->error();  // a source that failed while stopping
  for (const RecordedDevice& d : rec->devices()) {
    if (!d.audio_source.empty()) {
      log->info("device {}: audio {} frames ({:.3f} s, {} ch, {}), {} lost in {} gap(s), {} ring overrun(s)", d.id,
                d.frames, d.frames / d.sample_rate_hz, d.channels, scene::to_string(d.sample_format), d.lost_frames,
                d.gaps.size(), d.ring_overruns);
      if (d.lost_frames != 0) {
        log->warn("device {}: {} lost frames were written as zeros (listed in {}/gaps.csv)", d.id, d.lost_frames, d.id);
      }
    }
    for (std::size_t k = 0; k < 3; ++k) {
      if (d.sensor_source[k].empty()) continue;
      log->info("device {}: {} {} events, {} dropped", d.id, d.events[k],
                sensor_kind_name(static_cast<SensorKind>(k)), d.dropped_events[k]);
      if (d.dropped_events[k] != 0) {
        log->warn("device {}: {} {} events were dropped (queue full; raise queue_capacity)", d.id, d.dropped_events[k],
                  sensor_kind_name(static_cast<SensorKind>(k)));
      }
    }
    for (std::size_t k = 0; k < 3; ++k) {
      if (d.time_base[k] == "monotonic") {
        log->warn("device {}: the {} times are CLOCK_MONOTONIC seconds: the live audio never reported when its frame 0 "
                  "was captured, so they could not be put on the audio timeline", d.id,
                  sensor_kind_name(static_cast<SensorKind>(k)));
      }
    }
    if (d.imu_out_of_order != 0) {
      log->warn("device {}: {} IMU rows go back in time (the source broke its ordering promise)", d.id,
                d.imu_out_of_order);
    }
  }
  if (!failure.empty()) {
    log->error("{}", failure);
    std::cerr << "the recording stopped early; what was recorded before is in " << opts.out_dir << "\n";
    status = kExitFailure;
  } else {
    log->info("recorded {} ({}) into {}", rec->scene().name, reason, opts.out_dir);
  }
  return status;
}

}  // namespace locus::app
