#include "locus/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "locus/fftw_planner.hpp"
#include "locus/inprocess_link.hpp"
#include "locus/json_events.hpp"
#include "locus/logging.hpp"

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

// ------------------------------------------------------------------ Pipeline

struct Pipeline::Device {
  std::string id;
  std::unique_ptr<SpdLogger> source_log;
  std::unique_ptr<AudioSource> source;
  std::unique_ptr<AudioRing> ring;
  std::vector<std::unique_ptr<SpdLogger>> detector_logs;
  std::vector<std::unique_ptr<Detector>> detectors;
  RtEventQueue* queue = nullptr;
  std::unique_ptr<AudioBlockRunner> runner;
  std::thread thread;
  std::atomic<bool> stop_requested{false};
  std::atomic<bool> done{false};
};

struct Pipeline::LocalizerInstance {
  std::string name;
  std::unique_ptr<SpdLogger> log;
  std::unique_ptr<Localizer> localizer;
};

Pipeline::Pipeline(const Config& config, Registry& registry)
    : config_(config),
      registry_(registry),
      link_(std::make_unique<InProcessLink>()),
      fft_(std::make_unique<FftwPlanner>()),
      clock_(std::make_unique<SteadyClock>()) {
  dispatched_link_ = std::make_unique<DispatchedLink>(*link_, bus_);
  publisher_ = std::make_unique<BusPublisher>(bus_);

  for (const DeviceConfig& dc : config_.devices) {
    auto dev = std::make_unique<Device>();
    dev->id = dc.id;
    if (dc.audio) {
      const AudioConfig& ac = *dc.audio;
      dev->source_log = std::make_unique<SpdLogger>(dc.id + "/" + ac.source);
      HostContext ctx{*dev->source_log, *clock_, *fft_, *dispatched_link_, ac.source, dc.id};
      try {
        dev->source = registry_.create_source(ac.source);
        dev->source->open(ac.params, ctx);
      } catch (const std::exception& e) {
        throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "': " + e.what());
      }
      if (std::abs(dev->source->sample_rate_hz() - config_.sample_rate_hz) > 1e-6) {
        throw std::runtime_error("device '" + dc.id + "': audio source '" + ac.source + "' runs at " +
                                 std::to_string(dev->source->sample_rate_hz()) + " Hz but the node is configured for " +
                                 std::to_string(config_.sample_rate_hz) + " Hz (sample_rate_hz)");
      }
      dev->ring = std::make_unique<AudioRing>(dev->source->channels(), ac.ring_frames);
      StreamInfo info;
      info.device = DeviceId(dc.id);
      info.channels = dev->source->channels();
      info.sample_rate_hz = dev->source->sample_rate_hz();
      info.max_block_frames = ac.block_frames;
      for (const ComponentConfig& cc : dc.detectors) {
        auto log = std::make_unique<SpdLogger>(cc.name);
        HostContext dctx{*log, *clock_, *fft_, *dispatched_link_, cc.name, dc.id};
        try {
          auto det = registry_.create_detector(cc.plugin);
          det->configure(info, cc.params, dctx);
          dev->detectors.push_back(std::move(det));
        } catch (const std::exception& e) {
          throw std::runtime_error("device '" + dc.id + "': detector '" + cc.name + "': " + e.what());
        }
        dev->detector_logs.push_back(std::move(log));
      }
      dev->queue = &bus_.make_rt_queue(dc.id, 4096);
      std::vector<Detector*> raw;
      for (auto& d : dev->detectors) raw.push_back(d.get());
      dev->runner = std::make_unique<AudioBlockRunner>(*dev->ring, ac.block_frames, std::move(raw), *dev->queue);
    }
    devices_.push_back(std::move(dev));
  }

  for (const ComponentConfig& cc : config_.localizers) {
    auto inst = std::make_unique<LocalizerInstance>();
    inst->name = cc.name;
    inst->log = std::make_unique<SpdLogger>(cc.name);
    HostContext ctx{*inst->log, *clock_, *fft_, *dispatched_link_, cc.name, ""};
    try {
      inst->localizer = registry_.create_localizer(cc.plugin);
      inst->localizer->configure(cc.params, ctx);
    } catch (const std::exception& e) {
      throw std::runtime_error("localizer '" + cc.name + "': " + e.what());
    }
    Localizer* loc = inst->localizer.get();
    Publisher* pub = publisher_.get();
    for (EventType t : loc->subscriptions()) {
      bus_.subscribe(t, [loc, pub](const Event& e) { loc->on_event(e, *pub); });
    }
    localizers_.push_back(std::move(inst));
  }

  writer_ = std::make_unique<JsonLinesWriter>(config_.output.path);
  for (EventType t : config_.output.events) {
    JsonLinesWriter* w = writer_.get();
    bus_.subscribe(t, [w](const Event& e) { w->write(e); });
  }
}

Pipeline::~Pipeline() { stop(); }

void Pipeline::subscribe(EventType type, EventBus::Handler handler) { bus_.subscribe(type, std::move(handler)); }

void Pipeline::run_device(Device& dev) {
  using namespace std::chrono_literals;
  for (;;) {
    const bool ended = dev.stop_requested.load(std::memory_order_acquire) || dev.source->finished();
    const std::size_t n = dev.runner->step(ended);
    if (n > 0) continue;
    if (ended && dev.ring->readable_frames() == 0) break;
    std::this_thread::sleep_for(200us);  // idle: the ring is empty; never inside a detector
  }
  for (auto& d : dev.detectors) d->finish(*dev.queue);
  dev.done.store(true, std::memory_order_release);
}

void Pipeline::start() {
  if (started_) return;
  started_ = true;
  bus_.start();
  for (auto& dev : devices_) {
    if (!dev->source) continue;
    Device* d = dev.get();
    d->thread = std::thread([this, d] { run_device(*d); });
  }
  for (auto& dev : devices_) {
    if (dev->source) dev->source->start(*dev->ring);
  }
}

bool Pipeline::finished() const noexcept {
  for (const auto& dev : devices_) {
    if (dev->source && !dev->done.load(std::memory_order_acquire)) return false;
  }
  return true;
}

void Pipeline::stop() {
  if (stopped_) return;
  stopped_ = true;
  if (started_) {
    for (auto& dev : devices_) {
      if (dev->source) dev->source->stop();
    }
    for (auto& dev : devices_) {
      dev->stop_requested.store(true, std::memory_order_release);
      if (dev->thread.joinable()) dev->thread.join();
    }
    bus_.stop();
  }
  // The dispatcher has stopped: this thread now delivers. Let link traffic settle before the
  // localizers finish, and deliver what they publish when they do.
  auto quiesce = [this] {
    do {
      static_cast<InProcessLink&>(*link_).flush();
    } while (bus_.drain() > 0);
  };
  quiesce();
  for (auto& inst : localizers_) inst->localizer->finish(*publisher_);
  quiesce();
  for (const DeviceStats& s : stats()) {
    auto log = host_logger();
    log->info("device {}: {} frames processed, {} lost in {} overruns, {} events dropped{}", s.id, s.frames_processed,
              s.frames_lost, s.overruns, s.events_dropped, s.source_error.empty() ? "" : ", source error: " + s.source_error);
  }
  if (writer_) writer_->flush();
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
      s.events_dropped = dev->queue->dropped();
      s.source_error = dev->source->error();
    }
    out.push_back(std::move(s));
  }
  return out;
}

}  // namespace locus
