// `jack` source and sink (see jack_backend.hpp): parameters, validation, and the thin AudioSource /
// AudioSink faces of SharedJackClient.
#include "jack/jack_backend.hpp"

#include <jack/jack.h>
#include <regex.h>

#include <sstream>
#include <stdexcept>

namespace locus::hal::jack {

namespace {

[[noreturn]] void fail(const std::string& message) { throw std::runtime_error("jack: " + message); }

ParamSchema common_schema(bool source) {
  ParamSchema s;
  s.push_back(string_param("server", std::string(""),
                           "JACK server name (jackd -n NAME); empty = $JACK_DEFAULT_SERVER, else 'default'. "
                           "Never started by locus."));
  s.push_back(string_param("client_name", std::string("locus"),
                           "JACK client name (exact; ports are NAME:in_1.. and NAME:out_1..). A source and a sink "
                           "with the same server and client_name share one client and one frame clock."));
  s.push_back(int_param("channels", std::int64_t{source ? 1 : 1}, 1, kMaxPorts, "",
                        source ? "Input ports (capture channels) in_1..in_N."
                               : "Output ports (playback channels) out_1..out_M."));
  s.push_back(string_param("connect", std::string(""),
                           source ? "Regex (as jack_get_ports takes it, POSIX extended) of output ports to connect, in "
                                    "order, to in_1..in_N, e.g. 'system:capture_.*'; re-applied when ports appear; "
                                    "empty = connect nothing."
                                  : "Regex (as jack_get_ports takes it, POSIX extended) of input ports that out_1..out_M "
                                    "connect to, in order, e.g. 'system:playback_.*'; re-applied when ports appear; "
                                    "empty = connect nothing."));
  s.push_back(float_param("reconnect_backoff_s", 0.5, 0.01, 60.0, "s",
                          "First retry delay after the server went away; doubles per failed attempt up to "
                          "max(this, 5 s)."));
  s.push_back(int_param("reconnect_max", std::int64_t{0}, 0, 1e9, "",
                        "Failed reconnection attempts before the stream ends with an error; 0 = retry until stopped."));
  return s;
}

}  // namespace

const ParamSchema& jack_source_schema() {
  static const ParamSchema s = common_schema(true);
  return s;
}
const ParamSchema& jack_sink_schema() {
  static const ParamSchema s = common_schema(false);
  return s;
}

JackParams JackParams::from_params(const Params& p) {
  JackParams j;
  try {
    j.server = p.get_string("server");
    j.client_name = p.get_string("client_name");
    const std::int64_t ch = p.get_int("channels");
    if (ch < 1 || ch > kMaxPorts)
      fail("channels must be 1.." + std::to_string(kMaxPorts) + " (got " + std::to_string(ch) + ")");
    j.channels = static_cast<std::uint32_t>(ch);
    j.connect = p.get_string("connect");
    j.reconnect.backoff_s = p.get_float("reconnect_backoff_s");
    const std::int64_t max = p.get_int("reconnect_max");
    if (max < 0) fail("reconnect_max must be >= 0 (got " + std::to_string(max) + "; 0 = forever)");
    j.reconnect.max_attempts = max;
  } catch (const std::out_of_range& e) {
    fail(std::string("missing or mistyped parameter: ") + e.what());
  }
  if (j.client_name.empty()) fail("client_name must not be empty");
  const auto max_name = static_cast<std::size_t>(jack_client_name_size()) - 1;
  if (j.client_name.size() > max_name)
    fail("client_name '" + j.client_name + "' is longer than JACK's " + std::to_string(max_name) + " characters");
  if (j.client_name.find(':') != std::string::npos)
    fail("client_name '" + j.client_name + "' must not contain ':' (it separates client and port in JACK names)");
  if (!(j.reconnect.backoff_s >= 0.01 && j.reconnect.backoff_s <= 60.0)) {
    std::ostringstream os;
    os << "reconnect_backoff_s must be in [0.01, 60] s (got " << j.reconnect.backoff_s << ")";
    fail(os.str());
  }
  if (!j.connect.empty()) {
    regex_t re;
    const int r = regcomp(&re, j.connect.c_str(), REG_EXTENDED | REG_NOSUB);
    if (r != 0) {
      char buf[256];
      regerror(r, &re, buf, sizeof buf);
      fail("connect '" + j.connect + "' is not a valid port pattern (POSIX extended regex, as jack_get_ports takes it): " +
           buf);
    }
    regfree(&re);
  }
  return j;
}

// ---------------------------------------------------------------- source

JackSource::~JackSource() {
  if (client_) client_->detach(SharedJackClient::Part::Capture);
}

void JackSource::open(const Params& params, HostContext& ctx) { open(JackParams::from_params(params), ctx.log); }

void JackSource::open(const JackParams& params, Logger& log) {
  if (client_) fail("open() called twice");
  params_ = params;
  auto client = SharedJackClient::acquire(params.server, params.client_name, params.reconnect, log);
  client->attach(SharedJackClient::Part::Capture, params.channels, params.connect, log);
  client_ = std::move(client);
}

void JackSource::start(AudioRing& ring) {
  if (!client_) fail("start() before open()");
  client_->start_capture(ring);
  capturing_.store(true, std::memory_order_release);
}

void JackSource::stop() {
  // capturing_ stays set: the origin still describes the frames already in the ring.
  if (client_) client_->stop(SharedJackClient::Part::Capture);
}

// ---------------------------------------------------------------- sink

JackSink::~JackSink() {
  if (client_) client_->detach(SharedJackClient::Part::Playback);
}

void JackSink::open(const Params& params, HostContext& ctx) { open(JackParams::from_params(params), ctx.log); }

void JackSink::open(const JackParams& params, Logger& log) {
  if (client_) fail("open() called twice");
  params_ = params;
  auto client = SharedJackClient::acquire(params.server, params.client_name, params.reconnect, log);
  client->attach(SharedJackClient::Part::Playback, params.channels, params.connect, log);
  client_ = std::move(client);
}

void JackSink::start(PlaybackScheduler& scheduler) {
  if (!client_) fail("start() before open()");
  client_->start_playback(scheduler);
}

void JackSink::stop() {
  if (client_) client_->stop(SharedJackClient::Part::Playback);
}

// ---------------------------------------------------------------- registration

void register_jack_backends(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "jack",
      "JACK client input ports (capture; shares one client and clock with a jack sink of the same client_name)",
      jack_source_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<JackSource>()); },
  });
  registry.add_sink(SinkDescriptor{
      "jack",
      "JACK client output ports (playback of scheduled emissions; shares the client of a jack source)",
      jack_sink_schema(),
      [] { return std::unique_ptr<AudioSink>(std::make_unique<JackSink>()); },
  });
}

}  // namespace locus::hal::jack
