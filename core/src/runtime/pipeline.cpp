#include "locus/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "locus/fftw_planner.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/json_events.hpp"
#include "locus/logging.hpp"
#include "pipeline_steps.hpp"

#include <spdlog/spdlog.h>

namespace locus {

// ------------------------------------------------------------------ AudioBlockRunner

AudioBlockRunner::AudioBlockRunner(AudioRing& ring, std::uint32_t block_frames, std::vector<Detector*> detectors,
                                   EventSink& sink)
    : ring_(ring),
      block_frames_(block_frames),
      detectors_(std::move(detectors)),
      sink_(sink),
      planar_(static_cast<std::size_t>(ring.channels()) * block_frames),
      channel_ptrs_(ring.channels()) {
  for (std::uint32_t c = 0; c < ring.channels(); ++c) channel_ptrs_[c] = planar_.data() + std::size_t{c} * block_frames;
}

std::size_t AudioBlockRunner::step(bool end_of_stream) noexcept {
  // A span stops at a gap, so "a whole block" is judged on everything readable, not on the span.
  if (!end_of_stream && ring_.readable_frames() < block_frames_) return 0;
  const AudioRing::ReadSpan span = ring_.read_acquire(block_frames_);
  pending_lost_ += span.lost_before;
  const std::size_t frames = span.frames();
  if (frames == 0) return 0;

  const std::uint32_t channels = ring_.channels();
  std::size_t out = 0;
  for (const AudioRing::Segment& seg : {span.first, span.second}) {
    const float* src = seg.data;
    for (std::size_t i = 0; i < seg.frames; ++i, ++out) {
      for (std::uint32_t c = 0; c < channels; ++c) planar_[std::size_t{c} * block_frames_ + out] = *src++;
    }
  }
  ring_.read_release(frames);

  AudioBlock block;
  block.channel_data = channel_ptrs_.data();
  block.channels = channels;
  block.frames = static_cast<std::uint32_t>(frames);
  block.first_frame = span.first_frame;
  block.lost_before = pending_lost_;
  for (Detector* d : detectors_) d->process_audio(block, sink_);

  frames_lost_ += pending_lost_;
  pending_lost_ = 0;
  frames_processed_ += frames;
  next_frame_ = span.first_frame + frames;
  return frames;
}

// ------------------------------------------------------------------ DeviceRunner

DeviceRunner::DeviceRunner(double sample_rate_hz, EventSink& sink, const RtEventQueue* backpressure)
    : fs_(sample_rate_hz), sink_(sink), backpressure_(backpressure) {
  sensors_.reserve(kMaxSensors);
}

void DeviceRunner::set_audio(AudioBlockRunner& runner, AudioRing& ring, const AudioSource& source,
                             std::uint32_t block_frames) {
  audio_ = &runner;
  ring_ = &ring;
  audio_source_ = &source;
  block_frames_ = block_frames;
  audio_live_ = source.live();
  audio_ended_ = false;
  all_non_live_ = all_non_live_ && !audio_live_;
}

void DeviceRunner::add_sensor(SensorQueue& queue, const SensorSource& source, std::vector<Detector*> detectors) {
  if (sensors_.size() >= kMaxSensors) throw std::invalid_argument("DeviceRunner: too many sensor streams");
  Sensor s;
  s.queue = &queue;
  s.source = &source;
  s.kind = source.kind();
  s.live = source.live();
  s.monotonic = source.monotonic_time();
  s.detectors = std::move(detectors);
  all_non_live_ = all_non_live_ && !s.live;
  sensors_.push_back(std::move(s));
}

void DeviceRunner::deliver(Sensor& s) noexcept {
  sink_.emit(s.head);
  if (s.kind == SensorKind::Imu) {
    const ImuSample& sample = std::get<ImuSample>(s.head);
    for (Detector* d : s.detectors) d->process_imu(&sample, 1, sink_);
  } else if (s.kind == SensorKind::Ble) {
    const BleAdvertisement& advert = std::get<BleAdvertisement>(s.head);
    for (Detector* d : s.detectors) d->process_ble(&advert, 1, sink_);
  }
  s.has_head = false;
  ++sensor_events_;
}

bool DeviceRunner::place_on_timeline(Sensor& s, bool stop_requested) noexcept {
  // The source may refine its origin while running: read it for every event (one atomic load).
  const double reported_s = audio_source_->frame_zero_monotonic_s();
  if (std::isfinite(reported_s)) origin_s_ = reported_s;
  const double origin_s = origin_s_;  // the last one known (a stopped source may forget it)
  if (std::isfinite(origin_s)) {
    shift_sensor_event_time(s.head, -origin_s);
    s.untimed = false;
    ++translated_;
    return true;
  }
  // No origin yet. Hold the head unless it can never come (the audio ended or the inputs stop) or the
  // stream's queue is full (then the oldest goes out on its own clock rather than new ones being lost).
  if (stop_requested || audio_ended_ || audio_source_->finished() || s.queue->size_approx() >= s.queue->capacity()) {
    s.untimed = false;
    ++untranslated_;
    return true;
  }
  ++origin_waits_;
  return false;
}

bool DeviceRunner::step(bool stop_requested) noexcept {
  if (done_) return false;
  if (audio_live_ && audio_source_ != nullptr) {  // the origin, for audio_origin_monotonic_s() (one atomic load)
    const double origin = audio_source_->frame_zero_monotonic_s();
    if (std::isfinite(origin)) origin_seen_s_.store(origin, std::memory_order_relaxed);
  }
  // A lossless device waits for the dispatcher rather than dropping events.
  if (all_non_live_ && backpressure_ != nullptr &&
      backpressure_->size_approx() > backpressure_->capacity() / 2) {
    ++waits_;
    return false;
  }
  bool behind = false;  // a non-live stream has no head yet and has not ended: its next item is unknown

  // Sensor heads. "Ended" is decided only after seeing finished() and then an empty queue (finished()
  // is released after the last push).
  Sensor* best = nullptr;
  double best_t = 0.0;
  // Monotonic sensor times go onto the audio timeline when the audio is live ("Time base").
  const bool to_audio_time = audio_source_ != nullptr && audio_live_;
  for (Sensor& s : sensors_) {
    if (!s.has_head && !s.ended) {
      if (s.queue->try_pop(s.head)) {
        s.has_head = true;
      } else if (stop_requested || s.source->finished()) {
        if (s.queue->try_pop(s.head)) {
          s.has_head = true;
        } else {
          s.ended = true;
        }
      } else if (!s.live) {
        behind = true;
      }
      s.untimed = s.has_head && s.monotonic && to_audio_time;
    }
    if (s.has_head && s.untimed && !place_on_timeline(s, stop_requested)) continue;  // held: not a candidate
    if (s.has_head) {
      const double t = sensor_event_time_s(s.head);
      if (best == nullptr || t < best_t) {
        best = &s;
        best_t = t;
      }
    }
  }

  // Audio head: the start of the next block, known once a whole block (or the tail) is readable.
  bool audio_ready = false;
  bool audio_tail = false;
  if (!audio_ended_) {
    const bool ended = stop_requested || audio_source_->finished();
    const std::size_t readable = ring_->readable_frames();
    if (readable >= block_frames_) {
      audio_ready = true;
    } else if (ended) {
      if (readable > 0) {
        audio_ready = true;
        audio_tail = true;
      } else {
        audio_ended_ = true;
      }
    } else if (!audio_live_) {
      behind = true;
    }
  }

  if (behind && !stop_requested) {
    ++waits_;
    return false;
  }
  if (audio_ready) {
    // Frame numbers after an overrun gap are approximate here (live streams only: best effort).
    const double block_start = static_cast<double>(audio_->next_frame());
    if (best == nullptr || !(best_t * fs_ < block_start)) return audio_->step(audio_tail) > 0;
  }
  if (best != nullptr) {
    deliver(*best);
    return true;
  }
  if (audio_ended_ && std::all_of(sensors_.begin(), sensors_.end(), [](const Sensor& s) { return s.ended; })) {
    done_ = true;
  }
  return false;
}

// ------------------------------------------------------------------ Pipeline

using pipeline_steps::Device;
using pipeline_steps::HostServices;

Pipeline::Pipeline(const Config& config, Registry& registry, PipelineOptions options)
    : config_(config),
      registry_(registry),
      options_(std::move(options)),
      fft_(std::make_unique<FftwPlanner>(std::string{}, options_.fft_measure)),
      clock_(std::make_unique<SteadyClock>()) {
  pipeline_steps::LinkChoice link = pipeline_steps::choose_link(config_, registry_, options_.link);
  link_ = link.link;
  own_link_ = std::move(link.owned);
  own_inprocess_ = link.inprocess;
  link_log_ = std::move(link.log);
  pipeline_steps::add_config_geometry(config_, options_.geometry);
  dispatched_link_ = std::make_unique<DispatchedLink>(*link_, bus_);
  publisher_ = std::make_unique<BusPublisher>(bus_);
  const HostServices host{*clock_, *fft_, *dispatched_link_};
  for (const DeviceConfig& dc : config_.devices) {
    if (dc.is_template()) continue;
    devices_.push_back(
        pipeline_steps::build_device(dc, registry_, host, options_.geometry, config_.sample_rate_hz, bus_));
  }
  open_localizers(host);
  open_outputs();
}

void Pipeline::open_localizers(const HostServices& host) {
  // Localizers serve options_.localizer_device (replay: one node per device). A node-wide localizer
  // (locusd) on a node with exactly one device gets that device's geometry and emitter.
  served_device_ = pipeline_steps::served_device(config_, options_.localizer_device);
  const DeviceGeometry* node_geometry = pipeline_steps::find_geometry(options_.geometry, served_device_);
  Emitter* node_emitter = nullptr;
  for (const auto& dev : devices_) {
    if (dev->id == served_device_ && dev->emitter) node_emitter = dev->emitter.get();
  }
  for (const ComponentConfig& cc : config_.localizers) {
    const std::string log_name =
        options_.localizer_device.empty() ? cc.name : options_.localizer_device + "/" + cc.name;
    auto inst = pipeline_steps::open_localizer(cc, registry_, host, log_name, served_device_, node_geometry,
                                               node_emitter);
    Localizer* loc = inst->localizer.get();
    Publisher* pub = publisher_.get();
    for (EventType t : loc->subscriptions()) {
      bus_.subscribe(t, [loc, pub](const Event& e) { loc->on_event(e, *pub); });
    }
    localizers_.push_back(std::move(inst));
  }
}

void Pipeline::open_outputs() {
  if (options_.write_output) {
    writer_ = std::make_unique<JsonLinesWriter>(config_.output.path, [](const std::string& message, bool error) {
      auto log = host_logger();
      if (error) {
        log->error("{}", message);
      } else {
        log->info("{}", message);
      }
    });
    for (EventType t : config_.output.events) {
      JsonLinesWriter* w = writer_.get();
      bus_.subscribe(t, [w](const Event& e) { w->write(e); });
    }
  }
  for (const EventOutputConfig& oc : config_.outputs) {
    std::unique_ptr<EventOutput> out = pipeline_steps::open_output(oc, registry_, output_logs_);
    EventOutput* o = out.get();
    for (EventType t : oc.events) bus_.subscribe(t, [o](const Event& e) { o->write(e); });
    outputs_.push_back(std::move(out));
  }
}

Pipeline::~Pipeline() {
  stop();
  // Members die in reverse order: output_logs_/link_log_ (declared after outputs_/own_link_) would go before
  // the output and link threads that log through them, and dispatched_link_ before the link thread that
  // calls its handlers. Stop those threads first, after the localizers (which may unsubscribe).
  localizers_.clear();
  outputs_.clear();
  own_link_.reset();
  own_inprocess_ = nullptr;
}

void Pipeline::subscribe(EventType type, EventBus::Handler handler) { bus_.subscribe(type, std::move(handler)); }

void Pipeline::run_device(Device& dev) {
  using namespace std::chrono_literals;
  for (;;) {
    const bool stop = dev.stop_requested.load(std::memory_order_acquire);
    if (dev.device_runner->step(stop)) continue;
    if (dev.device_runner->done()) break;
    std::this_thread::sleep_for(200us);  // idle: waiting for a stream; never inside a detector
  }
  for (auto& d : dev.detectors) d->finish(*dev.queue);
  dev.done.store(true, std::memory_order_release);
}

void Pipeline::start() {
  if (started_) return;
  started_ = true;
  bus_.start();
  for (auto& dev : devices_) {
    if (!dev->device_runner) continue;
    Device* d = dev.get();
    d->thread = std::thread([this, d] { run_device(*d); });
  }
  for (auto& dev : devices_) {
    if (dev->sink) dev->sink->start(*dev->scheduler);  // playing before capture starts
    if (dev->source) dev->source->start(*dev->ring);
    for (auto& s : dev->sensors) s.source->start(*s.queue);
  }
}

bool Pipeline::finished() const noexcept {
  for (const auto& dev : devices_) {
    if (dev->device_runner && !dev->done.load(std::memory_order_acquire)) return false;
  }
  return true;
}

void Pipeline::stop_inputs() {
  if (inputs_stopped_) return;
  inputs_stopped_ = true;
  if (started_) {
    for (auto& dev : devices_) {
      if (dev->source) dev->source->stop();
      for (auto& s : dev->sensors) s.source->stop();
      if (dev->sink) dev->sink->stop();
    }
    for (auto& dev : devices_) {
      dev->stop_requested.store(true, std::memory_order_release);
      if (dev->thread.joinable()) dev->thread.join();
    }
    bus_.stop();
  }
  // Detectors of devices whose thread never ran (not started) still finish, for symmetry.
  if (!started_) {
    for (auto& dev : devices_) {
      if (!dev->queue) continue;
      for (auto& d : dev->detectors) d->finish(*dev->queue);
    }
  }
  while (bus_.drain() > 0) {
  }
}

std::size_t Pipeline::deliver_pending() {
  std::size_t total = 0;
  for (std::size_t n; (n = bus_.drain()) > 0;) total += n;
  return total;
}

void Pipeline::end_localizer_inputs() {
  if (localizer_inputs_ended_) return;
  localizer_inputs_ended_ = true;
  for (auto& inst : localizers_) inst->localizer->inputs_ended(*publisher_);
}

void Pipeline::finish_localizers() {
  if (localizers_finished_) return;
  end_localizer_inputs();
  localizers_finished_ = true;
  for (auto& inst : localizers_) inst->localizer->finish(*publisher_);
}

void Pipeline::settle() {
  // The dispatcher has stopped: this thread now delivers. Let link traffic settle (own link only; a
  // shared link is the embedder's to flush).
  do {
    if (own_inprocess_ != nullptr) own_inprocess_->flush();
  } while (deliver_pending() > 0);
}

void Pipeline::flush() {
  if (flushed_) return;
  flushed_ = true;
  for (const DeviceStats& s : stats()) {
    auto log = host_logger();
    log->info("device {}: {} frames processed, {} lost in {} overruns, {} sensor events ({} dropped{}), {} events "
              "dropped{}{}",
              s.id, s.frames_processed, s.frames_lost, s.overruns, s.sensor_events, s.sensor_dropped,
              s.sensor_untranslated == 0 ? std::string()
                                         : ", " + std::to_string(s.sensor_untranslated) +
                                               " left on CLOCK_MONOTONIC: the live audio had no time origin",
              s.events_dropped,
              s.has_playback ? ", playback: " + std::to_string(s.playback_xruns) + " xruns, " +
                                   std::to_string(s.late_emissions) + " emissions late or refused"
                             : std::string(),
              s.source_error.empty() ? "" : ", source error: " + s.source_error);
    // What relates this device's clock to the host's (docs/room.md: the truth clocks of a HIL run).
    if (std::isfinite(s.audio_origin_monotonic_s))
      log->info("device {}: audio frame 0 at CLOCK_MONOTONIC {:.9f} s", s.id, s.audio_origin_monotonic_s);
  }
  if (writer_) {
    writer_->flush();
    if (writer_->lines_failed() > 0) {
      host_logger()->error("output '{}': {} lines written, {} not written (last error: {})", writer_->path(),
                           writer_->lines(), writer_->lines_failed(), writer_->error());
    }
  }
  for (auto& o : outputs_) o->flush();
}

void Pipeline::stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_inputs();
  settle();
  end_localizer_inputs();
  settle();
  finish_localizers();
  settle();
  flush();
}

std::vector<DeviceStats> Pipeline::live_stats() const {
  std::vector<DeviceStats> out;
  out.reserve(devices_.size());
  for (const auto& dev : devices_) {
    DeviceStats s;
    s.id = dev->id;
    if (dev->ring) {
      s.frames_lost = dev->ring->frames_lost();
      s.overruns = dev->ring->overruns();
    }
    if (dev->queue) s.events_dropped = dev->queue->dropped();
    if (dev->sink) {
      s.has_playback = true;
      s.playback_xruns = dev->sink->xruns();
    }
    for (const auto& sensor : dev->sensors) s.sensor_dropped += sensor.queue->dropped();
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<DeviceStats> Pipeline::stats() const {
  std::vector<DeviceStats> out;
  for (const auto& dev : devices_) {
    DeviceStats s;
    s.id = dev->id;
    if (dev->runner) {
      s.frames_processed = dev->runner->frames_processed();
      s.frames_lost = dev->ring->frames_lost();
      s.overruns = dev->ring->overruns();
    }
    if (dev->queue) s.events_dropped = dev->queue->dropped();
    if (dev->source) s.source_error = dev->source->error();
    if (dev->sink) {
      s.has_playback = true;
      s.playback_xruns = dev->sink->xruns();
      s.late_emissions = dev->emitter->late_emissions();
      if (s.source_error.empty() && !dev->sink->error().empty()) s.source_error = "playback: " + dev->sink->error();
    }
    if (dev->device_runner) {
      s.audio_origin_monotonic_s = dev->device_runner->audio_origin_monotonic_s();
      s.sensor_events = dev->device_runner->sensor_events_delivered();
      s.sensor_untranslated = dev->device_runner->sensor_events_untranslated();
    }
    for (const auto& sensor : dev->sensors) {
      s.sensor_dropped += sensor.queue->dropped();
      if (s.source_error.empty()) {
        const std::string e = sensor.source->error();
        if (!e.empty()) s.source_error = std::string(sensor_kind_name(sensor.kind)) + " source: " + e;
      }
    }
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace locus
