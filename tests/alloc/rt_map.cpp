// Real-time safety with the live map's HTTP server running (locusd --http, tools/map): while the
// server serves a page's event stream and a client polling the state, the real-time side (the audio
// ring write of a HAL callback, the detector thread's event hand-over) and the map's own hand-over
// (EventTap::push, what each pipeline's dispatcher calls for every event the map gets) must not
// allocate, free or lock. The server's threads allocate and lock as they like: they are not counted
// (RtSection counts the calling thread only), which is the point — nothing of theirs leaks into ours.
#include <gtest/gtest.h>
#include <httplib.h>

#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include "locus/audio_ring.hpp"
#include "locus/config.hpp"
#include "locus/event_bus.hpp"
#include "map_server.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus {
namespace {

class NullLog final : public Logger {
 public:
  void log(LogLevel, std::string_view) override {}
};

TEST(RtSafety, HandOverToTheLiveMapDoesNotAllocateOrLockWithTheServerRunning) {
  NullLog log;
  std::vector<ConfigError> errors;
  const Params params = validate_params(map::map_schema(), {{"tap_capacity", "1024"}}, errors);
  ASSERT_TRUE(errors.empty());
  map::MapServer server(map::map_options("127.0.0.1:0", params), log);
  map::EventTap& tap = server.add_tap("A");
  server.start();

  // A page's event stream and a client hammering the state, for the whole measured section.
  std::atomic<bool> stop{false};
  std::atomic<long> streamed_bytes{0}, polls{0};
  std::thread stream([&] {
    httplib::Client c("127.0.0.1", server.port());
    c.set_read_timeout(5, 0);
    c.Get("/events?after=0", [&](const char*, std::size_t n) {
      streamed_bytes += static_cast<long>(n);
      return !stop.load();
    });
  });
  std::thread poller([&] {
    httplib::Client c("127.0.0.1", server.port());
    while (!stop.load()) {
      if (auto r = c.Get("/api/state"); r && r->status == 200) ++polls;
    }
  });

  AudioRing ring(2, 4096, 8);
  RtEventQueue queue("A", 256);
  std::vector<float> period(2 * 256, 0.1f), drain(2 * 4096);
  AudioDetection d;
  d.device = "A";
  d.detector = "chirp";
  d.snr_db = 30.0f;
  Estimate e;
  e.plugin = "amil";
  e.reference = "A";
  e.frame = "A_start";
  e.target = "B";
  e.std_m = 0.1;
  Event out;
  // Warm-up, then the measured section: 20 000 iterations with the server busy.
  for (int i = 0; i < 100; ++i) tap.push(e);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  long pushed = 0;
  RtSection rt;
  for (int i = 0; i < 20000; ++i) {
    ring.write(period.data(), 256);             // HAL callback
    if (i % 16 == 0) ring.read(drain.data(), 4096);
    d.frame = i;
    queue.emit(d);                              // detector thread -> dispatcher
    queue.pop(out);
    e.position_m = {0.001 * i, 1.0, 0.0};
    if (tap.push(out)) ++pushed;                // dispatcher -> map (the hand-over under test)
    if (tap.push(e)) ++pushed;
    if (i % 50 == 0) {
      // give the server's threads time to run (a sleep is a syscall, not an allocation or a lock)
      timespec ts{0, 200000};
      nanosleep(&ts, nullptr);
    }
  }
  rt.end();
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  stop = true;
  tap.push(e);  // wakes the stream so that its client can stop
  stream.join();
  poller.join();
  const auto stats = server.stats();
  server.stop();
  EXPECT_EQ(rt.allocs(), 0);
  EXPECT_EQ(rt.frees(), 0);
  EXPECT_EQ(rt.locks(), 0);
  // The server really was busy and really got the events.
  EXPECT_GT(pushed, 1000);
  EXPECT_GT(stats.events, 1000u);
  EXPECT_GT(streamed_bytes.load(), 100000);
  EXPECT_GT(polls.load(), 0);
}

}  // namespace
}  // namespace locus
