// A small JACK client for the record integration test: plays a mono float WAV into its output port
// `<client>:out`, exactly once, as soon as something is connected to the port (plus `--lead-periods`
// silent periods), then silence; exits 0 after `--tail-periods` more periods, 1 on a timeout or error.
//
//   jack_wav_player --server NAME --client NAME --wav FILE [--lead-periods N] [--tail-periods N]
//                   [--timeout-s S]
//
// Why a dedicated client: the test needs a known signal in the graph at a frame-exact position, and
// the stock JACK example clients play sines, not files. process() only copies from a preloaded buffer.
#include <jack/jack.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "locus/scene/streams.hpp"

namespace {

struct Player {
  jack_client_t* client = nullptr;
  jack_port_t* port = nullptr;
  std::vector<float> samples;
  std::size_t pos = 0;
  std::uint64_t lead_periods = 4;
  std::uint64_t connected_periods = 0;
  std::atomic<bool> playing{false};
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> periods_after_done{0};
  std::atomic<std::uint32_t> first_play_frame_time{0};
};

int process(jack_nframes_t nframes, void* arg) {
  auto* p = static_cast<Player*>(arg);
  auto* out = static_cast<float*>(jack_port_get_buffer(p->port, nframes));
  std::memset(out, 0, sizeof(float) * nframes);
  if (p->done.load(std::memory_order_relaxed)) {
    p->periods_after_done.fetch_add(1, std::memory_order_relaxed);
    return 0;
  }
  if (!p->playing.load(std::memory_order_relaxed)) {
    if (jack_port_connected(p->port) <= 0) return 0;
    if (++p->connected_periods <= p->lead_periods) return 0;
    p->playing.store(true, std::memory_order_relaxed);
    p->first_play_frame_time.store(jack_last_frame_time(p->client), std::memory_order_relaxed);
  }
  const std::size_t n = std::min<std::size_t>(nframes, p->samples.size() - p->pos);
  std::memcpy(out, p->samples.data() + p->pos, n * sizeof(float));
  p->pos += n;
  if (p->pos >= p->samples.size()) p->done.store(true, std::memory_order_release);
  return 0;
}

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr, "jack_wav_player: %s\nusage: jack_wav_player --server NAME --client NAME --wav FILE "
                       "[--lead-periods N] [--tail-periods N] [--timeout-s S]\n", why);
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  std::string server, client = "locus_player", wav;
  std::uint64_t lead = 4, tail = 8;
  double timeout_s = 30.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage(("missing value for " + a).c_str());
    const std::string v = argv[++i];
    if (a == "--server") server = v;
    else if (a == "--client") client = v;
    else if (a == "--wav") wav = v;
    else if (a == "--lead-periods") lead = std::stoull(v);
    else if (a == "--tail-periods") tail = std::stoull(v);
    else if (a == "--timeout-s") timeout_s = std::stod(v);
    else usage(("unknown option " + a).c_str());
  }
  if (wav.empty()) usage("--wav is required");

  Player p;
  p.lead_periods = lead;
  try {
    locus::scene::WavReader r(wav);
    if (r.info().channels != 1) usage("the WAV must be mono");
    p.samples.resize(r.info().frames);
    std::size_t got = 0;
    while (got < p.samples.size()) {
      const std::size_t n = r.read(p.samples.data() + got, p.samples.size() - got);
      if (n == 0) break;
      got += n;
    }
    p.samples.resize(got);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "jack_wav_player: %s\n", e.what());
    return 1;
  }

  jack_status_t status{};
  const auto options = static_cast<jack_options_t>(JackNoStartServer | (server.empty() ? 0 : JackServerName));
  jack_client_t* c = server.empty() ? jack_client_open(client.c_str(), options, &status)
                                    : jack_client_open(client.c_str(), options, &status, server.c_str());
  if (c == nullptr) {
    std::fprintf(stderr, "jack_wav_player: cannot connect to JACK server '%s' (status 0x%x)\n", server.c_str(), status);
    return 1;
  }
  p.client = c;
  p.port = jack_port_register(c, "out", JACK_DEFAULT_AUDIO_TYPE, JackPortIsOutput, 0);
  if (p.port == nullptr || jack_set_process_callback(c, process, &p) != 0 || jack_activate(c) != 0) {
    std::fprintf(stderr, "jack_wav_player: cannot register/activate\n");
    jack_client_close(c);
    return 1;
  }
  std::printf("ready %s:out rate %u period %u\n", jack_get_client_name(c), jack_get_sample_rate(c),
              jack_get_buffer_size(c));
  std::fflush(stdout);
  const auto t0 = std::chrono::steady_clock::now();
  int rc = 0;
  while (!(p.done.load(std::memory_order_acquire) && p.periods_after_done.load() >= tail)) {
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > timeout_s) {
      std::fprintf(stderr, "jack_wav_player: timeout (%s)\n", p.playing.load() ? "still playing" : "nobody connected");
      rc = 1;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (rc == 0) {
    std::printf("played %zu frames from frame time %u\n", p.samples.size(), p.first_play_frame_time.load());
  }
  jack_deactivate(c);
  jack_client_close(c);
  return rc;
}
