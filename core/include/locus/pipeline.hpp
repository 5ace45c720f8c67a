// The node pipeline built from a validated Config: per device an audio source (HAL) feeding an
// AudioRing, optional sensor sources (imu, ble, sync) feeding SensorQueues, an optional playback sink
// fed by a PlaybackScheduler (the device's Emitter, HostContext::emitter), a detector thread that
// merges the device's streams by local time and runs its detectors, and one event bus whose dispatcher
// thread feeds the localizers and the JSON-lines sink.
//
//   audio source  --AudioRing---+
//   imu/ble/sync  --SensorQueue--+--> detector thread (DeviceRunner) --RtEventQueue--> dispatcher --> localizers
//                                                                                              +--> JSON lines
//
// Time order: the detector thread delivers every sensor event with local time t_s before the first
// audio block that starts after t_s * fs (before block [F, F+n) come exactly the events with
// t_s * fs < F), and merges the sensor streams among themselves by t_s. When every source of the
// device is non-live (replay at max speed) the thread waits for whichever stream is behind, so the
// interleaving is exact and nothing is dropped (it also waits for room in the event queue). A live
// stream never makes it wait: live streams are merged as they come (best effort).
//
// Time base: device-local time means the same thing live and in replay: audio frame F <-> t = F / fs.
// Replay sources already stamp that way. Live sensor sources stamp CLOCK_MONOTONIC seconds
// (SensorSource::monotonic_time()); on a device whose audio source is live the detector thread moves
// each such event onto the audio timeline, t_s - AudioSource::frame_zero_monotonic_s(), before it is
// merged, handed to detectors and posted to the bus (events sensed before the first audio frame get
// t_s < 0). An event popped before the audio source knows its origin (not started yet) is held (the
// sensor queue is the bound) until it does; it goes out untranslated (monotonic time, counted in
// DeviceStats::sensor_untranslated) only if the audio ends or the inputs stop without an origin, or the
// held stream's queue is full (audio that never starts does not silence the sensors). A device without
// audio, or with non-live audio, keeps its sensors' own times (monotonic for live sources).
//
// Every raw sensor event (ImuSample, BleAdvertisement, RadioSync) is also posted to the bus, in that
// order with the detections, so localizers can subscribe to them.
//
// The runners (AudioBlockRunner, DeviceRunner) are plain objects, testable on one thread; Pipeline only
// adds the threads and the orderly shutdown (stop sources, drain rings and queues through the
// detectors, finish detectors, drain the bus, finish localizers, flush sinks). `locus replay` runs
// several pipelines over one shared link and drives the two shutdown phases itself.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/audio_source.hpp"
#include "locus/config.hpp"
#include "locus/detector.hpp"
#include "locus/event_bus.hpp"
#include "locus/event_output.hpp"
#include "locus/playback.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"

namespace locus {

namespace pipeline_steps {  // the steps that build a Pipeline (core/src/runtime/pipeline_steps.hpp)
struct Device;
struct LocalizerInstance;
struct HostServices;
}  // namespace pipeline_steps

/// Consumer side of one device's audio: reads spans from the ring, deinterleaves them into planar
/// blocks and runs the detectors. All buffers are allocated in the constructor.
class AudioBlockRunner {
 public:
  AudioBlockRunner(AudioRing& ring, std::uint32_t block_frames, std::vector<Detector*> detectors, EventSink& sink);

  /// [RT] Processes at most one block. Waits for a whole block unless `end_of_stream` (then takes
  /// what is there). Returns the frames processed (0 = nothing to do now). Never allocates or blocks.
  std::size_t step(bool end_of_stream) noexcept;

  std::uint64_t frames_processed() const noexcept { return frames_processed_; }
  std::uint64_t frames_lost() const noexcept { return frames_lost_; }
  std::uint64_t next_frame() const noexcept { return next_frame_; }

 private:
  AudioRing& ring_;
  std::uint32_t block_frames_;
  std::vector<Detector*> detectors_;
  EventSink& sink_;
  std::vector<float> planar_;            // channels x block_frames
  std::vector<const float*> channel_ptrs_;
  std::uint64_t frames_processed_ = 0;
  std::uint64_t frames_lost_ = 0;
  std::uint64_t pending_lost_ = 0;
  std::uint64_t next_frame_ = 0;
};

/// Consumer side of one device: merges its audio (through an AudioBlockRunner) and its sensor queues
/// by local time, hands sensor events to the detectors that consume them and posts them to the sink.
/// Set up on the main thread; step() runs on the device's detector thread.
class DeviceRunner {
 public:
  /// `sink` receives the raw sensor events (and is what detectors emit into); `backpressure`, when
  /// given, is the queue behind `sink`: a device whose sources are all non-live waits while it is more
  /// than half full instead of dropping.
  DeviceRunner(double sample_rate_hz, EventSink& sink, const RtEventQueue* backpressure = nullptr);

  /// [main] The device's audio (optional). The runner and ring outlive this object.
  void set_audio(AudioBlockRunner& runner, AudioRing& ring, const AudioSource& source, std::uint32_t block_frames);
  /// [main] One sensor stream and the detectors that consume it (process_imu for Imu, process_ble for
  /// Ble; Sync events only go to the sink). Up to kMaxSensors streams.
  void add_sensor(SensorQueue& queue, const SensorSource& source, std::vector<Detector*> detectors);
  static constexpr std::size_t kMaxSensors = 8;

  /// [RT] Delivers at most one item (one audio block or one sensor event), the earliest in local time.
  /// Returns false when nothing can be delivered now (a non-live stream is behind, or all is drained).
  /// `stop_requested`: the sources were stopped; deliver what is queued without waiting for more.
  bool step(bool stop_requested) noexcept;
  /// [RT] True once every stream has ended and everything queued was delivered.
  bool done() const noexcept { return done_; }

  std::uint64_t sensor_events_delivered() const noexcept { return sensor_events_; }
  /// [any thread] CLOCK_MONOTONIC seconds of the live audio's frame 0 (the last origin its source
  /// reported; NaN for non-live audio or before it started). Kept after the source stopped (which may
  /// forget it): what relates the device's clock to the host's (`locus room` writes the truth clocks of
  /// a hardware-in-the-loop run from it).
  double audio_origin_monotonic_s() const noexcept { return origin_seen_s_.load(std::memory_order_relaxed); }
  /// Sensor events moved from CLOCK_MONOTONIC onto the audio timeline ("Time base" above).
  std::uint64_t sensor_events_translated() const noexcept { return translated_; }
  /// Monotonic-time sensor events delivered untranslated because the live audio had no origin yet.
  std::uint64_t sensor_events_untranslated() const noexcept { return untranslated_; }
  /// Steps on which a sensor head was held waiting for the audio's origin.
  std::uint64_t origin_waits() const noexcept { return origin_waits_; }
  /// Times the runner found nothing it could deliver while a non-live stream was behind (waits).
  std::uint64_t waits() const noexcept { return waits_; }

 private:
  struct Sensor {
    SensorQueue* queue = nullptr;
    const SensorSource* source = nullptr;
    SensorKind kind = SensorKind::Imu;
    bool live = false;
    bool monotonic = false;  ///< t_s on CLOCK_MONOTONIC (source->monotonic_time())
    std::vector<Detector*> detectors;
    Event head;
    bool has_head = false;
    bool untimed = false;    ///< head still on CLOCK_MONOTONIC, waiting for the audio's origin
    bool ended = false;
  };
  void deliver(Sensor& s) noexcept;
  /// Puts an untimed head on the audio timeline; false while it must be held.
  bool place_on_timeline(Sensor& s, bool stop_requested) noexcept;

  double fs_;
  EventSink& sink_;
  const RtEventQueue* backpressure_;
  AudioBlockRunner* audio_ = nullptr;
  AudioRing* ring_ = nullptr;
  const AudioSource* audio_source_ = nullptr;
  std::uint32_t block_frames_ = 0;
  bool audio_live_ = false;
  bool audio_ended_ = true;
  bool all_non_live_ = true;
  std::vector<Sensor> sensors_;  // reserved kMaxSensors: never reallocates
  bool done_ = false;
  std::uint64_t sensor_events_ = 0;
  std::uint64_t waits_ = 0;
  double origin_s_ = std::numeric_limits<double>::quiet_NaN();  // last finite frame_zero_monotonic_s()
  std::atomic<double> origin_seen_s_{std::numeric_limits<double>::quiet_NaN()};  // same, read every step
  std::uint64_t translated_ = 0;
  std::uint64_t untranslated_ = 0;
  std::uint64_t origin_waits_ = 0;
};

struct DeviceStats {
  std::string id;
  std::uint64_t frames_processed = 0;
  std::uint64_t frames_lost = 0;
  std::uint64_t overruns = 0;
  std::uint64_t events_dropped = 0;
  std::uint64_t sensor_events = 0;   ///< sensor events delivered (all streams)
  std::uint64_t sensor_dropped = 0;  ///< sensor events live sources dropped (full queue)
  std::uint64_t sensor_untranslated = 0;  ///< monotonic sensor events delivered without the audio's origin
  bool has_playback = false;         ///< the device has a `playback:` section
  std::uint64_t playback_xruns = 0;  ///< underruns of the playback sink
  std::uint64_t late_emissions = 0;  ///< emissions cut or refused (Emitter::late_emissions)
  /// CLOCK_MONOTONIC seconds of the live audio's frame 0 (DeviceRunner::audio_origin_monotonic_s);
  /// NaN for non-live audio.
  double audio_origin_monotonic_s = std::numeric_limits<double>::quiet_NaN();
  std::string source_error;          ///< first error of the device's sources ("imu source: ..." for sensors,
                                     ///< "playback: ..." for the sink)
};

/// The geometry a pipeline hands to the plugins of one device, with the signals it owns for them
/// (DeviceGeometry::emits / scene_emits point into `emits` / `scene_emits`, fixed up by the pipeline).
struct GeometrySpec {
  DeviceGeometry geometry;
  std::vector<SignalSpec> emits;          ///< DeviceGeometry::emits
  std::vector<SceneSignal> scene_emits;   ///< DeviceGeometry::scene_emits
};

/// How a pipeline is embedded (defaults: a stand-alone node, as locusd runs it).
struct PipelineOptions {
  /// Shared link (not owned; must outlive the pipeline and be flushed by the owner). nullptr: the
  /// pipeline has its own InProcessLink.
  Link* link = nullptr;
  /// Write config.output through the pipeline's own JSON-lines writer. False when the embedder
  /// subscribes its own sink (replay: one writer for every node).
  bool write_output = true;
  /// HostContext::device of the localizers ("" = node-wide; on a node with exactly one device the
  /// localizers serve that device). Replay: the node's device id.
  std::string localizer_device;
  /// Per device id; plugins of a device listed here get HostContext::geometry. A device not listed
  /// here whose config has a `geometry:` section gets that one.
  std::map<std::string, GeometrySpec> geometry;
  /// FFTW plans by measurement (FFTW_MEASURE: faster transforms, chosen by timing) or by estimate
  /// (FFTW_ESTIMATE). Measured plans differ from run to run, and so do the last bits of every
  /// transform; a localizer that picks among basins turns those bits into different results. Replay
  /// plans by estimate: the same scene gives the same output, bit for bit (docs/config.md "Replay").
  bool fft_measure = true;
};

class Pipeline {
 public:
  /// [main] Instantiates and configures every source, detector, localizer and sink of `config`.
  /// Template devices (id "*") are not instantiated. Throws std::runtime_error naming the component
  /// that failed (including a detector whose inputs the device has no stream for). Built by the
  /// steps of pipeline_steps.hpp: the link, the geometry, each device, the localizers, the outputs.
  Pipeline(const Config& config, Registry& registry, PipelineOptions options = {});
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// [main, before start()] Extra subscriber (tools and tests), called on the dispatcher thread.
  void subscribe(EventType type, EventBus::Handler handler);

  /// [main] Starts the dispatcher, the detector threads, then the sources.
  void start();
  /// [any] True when every finite source has ended and its frames went through the detectors.
  bool finished() const noexcept;
  /// [main] Orderly shutdown; idempotent. Everything accepted so far reaches the sinks.
  /// Same as stop_inputs(); settle (own link only); end_localizer_inputs(); settle; finish_localizers();
  /// settle; flush().
  void stop();

  // The shutdown phases, for embedders that share a link between pipelines (replay):
  /// [main] Phase (a): stops the sources, drains rings and queues through the detectors, finishes the
  /// detectors and delivers everything on the bus; stops the dispatcher thread (from then on the
  /// calling thread delivers, through deliver_pending()). Idempotent.
  void stop_inputs();
  /// [main, after stop_inputs()] Delivers what is queued on the bus now (link messages re-posted by the
  /// link, events localizers published). Returns the number of items delivered.
  std::size_t deliver_pending();
  /// [main, after stop_inputs()] Calls every localizer's inputs_ended() once (later calls do nothing).
  /// An embedder sharing a link calls it on every pipeline, settles the link, then finish_localizers().
  void end_localizer_inputs();
  /// [main, after stop_inputs()] Calls every localizer's finish() once (later calls do nothing); calls
  /// end_localizer_inputs() first if it was not.
  void finish_localizers();
  /// [main] Logs the device statistics and flushes the pipeline's own writer (if any); once.
  void flush();

  std::vector<DeviceStats> stats() const;
  /// [any, while running] The counters of stats() that other threads may read while the pipeline runs
  /// (atomics only: frames_lost, overruns, events_dropped, playback_xruns, sensor_dropped,
  /// has_playback; the rest stays 0/empty). The live map polls it from the main thread.
  std::vector<DeviceStats> live_stats() const;
  std::uint64_t events_delivered(EventType type) const noexcept { return bus_.delivered(type); }
  /// The config the pipeline was built from.
  const Config& config() const noexcept { return config_; }
  /// How its localizers reach other nodes: "in-process" (own or shared in-process link) or the
  /// config's link type ("mqtt").
  std::string link_kind() const { return options_.link == nullptr && config_.link ? config_.link->type : "in-process"; }

 private:
  using Device = pipeline_steps::Device;
  using LocalizerInstance = pipeline_steps::LocalizerInstance;
  void open_localizers(const pipeline_steps::HostServices& host);
  void open_outputs();
  void run_device(Device& device);
  void settle();

  const Config config_;
  Registry& registry_;
  PipelineOptions options_;
  EventBus bus_;
  std::unique_ptr<Link> own_link_;  // when options_.link is nullptr: config.link's type, else in-process
  class InProcessLink* own_inprocess_ = nullptr;  // own_link_ when it is in-process (settle() flushes it)
  Link* link_ = nullptr;
  std::unique_ptr<Link> dispatched_link_;
  std::unique_ptr<FftPlanner> fft_;
  std::unique_ptr<Clock> clock_;
  std::vector<std::unique_ptr<Device>> devices_;
  std::vector<std::unique_ptr<LocalizerInstance>> localizers_;
  std::string served_device_;  // HostContext::device of the localizers (they may keep the view)
  std::unique_ptr<class JsonLinesWriter> writer_;
  std::vector<std::unique_ptr<EventOutput>> outputs_;  // config.outputs
  std::vector<std::unique_ptr<class SpdLogger>> output_logs_;
  std::unique_ptr<class SpdLogger> link_log_;
  std::unique_ptr<Publisher> publisher_;
  bool started_ = false;
  bool inputs_stopped_ = false;
  bool localizers_finished_ = false;
  bool localizer_inputs_ended_ = false;
  bool flushed_ = false;
  bool stopped_ = false;
};

}  // namespace locus
