// Round-trip latency of the MQTT link on loopback: publish on a link -> the broker -> the same link's
// handler (a link hears its own messages), and publish on link A -> handler on link B (two clients, as
// two boards). Each iteration publishes one message and waits for its delivery, so the time per
// iteration is the round trip (the Time column, real time). The benchmark starts its own mosquitto broker (tests/integration/mqtt/
// broker.hpp) on a free port in 18830-18899 and stops it at the end.
//   BM_MqttRoundTrip/<qos>/<payload bytes>   own handler
//   BM_MqttPeer/<qos>/<payload bytes>        another client's handler
// Run: build/bin/locus_bench_mqtt --benchmark_min_time=1   (see docs/mqtt.md, "Latency")
#include <benchmark/benchmark.h>

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>

#include "integration/mqtt/broker.hpp"
#include "mqtt/mqtt_link.hpp"

namespace {

class QuietLogger final : public locus::Logger {
 public:
  void log(locus::LogLevel, std::string_view) override {}
};

struct Fixture {
  locus::testing::TempDir dir;
  locus::testing::Broker broker{dir.path(), {}};
  QuietLogger log;
  Fixture() { broker.start(); }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

locus::mqtt::MqttOptions options(int qos) {
  locus::mqtt::MqttOptions o;
  o.port = fixture().broker.port();
  o.qos = qos;
  return o;
}

class Waiter {
 public:
  locus::LinkHandler handler() {
    return [this](const locus::LinkMessage&) {
      {
        std::lock_guard lock(m_);
        ++count_;
      }
      cv_.notify_one();
    };
  }
  bool wait(std::uint64_t n) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return count_ >= n; });
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::uint64_t count_ = 0;
};

void run(benchmark::State& state, bool peer) {
  const int qos = static_cast<int>(state.range(0));
  const std::string payload(static_cast<std::size_t>(state.range(1)), 'x');
  auto a = std::make_unique<locus::mqtt::MqttLink>(options(qos), "bench", fixture().log);
  std::unique_ptr<locus::mqtt::MqttLink> b;
  if (peer) b = std::make_unique<locus::mqtt::MqttLink>(options(qos), "bench", fixture().log);
  locus::mqtt::MqttLink& receiver = peer ? *b : *a;
  Waiter waiter;
  receiver.subscribe("rt", waiter.handler());
  if (!receiver.wait_ready(10)) {
    state.SkipWithError("link not ready");
    return;
  }
  std::uint64_t n = 0;
  for (auto _ : state) {
    a->publish("rt", payload);
    if (!waiter.wait(++n)) {
      state.SkipWithError("message not delivered within 10 s");
      return;
    }
  }
  state.SetItemsProcessed(state.iterations());
}

void BM_MqttRoundTrip(benchmark::State& state) { run(state, false); }
void BM_MqttPeer(benchmark::State& state) { run(state, true); }

BENCHMARK(BM_MqttRoundTrip)->Args({0, 64})->Args({1, 64})->Args({1, 4096})->UseRealTime()->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_MqttPeer)->Args({0, 64})->Args({1, 64})->UseRealTime()->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
