// Shared test doubles for the host services every plugin receives (header-only).
//
//   locus::test::TestHost host;                 // logger + clock + FFT planner + link
//   HostContext ctx = host.context("onset_a", "A");
//   locus::test::CollectingSink sink;           // an EventSink that keeps every event
//   locus::test::feed_planar(detector, channels, /*block_frames=*/256, sink);
//
// The doubles are deterministic and single-threaded unless stated: RecordingLogger is thread-safe,
// LoopbackLink delivers synchronously inside publish() (the real links deliver asynchronously).
#pragma once

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "locus/audio_source.hpp"
#include "locus/detector.hpp"
#include "locus/emitter.hpp"
#include "locus/events.hpp"
#include "locus/fft.hpp"
#include "locus/host.hpp"
#include "locus/link.hpp"
#include "locus/localizer.hpp"
#include "locus/signal.hpp"

namespace locus::test {

/// Keeps every message (thread-safe).
class RecordingLogger final : public Logger {
 public:
  struct Entry {
    LogLevel level;
    std::string message;
  };
  void log(LogLevel level, std::string_view message) override {
    std::lock_guard lock(mutex_);
    entries_.push_back(Entry{level, std::string(message)});
  }
  std::vector<Entry> entries() const {
    std::lock_guard lock(mutex_);
    return entries_;
  }
  /// True if some message at `min_level` or above contains `needle`.
  bool contains(std::string_view needle, LogLevel min_level = LogLevel::Trace) const {
    std::lock_guard lock(mutex_);
    return std::any_of(entries_.begin(), entries_.end(), [&](const Entry& e) {
      return e.level >= min_level && e.message.find(needle) != std::string::npos;
    });
  }
  void clear() {
    std::lock_guard lock(mutex_);
    entries_.clear();
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Entry> entries_;
};

/// An Emitter that records every schedule() call (or refuses them all, `refuse`); its playback frame
/// is whatever the test sets.
class RecordingEmitter : public Emitter {
 public:
  struct Call {
    SignalSpec signal;
    std::uint64_t start_frame;
    double gain;
  };
  explicit RecordingEmitter(std::uint64_t start_frame = 0, double rate_hz = 48000.0) : frame(start_frame), rate(rate_hz) {}
  bool schedule(const SignalSpec& signal, std::uint64_t start_frame, double gain, std::string* error) override {
    if (refuse) {
      if (error) *error = "too many emissions pending";
      return false;
    }
    calls.push_back({signal, start_frame, gain});
    return true;
  }
  std::uint64_t playback_frame() const noexcept override { return frame; }
  double sample_rate_hz() const noexcept override { return rate; }
  std::uint64_t late_emissions() const noexcept override { return 0; }
  std::vector<Call> calls;
  std::uint64_t frame = 0;
  double rate = 48000.0;
  bool refuse = false;
};

/// A clock the test moves by hand.
class ManualClock final : public Clock {
 public:
  double now_s() const noexcept override { return now_; }
  void set(double t_s) noexcept { now_ = t_s; }
  void advance(double dt_s) noexcept { now_ += dt_s; }

 private:
  double now_ = 0.0;
};

/// A direct O(n^2) real DFT with the RealFft contract (unnormalised; inverse(forward(x)) = n*x).
/// Slow but obviously correct: a reference for tests. Twiddles are made when planning, so executing
/// does not allocate.
class NaiveRealFft final : public RealFft {
 public:
  explicit NaiveRealFft(std::size_t n) : RealFft(n), cos_(n), sin_(n) {
    for (std::size_t k = 0; k < n; ++k) {
      const double a = 2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(n);
      cos_[k] = std::cos(a);
      sin_[k] = std::sin(a);
    }
  }
  void forward(const float* in, std::complex<float>* out) noexcept override {
    for (std::size_t k = 0; k <= n_ / 2; ++k) {
      double re = 0.0, im = 0.0;
      for (std::size_t t = 0; t < n_; ++t) {
        const std::size_t idx = (k * t) % n_;
        re += in[t] * cos_[idx];
        im -= in[t] * sin_[idx];
      }
      out[k] = {static_cast<float>(re), static_cast<float>(im)};
    }
  }
  void inverse(const std::complex<float>* in, float* out) noexcept override {
    for (std::size_t t = 0; t < n_; ++t) {
      double acc = 0.0;
      for (std::size_t k = 0; k < n_; ++k) {
        // Hermitian extension of the n/2+1 bins.
        const std::complex<double> c =
            k <= n_ / 2 ? std::complex<double>(in[k]) : std::conj(std::complex<double>(in[n_ - k]));
        const std::size_t idx = (k * t) % n_;
        acc += c.real() * cos_[idx] - c.imag() * sin_[idx];
      }
      out[t] = static_cast<float>(acc);
    }
  }

 private:
  std::vector<double> cos_, sin_;
};

class NaiveFftPlanner final : public FftPlanner {
 public:
  std::unique_ptr<RealFft> plan_real(std::size_t n) override {
    if (n < 2) throw std::invalid_argument("plan_real: n must be >= 2");
    ++plans_made;
    return std::make_unique<NaiveRealFft>(n);
  }
  std::size_t plans_made = 0;
};

/// In-memory link delivering synchronously inside publish() to every matching subscription
/// (MQTT wildcards via locus::topic_matches). Keeps a log of everything published.
class LoopbackLink final : public Link {
 public:
  void publish(std::string_view topic, std::string_view payload) override {
    LinkMessage msg{std::string(topic), std::string(payload)};
    published.push_back(msg);
    const auto subs = subs_;  // handlers may (un)subscribe
    for (const auto& [id, sub] : subs)
      if (topic_matches(sub.first, msg.topic)) sub.second(msg);
  }
  std::uint64_t subscribe(std::string_view filter, LinkHandler handler) override {
    subs_.emplace(next_id_, std::make_pair(std::string(filter), std::move(handler)));
    return next_id_++;
  }
  void unsubscribe(std::uint64_t id) override { subs_.erase(id); }
  std::size_t subscriptions() const noexcept { return subs_.size(); }

  std::vector<LinkMessage> published;

 private:
  std::map<std::uint64_t, std::pair<std::string, LinkHandler>> subs_;
  std::uint64_t next_id_ = 1;
};

/// Every host service a plugin needs, owned by the test. The context references stay valid for the
/// TestHost's lifetime.
struct TestHost {
  RecordingLogger log;
  ManualClock clock;
  NaiveFftPlanner fft;
  LoopbackLink link;

  /// A HostContext for instance `instance` on device `device` (the views must outlive its use).
  HostContext context(std::string_view instance = "test", std::string_view device = "dev0") {
    return HostContext{log, clock, fft, link, instance, device};
  }
};

/// An EventSink that keeps every event; with a capacity it refuses (returns false) once full, like a
/// full event queue.
class CollectingSink final : public EventSink {
 public:
  explicit CollectingSink(std::size_t capacity = SIZE_MAX) : capacity_(capacity) {
    events.reserve(std::min<std::size_t>(capacity, 4096));
  }
  bool emit(const Event& event) noexcept override {
    if (events.size() >= capacity_) {
      ++refused;
      return false;
    }
    events.push_back(event);
    return true;
  }
  std::vector<AudioDetection> detections() const {
    std::vector<AudioDetection> out;
    for (const Event& e : events)
      if (const auto* d = std::get_if<AudioDetection>(&e)) out.push_back(*d);
    return out;
  }
  /// Detections of one channel, in emission order.
  std::vector<AudioDetection> detections(std::uint16_t channel) const {
    std::vector<AudioDetection> out;
    for (const AudioDetection& d : detections())
      if (d.channel == channel) out.push_back(d);
    return out;
  }

  std::vector<Event> events;
  std::size_t refused = 0;

 private:
  std::size_t capacity_;
};

/// Feeds planar audio (one vector per channel, equal lengths) to `detector` in blocks of
/// `block_frames` (the last block may be shorter), numbering frames from `first_frame`. The first
/// block carries `lost_before`. Does not call finish().
inline void feed_planar(Detector& detector, const std::vector<std::vector<float>>& channels,
                        std::size_t block_frames, EventSink& sink, std::uint64_t first_frame = 0,
                        std::uint64_t lost_before = 0) {
  if (channels.empty() || block_frames == 0) return;
  const std::size_t total = channels[0].size();
  std::vector<const float*> ptrs(channels.size());
  for (std::size_t pos = 0; pos < total; pos += block_frames) {
    const std::size_t n = std::min(block_frames, total - pos);
    for (std::size_t c = 0; c < channels.size(); ++c) ptrs[c] = channels[c].data() + pos;
    AudioBlock block;
    block.channel_data = ptrs.data();
    block.channels = static_cast<std::uint32_t>(channels.size());
    block.frames = static_cast<std::uint32_t>(n);
    block.first_frame = first_frame + pos;
    block.lost_before = pos == 0 ? lost_before : 0;
    detector.process_audio(block, sink);
  }
}

/// Splits interleaved frames into planar channels.
inline std::vector<std::vector<float>> deinterleave(const std::vector<float>& interleaved, std::uint32_t channels) {
  const std::size_t frames = interleaved.size() / channels;
  std::vector<std::vector<float>> out(channels, std::vector<float>(frames));
  for (std::size_t i = 0; i < frames; ++i)
    for (std::uint32_t c = 0; c < channels; ++c) out[c][i] = interleaved[i * channels + c];
  return out;
}

/// Components that do nothing, for registry and config tests that only need something registered.
class NullDetector : public Detector {
 public:
  void configure(const StreamInfo&, const Params&, HostContext&) override {}
};

class NullLocalizer : public Localizer {
 public:
  void configure(const Params&, HostContext&) override {}
  std::vector<EventType> subscriptions() const override { return {EventType::AudioDetection}; }
  void on_event(const Event&, Publisher&) override {}
};

/// Descriptor callbacks for registry and config tests: a NullDetector, a NullLocalizer, an empty schema.
inline Detector* make_null_detector() { return new NullDetector; }
inline Localizer* make_null_localizer() { return new NullLocalizer; }
inline const ParamSchema* empty_schema() {
  static const ParamSchema schema;
  return &schema;
}

/// A one-channel, 44.1 kHz source that has already finished.
class NullSource : public AudioSource {
 public:
  void open(const Params&, HostContext&) override {}
  std::uint32_t channels() const override { return 1; }
  double sample_rate_hz() const override { return 44100.0; }
  bool live() const override { return false; }
  void start(AudioRing&) override {}
  void stop() override {}
  bool finished() const noexcept override { return true; }
};

/// TUM's working-pair chirps (2 -> 8 kHz up from `own_id`, 8 -> 2 kHz down from `other_id`, 40 ms, 5 ms
/// fades) as the signals a DeviceGeometry points at: the device's own emits and the scene's.
struct TumChirpSignals {
  std::vector<SignalSpec> own;
  std::vector<SceneSignal> scene;
};
inline TumChirpSignals tum_chirp_signals(const char* own_id, const char* other_id) {
  SignalSpec up, down;
  up.type = down.type = "lfm";
  up.f0_hz = down.f1_hz = 2000;
  up.f1_hz = down.f0_hz = 8000;
  up.duration_s = down.duration_s = 0.04;
  up.fade_s = down.fade_s = 0.005;
  return TumChirpSignals{{up}, {{own_id, up}, {other_id, down}}};
}

}  // namespace locus::test
