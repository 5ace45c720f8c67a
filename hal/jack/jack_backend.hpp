// `jack` audio source and `jack` playback sink: a JACK client with N input ports (capture into the
// device's AudioRing) and/or M output ports (playback from the device's PlaybackScheduler).
//
// Why one file for both: they are two faces of the same shared client (jack_client.hpp): a source and
// a sink with the same `server` and `client_name` on one node are ONE JACK client with one process
// callback, so capture frame F and playback frame F are the same instant of the same stream. The
// server must run at the node's sample rate (the pipeline refuses a source whose rate differs; the
// sink refuses a scheduler of another rate at start()). libjack never starts a server for us
// (JackNoStartServer): open() fails with a clear error when none runs. A server that goes away later
// is waited for and the stream resumes, the outage reported as lost frames (docs/hal-jack.md).
#pragma once

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

#include "jack/jack_client.hpp"
#include "locus/audio_source.hpp"
#include "locus/params.hpp"
#include "locus/playback.hpp"
#include "locus/registry.hpp"

namespace locus::hal::jack {

/// Validated parameters of a jack source or sink.
struct JackParams {
  std::string server;        ///< "" = $JACK_DEFAULT_SERVER or "default"
  std::string client_name = "locus";
  std::uint32_t channels = 1;
  std::string connect;       ///< jack_get_ports regex; "" = connect nothing
  ReconnectPolicy reconnect;

  /// Reads and checks every key of jack_source_schema()/jack_sink_schema(). Throws std::runtime_error
  /// naming the parameter and what was expected.
  static JackParams from_params(const Params& params);
};

const ParamSchema& jack_source_schema();
const ParamSchema& jack_sink_schema();

/// Registers the "jack" source and the "jack" sink.
void register_jack_backends(Registry& registry);

class JackSource final : public AudioSource {
 public:
  JackSource() = default;
  ~JackSource() override;

  void open(const Params& params, HostContext& ctx) override;
  /// Same as open() from ready parameters (tests, tools).
  void open(const JackParams& params, Logger& log);
  std::uint32_t channels() const override { return params_.channels; }
  double sample_rate_hz() const override { return client_ ? client_->sample_rate_hz() : 0.0; }
  bool live() const override { return true; }
  void start(AudioRing& ring) override;
  void stop() override;
  /// A live source ends only when its client gave up (see SharedJackClient::failed).
  bool finished() const noexcept override { return client_ && client_->failed(); }
  std::string error() const override { return client_ ? client_->error() : std::string(); }
  /// The client's (SharedJackClient::frame_zero_monotonic_s: the ring has the client's frame numbers)
  /// once capturing started (kept after stop(): it still describes the frames captured); NaN before start().
  double frame_zero_monotonic_s() const noexcept override {
    return client_ && capturing_.load(std::memory_order_acquire) ? client_->frame_zero_monotonic_s()
                                                                 : std::numeric_limits<double>::quiet_NaN();
  }

  /// [any] The shared client (nullptr before open()).
  const SharedJackClient* client() const noexcept { return client_.get(); }

 private:
  JackParams params_;
  std::shared_ptr<SharedJackClient> client_;
  std::atomic<bool> capturing_{false};
};

class JackSink final : public AudioSink {
 public:
  JackSink() = default;
  ~JackSink() override;

  void open(const Params& params, HostContext& ctx) override;
  void open(const JackParams& params, Logger& log);
  std::uint32_t channels() const override { return params_.channels; }
  double sample_rate_hz() const override { return client_ ? client_->sample_rate_hz() : 0.0; }
  void start(PlaybackScheduler& scheduler) override;
  void stop() override;
  std::uint64_t xruns() const noexcept override { return client_ ? client_->processor().xruns() : 0; }
  std::string error() const override { return client_ ? client_->error() : std::string(); }

  const SharedJackClient* client() const noexcept { return client_.get(); }

 private:
  JackParams params_;
  std::shared_ptr<SharedJackClient> client_;
};

}  // namespace locus::hal::jack
