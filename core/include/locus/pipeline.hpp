// The node pipeline built from a validated Config: per device an audio source (HAL) feeding an
// AudioRing, a detector thread running that device's detectors block by block, and one event bus
// whose dispatcher thread feeds the localizers and the JSON-lines sink.
//
//   source thread/callback --AudioRing--> detector thread --RtEventQueue--> dispatcher --> localizers
//                                                                                      \-> JSON lines
//
// The block runner (AudioBlockRunner) is a plain object, testable on one thread; Pipeline only adds
// the threads and the orderly shutdown (stop sources, drain rings through the detectors, finish
// detectors, drain the bus, finish localizers, flush sinks).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/audio_source.hpp"
#include "locus/config.hpp"
#include "locus/detector.hpp"
#include "locus/event_bus.hpp"
#include "locus/registry.hpp"

namespace locus {

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

struct DeviceStats {
  std::string id;
  std::uint64_t frames_processed = 0;
  std::uint64_t frames_lost = 0;
  std::uint64_t overruns = 0;
  std::uint64_t events_dropped = 0;
  std::string source_error;
};

class Pipeline {
 public:
  /// [main] Instantiates and configures every source, detector, localizer and sink of `config`.
  /// Throws std::runtime_error naming the component that failed.
  Pipeline(const Config& config, Registry& registry);
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
  void stop();

  std::vector<DeviceStats> stats() const;
  std::uint64_t events_delivered(EventType type) const noexcept { return bus_.delivered(type); }

 private:
  struct Device;
  struct LocalizerInstance;
  void run_device(Device& device);

  const Config config_;
  Registry& registry_;
  EventBus bus_;
  std::unique_ptr<Link> link_;
  std::unique_ptr<Link> dispatched_link_;
  std::unique_ptr<FftPlanner> fft_;
  std::unique_ptr<Clock> clock_;
  std::vector<std::unique_ptr<Device>> devices_;
  std::vector<std::unique_ptr<LocalizerInstance>> localizers_;
  std::unique_ptr<class JsonLinesWriter> writer_;
  std::unique_ptr<Publisher> publisher_;
  bool started_ = false;
  bool stopped_ = false;
};

}  // namespace locus
