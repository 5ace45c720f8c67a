// hal/jack against a real JACK server (jackd, dummy driver, non-realtime `-r`) that each test starts
// and stops itself by PID under a unique name (locus_jack_<pid>_<n>); jackd also gets PR_SET_PDEATHSIG
// so it cannot outlive a crashed test. The other JACK clients (a player, a recorder, a "wire" standing
// in for the air between a speaker and a microphone) are plain libjack clients inside this process.
//
// What is checked (never "no xruns": they happen on a shared machine; they are counted and printed):
//   - a chirp played by another client is captured bit-exact, at the stream frame predicted from the
//     server's frame time (period-aligned);
//   - a clip scheduled at playback frame F reaches a recording client bit-exact at the server frame
//     time that corresponds to F;
//   - a source and a sink with one client_name are one JACK client, and the device records its own
//     emission (through the wire) bit-exact at one fixed, period-aligned offset;
//   - jackd SIGKILLed mid-stream and restarted under the same name: the source reconnects by itself,
//     re-connects its ports by pattern, resumes bit-exact, reports the outage as lost frames of about
//     the outage's length, and the consumer sees one continuous frame counter;
//   - reconnect_max ends the stream with a clear error; a server at another rate is refused;
//     a second source on one client is refused; the port list shows the server's and our ports.
#include <gtest/gtest.h>
#include <jack/jack.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <mutex>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "jack/jack_backend.hpp"
#include "jack/jack_client.hpp"
#include "jack/jack_devices.hpp"
#include "locus/config.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus::hal::jack {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr std::uint32_t kPeriod = 256;
constexpr double kRate = 44100.0;

std::string unique_server() {
  static int n = 0;
  return "locus_jack_" + std::to_string(::getpid()) + "_" + std::to_string(++n);
}

bool wait_for(const std::function<bool()>& cond, std::chrono::milliseconds timeout) {
  const auto end = Clock::now() + timeout;
  while (Clock::now() < end) {
    if (cond()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return cond();
}

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// ------------------------------------------------------------------ jackd, by PID

class Jackd {
 public:
  explicit Jackd(std::string name, int rate = 44100) : name_(std::move(name)), rate_(rate) {
    log_ = (fs::temp_directory_path() / (name_ + ".log")).string();
  }
  ~Jackd() {
    stop();
    if (killed_) {
      // A SIGKILLed jackd leaves its entry in JACK's machine-wide server registry (8 slots, reclaimed
      // only by a server of the same name): start and stop one cleanly to give the slot back.
      if (start().empty()) stop();
    }
    remove_shm();
    std::error_code ec;
    fs::remove(log_, ec);
  }
  const std::string& name() const { return name_; }

  /// "" when the server answers a client within 10 s, else why not.
  std::string start() {
    killed_ = false;
    pid_ = ::fork();
    if (pid_ < 0) return "fork failed";
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      FILE* f = std::fopen(log_.c_str(), "a");
      if (f != nullptr) {
        ::dup2(fileno(f), 1);
        ::dup2(fileno(f), 2);
      }
      ::setenv("JACK_NO_AUDIO_RESERVATION", "1", 1);
      const std::string rate = std::to_string(rate_), period = std::to_string(kPeriod);
      ::execlp("jackd", "jackd", "-n", name_.c_str(), "-r", "-S", "-d", "dummy", "-r", rate.c_str(), "-p", period.c_str(),
               static_cast<char*>(nullptr));
      ::_exit(127);
    }
    const auto end = Clock::now() + 10s;
    while (Clock::now() < end) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return "jackd exited early: " + log_text();
      }
      jack_status_t st{};
      jack_client_t* jc = nullptr;
      {
        QuietJack quiet;
        jc = jack_client_open("locus_ready_probe", static_cast<jack_options_t>(JackNoStartServer | JackServerName), &st,
                              name_.c_str());
        if (jc != nullptr) jack_client_close(jc);
      }
      if (jc != nullptr) return "";
      std::this_thread::sleep_for(50ms);
    }
    stop();
    return "jackd did not answer within 10 s: " + log_text();
  }
  void kill9() {
    if (pid_ <= 0) return;
    killed_ = true;
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    const auto end = Clock::now() + 5s;
    while (Clock::now() < end) {
      if (::waitpid(pid_, nullptr, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(20ms);
    }
    kill9();
  }
  std::string log_text() const {
    std::ifstream in(log_);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }

 private:
  void remove_shm() {  // what a SIGKILLed jackd leaves behind, for this server name only
    std::error_code ec;
    for (const auto& e : fs::directory_iterator("/dev/shm", ec)) {
      const std::string n = e.path().filename().string();
      if (n.find("_" + name_ + "_") != std::string::npos) fs::remove(e.path(), ec);
    }
  }
  std::string name_, log_;
  int rate_;
  pid_t pid_ = -1;
  bool killed_ = false;
};

// ------------------------------------------------------------------ other JACK clients

/// A libjack client: plays a signal once (Play), a continuous pattern of the server frame time
/// (Pattern), records its input (Record) or copies input to output (Wire).
class Peer {
 public:
  enum class Mode { Play, Pattern, Record, Wire };
  static float pattern(std::uint32_t ft) { return static_cast<float>(ft % 8191u + 1u) / 16384.0f; }

  Peer(const std::string& server, const std::string& name, Mode mode, std::uint32_t n_out, std::uint32_t n_in,
       std::size_t record_frames = 0)
      : mode_(mode), record_(record_frames, std::numeric_limits<float>::quiet_NaN()) {
    jack_status_t st{};
    jc_ = jack_client_open(name.c_str(), static_cast<jack_options_t>(JackNoStartServer | JackServerName | JackUseExactName),
                           &st, server.c_str());
    if (jc_ == nullptr) throw std::runtime_error("peer " + name + ": jack_client_open failed");
    for (std::uint32_t i = 0; i < n_out; ++i)
      outs_.push_back(jack_port_register(jc_, ("out_" + std::to_string(i + 1)).c_str(), JACK_DEFAULT_AUDIO_TYPE,
                                         JackPortIsOutput, 0));
    for (std::uint32_t i = 0; i < n_in; ++i)
      ins_.push_back(jack_port_register(jc_, ("in_" + std::to_string(i + 1)).c_str(), JACK_DEFAULT_AUDIO_TYPE,
                                        JackPortIsInput, 0));
    jack_set_process_callback(jc_, [](jack_nframes_t n, void* a) { return static_cast<Peer*>(a)->process(n); }, this);
    jack_activate(jc_);
  }
  ~Peer() {
    QuietJack quiet;
    jack_client_close(jc_);
  }
  void set_signal(std::vector<std::vector<float>> s) { signal_ = std::move(s); }
  void arm() { armed_.store(true, std::memory_order_release); }
  bool done() const { return done_.load(std::memory_order_acquire); }
  std::uint32_t start_frame_time() const { return start_ft_.load(std::memory_order_acquire); }
  std::size_t recorded() const { return rec_len_.load(std::memory_order_acquire); }
  const std::vector<float>& record() const { return record_; }
  bool out_connected(std::size_t i) const { return jack_port_connected(outs_[i]) > 0; }
  bool in_connected(std::size_t i) const { return jack_port_connected(ins_[i]) > 0; }

 private:
  int process(jack_nframes_t n) {
    const std::uint32_t ft = jack_last_frame_time(jc_);
    std::vector<float*> out(outs_.size());
    for (std::size_t c = 0; c < outs_.size(); ++c) out[c] = static_cast<float*>(jack_port_get_buffer(outs_[c], n));
    const bool armed = armed_.load(std::memory_order_acquire);
    switch (mode_) {
      case Mode::Play: {
        // Sample k of the signal goes out at server frame time start + k: positioned by the server
        // clock like a real player, so cycles the server skipped (xruns) skip signal too.
        if (armed && !started_) {
          started_ = true;
          start_ft_.store(ft, std::memory_order_release);
        }
        const std::uint32_t start = start_ft_.load(std::memory_order_relaxed);
        for (std::size_t c = 0; c < out.size(); ++c) {
          for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t k = ft + i - start;
            out[c][i] = (started_ && k < signal_[c].size()) ? signal_[c][k] : 0.0f;
          }
        }
        if (started_ && ft + n - start >= signal_[0].size()) done_.store(true, std::memory_order_release);
        break;
      }
      case Mode::Pattern:
        for (auto* o : out)
          for (std::uint32_t i = 0; i < n; ++i) o[i] = pattern(ft + i);
        break;
      case Mode::Record: {
        // Sample at server frame time start + k goes to record_[k] (cycles the server skipped stay NaN).
        const auto* in = static_cast<const float*>(jack_port_get_buffer(ins_[0], n));
        if (armed && !started_) {
          started_ = true;
          start_ft_.store(ft, std::memory_order_release);
        }
        if (started_) {
          const std::uint32_t k0 = ft - start_ft_.load(std::memory_order_relaxed);
          for (std::uint32_t i = 0; i < n && k0 + i < record_.size(); ++i) record_[k0 + i] = in[i];
          rec_len_.store(std::min<std::size_t>(k0 + n, record_.size()), std::memory_order_release);
        }
        break;
      }
      case Mode::Wire: {
        const auto* in = static_cast<const float*>(jack_port_get_buffer(ins_[0], n));
        for (std::uint32_t i = 0; i < n; ++i) out[0][i] = in[i];
        break;
      }
    }
    return 0;
  }

  jack_client_t* jc_ = nullptr;
  Mode mode_;
  std::vector<jack_port_t*> outs_, ins_;
  std::vector<std::vector<float>> signal_;
  std::vector<float> record_;
  bool started_ = false;  // RT-owned
  std::atomic<bool> armed_{false}, done_{false};
  std::atomic<std::uint32_t> start_ft_{0};
  std::atomic<std::size_t> rec_len_{0};
};

// ------------------------------------------------------------------ the consumer of the ring

/// Drains a ring on its own thread into a vector indexed by stream frame (NaN = never received) and
/// checks that the frame counter is continuous: each read starts at previous end + frames lost.
class Collector {
 public:
  Collector(AudioRing& ring, std::size_t max_frames)
      : ring_(ring), ch_(ring.channels()), data_(max_frames * ring.channels(), std::numeric_limits<float>::quiet_NaN()) {
    thread_ = std::thread([this] { run(); });
  }
  ~Collector() { stop(); }
  void stop() {
    quit_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  std::uint64_t next_frame() const { return next_.load(std::memory_order_acquire); }
  /// Frame-major samples: at(frame, channel).
  float at(std::uint64_t f, std::uint32_t c) const { return data_[f * ch_ + c]; }
  std::uint64_t size_frames() const { return data_.size() / ch_; }
  std::uint64_t lost_seen = 0;
  std::uint64_t gaps_seen = 0;
  std::uint64_t largest_gap = 0;
  bool continuous = true;

 private:
  void run() {
    std::vector<float> buf(1024 * ch_);
    for (;;) {
      std::uint64_t first = 0, lost = 0;
      const std::size_t n = ring_.read(buf.data(), 1024, &first, &lost);
      if (n == 0 && lost == 0) {
        if (quit_.load()) return;
        std::this_thread::sleep_for(2ms);
        continue;
      }
      const std::uint64_t next = next_.load(std::memory_order_relaxed);
      if (first != next + lost) continuous = false;
      if (lost != 0) {
        lost_seen += lost;
        ++gaps_seen;
        largest_gap = std::max(largest_gap, lost);
      }
      for (std::size_t i = 0; i < n; ++i)
        if (first + i < size_frames())
          for (std::uint32_t c = 0; c < ch_; ++c) data_[(first + i) * ch_ + c] = buf[i * ch_ + c];
      next_.store(first + n, std::memory_order_release);
    }
  }
  AudioRing& ring_;
  std::uint32_t ch_;
  std::vector<float> data_;
  std::atomic<std::uint64_t> next_{0};
  std::atomic<bool> quit_{false};
  std::thread thread_;
};

std::vector<float> chirp(std::size_t frames, double f0, double f1, double amplitude) {
  // cos, so that the first sample is not 0 and the start is unambiguous.
  std::vector<float> v(frames);
  const double d = static_cast<double>(frames) / kRate;
  for (std::size_t i = 0; i < frames; ++i) {
    const double t = static_cast<double>(i) / kRate;
    v[i] = static_cast<float>(amplitude * std::cos(2.0 * std::numbers::pi * (f0 * t + (f1 - f0) * t * t / (2.0 * d))));
  }
  return v;
}

JackParams params(const std::string& server, const std::string& client, std::uint32_t channels,
                  const std::string& connect) {
  JackParams p;
  p.server = server;
  p.client_name = client;
  p.channels = channels;
  p.connect = connect;
  p.reconnect.backoff_s = 0.1;
  return p;
}

/// Stream frame of server frame time `ft` on the connection described by the processor's anchor.
std::uint64_t stream_frame_of(const JackProcessor& proc, std::uint32_t ft) {
  return proc.anchor_frame() + static_cast<std::uint32_t>(ft - proc.anchor_frame_time());
}

void report(const std::string& what, const JackProcessor& proc) {
  std::cout << "[ jack     ] " << what << ": xruns " << proc.xruns() << ", frames lost " << proc.frames_lost()
            << ", skipped-cycle events " << proc.skip_events() << ", cycles " << proc.cycles() << std::endl;
}

// ------------------------------------------------------------------ tests

TEST(JackIntegration, CapturesAChirpFromAnotherClientBitExactAtThePredictedFrame) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  const std::vector<float> c0 = chirp(8820, 200.0, 8000.0, 0.5);  // 0.2 s
  std::vector<float> c1(c0.size());
  for (std::size_t i = 0; i < c0.size(); ++i) c1[i] = -0.7f * c0[i];
  Peer peer(jd.name(), "player", Peer::Mode::Play, 2, 0);
  peer.set_signal({c0, c1});

  test::RecordingLogger log;
  JackSource src;
  src.open(params(jd.name(), "locus_cap", 2, "player:out_.*"), log);
  EXPECT_EQ(src.channels(), 2u);
  EXPECT_EQ(src.sample_rate_hz(), kRate);
  EXPECT_TRUE(src.live());
  AudioRing ring(2, 1 << 16);
  Collector col(ring, 44100 * 20);
  src.start(ring);
  ASSERT_TRUE(wait_for([&] { return src.client()->running() && peer.out_connected(0) && peer.out_connected(1); }, 10s));
  ASSERT_TRUE(wait_for([&] { return col.next_frame() > 8 * kPeriod; }, 10s));
  peer.arm();
  ASSERT_TRUE(wait_for([&] { return peer.done(); }, 10s));
  const std::uint64_t want_end = col.next_frame() + 4 * kPeriod;
  ASSERT_TRUE(wait_for([&] { return col.next_frame() > want_end; }, 10s));
  src.stop();
  col.stop();
  const JackProcessor& proc = src.client()->processor();
  report("capture", proc);
  EXPECT_TRUE(col.continuous);
  EXPECT_TRUE(log.contains("connected player:out_1 -> locus_cap:in_1"));
  EXPECT_TRUE(log.contains("connected player:out_2 -> locus_cap:in_2"));

  const std::uint64_t at = stream_frame_of(proc, peer.start_frame_time());
  EXPECT_EQ((at - proc.anchor_frame()) % kPeriod, 0u) << "period-aligned";
  ASSERT_LT(at + c0.size(), col.size_frames());
  EXPECT_EQ(col.at(at - 1, 0), 0.0f) << "silence before the chirp";
  std::size_t mismatches = 0, received = 0;
  for (std::size_t i = 0; i < c0.size(); ++i) {
    if (std::isnan(col.at(at + i, 0))) continue;  // lost to a skipped cycle (counted, reported)
    ++received;
    if (col.at(at + i, 0) != c0[i] || col.at(at + i, 1) != c1[i]) ++mismatches;
  }
  EXPECT_EQ(mismatches, 0u) << "chirp expected bit-exact at stream frame " << at;
  EXPECT_GE(received, c0.size() / 2) << "most of the chirp received";
  EXPECT_EQ(received + proc.frames_lost() >= c0.size(), true);
  const float after = col.at(at + c0.size(), 0);
  EXPECT_TRUE(after == 0.0f || std::isnan(after)) << "silence after the chirp";
}

TEST(JackIntegration, SinkPlaysAScheduledClipIntoARecordingClientAtTheScheduledFrame) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  Peer rec(jd.name(), "recorder", Peer::Mode::Record, 0, 1, 44100 * 5);
  test::RecordingLogger log;
  JackSink sink;
  sink.open(params(jd.name(), "locus_play", 1, "recorder:in_.*"), log);
  EXPECT_EQ(sink.sample_rate_hz(), kRate);
  PlaybackScheduler sched(kRate);
  sink.start(sched);
  ASSERT_TRUE(wait_for([&] { return sink.client()->running() && rec.in_connected(0) && sched.frame() > 0; }, 10s));
  rec.arm();
  ASSERT_TRUE(wait_for([&] { return rec.recorded() > 0; }, 10s));
  std::vector<float> clip = chirp(4410, 1000.0, 6000.0, 0.8);
  const std::uint64_t f = sched.frame() + 22050;  // 0.5 s ahead
  ASSERT_TRUE(sched.submit(clip, f));
  ASSERT_TRUE(wait_for([&] { return sched.clips_played() == 1; }, 10s));
  ASSERT_TRUE(wait_for([&] { return sched.frame() > f + clip.size() + 4 * kPeriod; }, 10s));
  sink.stop();
  const JackProcessor& proc = sink.client()->processor();
  report("playback", proc);
  EXPECT_EQ(sink.xruns(), proc.xruns());
  std::cout << "[ jack     ] clips cut by skipped cycles: " << sched.late_clips() << std::endl;

  // Frame f of the playback stream leaves in the cycle at server time anchor_ft + (f - anchor_frame).
  const std::uint32_t ft = proc.anchor_frame_time() + static_cast<std::uint32_t>(f - proc.anchor_frame());
  const std::size_t idx = static_cast<std::uint32_t>(ft - rec.start_frame_time());
  ASSERT_LT(idx + clip.size(), rec.recorded());
  const auto silent = [](float v) { return v == 0.0f || std::isnan(v); };
  EXPECT_TRUE(silent(rec.record()[idx - 1]));
  std::size_t mismatches = 0, received = 0;
  for (std::size_t i = 0; i < clip.size(); ++i) {
    const float v = rec.record()[idx + i];
    if (std::isnan(v)) continue;  // a cycle the server skipped
    ++received;
    mismatches += v != clip[i];
  }
  EXPECT_EQ(mismatches, 0u) << "clip expected bit-exact at recorder frame " << idx;
  EXPECT_GE(received, clip.size() / 2);
  EXPECT_TRUE(silent(rec.record()[idx + clip.size()]));
}

TEST(JackIntegration, SourceAndSinkShareOneClientAndTheDeviceRecordsItsOwnEmissionAtAFixedOffset) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  Peer wire(jd.name(), "wire", Peer::Mode::Wire, 1, 1);
  test::RecordingLogger log;
  JackSource src;
  JackSink sink;
  src.open(params(jd.name(), "locus_dev", 1, "wire:out_.*"), log);
  sink.open(params(jd.name(), "locus_dev", 1, "wire:in_.*"), log);
  ASSERT_EQ(src.client(), sink.client()) << "one JACK client for the source and the sink";
  {
    const auto ports = list_jack_ports(jd.name());
    int ours = 0;
    for (const auto& d : ports) ours += d.id == "locus_dev:in_1" || d.id == "locus_dev:out_1";
    EXPECT_EQ(ours, 2);
  }
  // A second source on the same client is refused.
  JackSource other;
  try {
    other.open(params(jd.name(), "locus_dev", 1, ""), log);
    ADD_FAILURE() << "a second source on one client was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("already has a jack source"), std::string::npos) << e.what();
  }

  AudioRing ring(1, 1 << 16);
  Collector col(ring, 44100 * 20);
  PlaybackScheduler sched(kRate);
  src.start(ring);
  sink.start(sched);
  ASSERT_TRUE(wait_for([&] { return src.client()->running() && wire.in_connected(0) && wire.out_connected(0); }, 10s));
  ASSERT_TRUE(wait_for([&] { return col.next_frame() > 8 * kPeriod; }, 10s));
  const std::vector<float> clip = chirp(2205, 2000.0, 8000.0, 0.6);
  const std::uint64_t f1 = sched.frame() + 22050, f2 = f1 + 30011;  // the second one not period-aligned
  ASSERT_TRUE(sched.submit(clip, f1));
  ASSERT_TRUE(sched.submit(clip, f2));
  ASSERT_TRUE(wait_for([&] { return sched.clips_played() == 2; }, 10s));
  ASSERT_TRUE(wait_for([&] { return col.next_frame() > f2 + clip.size() + 8 * kPeriod; }, 10s));
  src.stop();
  sink.stop();
  col.stop();
  report("shared client", src.client()->processor());

  // Bit-exact wherever frames were received (frames lost to skipped cycles are NaN: the stream frame
  // numbers stay true, so the offset does not move), and most of the clip received.
  auto find = [&](std::uint64_t f) -> std::int64_t {
    for (std::uint64_t d = 0; d <= 8 * kPeriod; ++d) {
      bool ok = true;
      std::size_t received = 0;
      for (std::size_t i = 0; i < clip.size() && ok; ++i) {
        const float v = col.at(f + d + i, 0);
        if (std::isnan(v)) continue;
        ++received;
        ok = v == clip[i];
      }
      if (ok && received >= clip.size() / 2) return static_cast<std::int64_t>(d);
    }
    return -1;
  };
  const std::int64_t d1 = find(f1), d2 = find(f2);
  std::cout << "[ jack     ] own emission found " << d1 << " and " << d2 << " frames after its scheduled frame" << std::endl;
  ASSERT_GE(d1, 0) << "emission 1 not found bit-exact within 8 periods";
  EXPECT_EQ(d1, d2) << "the offset between playback and capture is fixed";
  EXPECT_EQ(d1 % kPeriod, 0) << "and a whole number of periods";
}

TEST(JackIntegration, SurvivesJackdKilledAndRestartedMidStream) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  auto peer = std::make_unique<Peer>(jd.name(), "pattern", Peer::Mode::Pattern, 1, 0);
  test::RecordingLogger log;
  JackSource src;
  src.open(params(jd.name(), "locus_rs", 1, "pattern:out_.*"), log);
  AudioRing ring(1, 1 << 17);
  Collector col(ring, 44100 * 60);
  src.start(ring);
  const SharedJackClient& client = *src.client();
  ASSERT_TRUE(wait_for([&] { return client.running() && peer->out_connected(0); }, 10s));
  ASSERT_TRUE(wait_for([&] { return col.next_frame() > 44100; }, 10s));  // 1 s of stream

  const auto t_kill = Clock::now();
  jd.kill9();
  ASSERT_TRUE(wait_for([&] { return !client.running(); }, 10s)) << "the loss was not noticed";
  peer.reset();  // the old player died with its server
  const std::uint64_t frames_before = col.next_frame();
  std::this_thread::sleep_for(1s);
  EXPECT_FALSE(src.finished()) << "reconnect_max 0: waits for the server forever";
  EXPECT_EQ(col.next_frame(), frames_before) << "nothing is captured while the server is down";

  const auto t_restart = Clock::now();
  ASSERT_EQ(jd.start(), "") << "restart under the same name";
  peer = std::make_unique<Peer>(jd.name(), "pattern", Peer::Mode::Pattern, 1, 0);
  ASSERT_TRUE(wait_for([&] { return client.processor().resumes() == 1; }, 20s)) << "did not resume";
  const double t_resumed_s = since(t_kill);
  ASSERT_TRUE(wait_for([&] { return peer->out_connected(0); }, 10s)) << "ports not re-connected by pattern";
  const std::uint64_t cycles_at = client.processor().cycles();
  ASSERT_TRUE(wait_for([&] { return client.processor().cycles() > cycles_at + 44100 / kPeriod; }, 10s));  // 1 s more
  src.stop();
  col.stop();
  const JackProcessor& proc = client.processor();
  report("restart", proc);

  EXPECT_EQ(client.reconnects(), 1u);
  EXPECT_FALSE(src.finished());
  EXPECT_EQ(src.error(), "");
  const double gap_s = static_cast<double>(proc.last_resume_gap_frames()) / kRate;
  const double lo = std::chrono::duration<double>(t_restart - t_kill).count() - 0.05;
  std::cout << "[ jack     ] outage: reported gap " << gap_s << " s; server down for >= " << lo + 0.05
            << " s; resumed " << t_resumed_s << " s after the kill" << std::endl;
  EXPECT_GE(gap_s, lo);
  EXPECT_LE(gap_s, t_resumed_s + 0.1);
  EXPECT_TRUE(col.continuous) << "one frame counter across the outage";
  EXPECT_GE(col.lost_seen, proc.last_resume_gap_frames());
  EXPECT_GE(col.largest_gap, proc.last_resume_gap_frames()) << "the outage reached the consumer as one gap";
  EXPECT_EQ(ring.frames_lost(), col.lost_seen);
  EXPECT_EQ(col.next_frame(), ring.producer_frame());
  EXPECT_TRUE(log.contains("the JACK server went away", LogLevel::Warn));
  EXPECT_TRUE(log.contains("stream resumed", LogLevel::Warn));

  // After the resume the data is the new player's pattern of the new server's frame time, bit-exact at
  // the frames the processor's current anchor predicts (frames lost to skipped cycles stay NaN).
  const std::uint64_t a = proc.anchor_frame();
  std::uint64_t first_signal = 0;
  for (std::uint64_t f = a; f < col.next_frame(); ++f) {
    if (col.at(f, 0) != 0.0f && !std::isnan(col.at(f, 0))) {
      first_signal = f;
      break;
    }
  }
  ASSERT_GT(first_signal, 0u) << "no signal after the resume";
  std::size_t checked = 0, mismatches = 0;
  for (std::uint64_t f = first_signal; f < col.next_frame(); ++f) {
    if (std::isnan(col.at(f, 0))) continue;
    ++checked;
    const std::uint32_t ft = proc.anchor_frame_time() + static_cast<std::uint32_t>(f - a);
    mismatches += col.at(f, 0) != Peer::pattern(ft);
  }
  EXPECT_GT(checked, 22050u);
  EXPECT_EQ(mismatches, 0u) << "data after the resume at the right frames";
}

TEST(JackIntegration, GivesUpAfterReconnectMaxWithAClearError) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  test::RecordingLogger log;
  JackSource src;
  JackParams p = params(jd.name(), "locus_gu", 1, "");
  p.reconnect.backoff_s = 0.05;
  p.reconnect.max_attempts = 3;
  src.open(p, log);
  AudioRing ring(1, 1 << 14);
  src.start(ring);
  ASSERT_TRUE(wait_for([&] { return src.client()->running(); }, 10s));
  jd.kill9();
  ASSERT_TRUE(wait_for([&] { return src.finished(); }, 20s)) << "never gave up";
  EXPECT_NE(src.error().find("did not come back after 3 reconnection attempts"), std::string::npos) << src.error();
  EXPECT_NE(src.error().find(jd.name()), std::string::npos);
  EXPECT_TRUE(log.contains("did not come back", LogLevel::Error));
  EXPECT_THROW(src.start(ring), std::runtime_error) << "a failed client refuses to start";
  src.stop();
}

TEST(JackIntegration, AServerAtAnotherRateIsRefused) {
  Jackd jd(unique_server(), 48000);
  ASSERT_EQ(jd.start(), "");
  // Through a real pipeline: the node runs at 44100 Hz.
  Registry registry;
  register_builtins(registry);
  const std::string yaml = "sample_rate_hz: 44100\noutput: {path: /dev/null, events: []}\ndevices:\n  - id: A\n"
                           "    audio:\n      source: jack\n      params: {server: " + jd.name() +
                           ", client_name: locus_rate}\n";
  const Config config = load_config_string(yaml, "rate.yaml", registry);
  try {
    Pipeline pipeline(config, registry);
    ADD_FAILURE() << "a 48 kHz JACK server was accepted for a 44.1 kHz node";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("runs at 48000"), std::string::npos) << m;
    EXPECT_NE(m.find("44100"), std::string::npos) << m;
  }
  test::RecordingLogger log;
  JackSink sink;
  sink.open(params(jd.name(), "locus_rate2", 1, ""), log);
  PlaybackScheduler sched(kRate);
  try {
    sink.start(sched);
    ADD_FAILURE() << "a 44.1 kHz playback stream was accepted by a 48 kHz server";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("runs at 48000.000 Hz but the playback stream is 44100.000 Hz"),
              std::string::npos)
        << e.what();
  }
}

TEST(JackIntegration, ListsTheServersPorts) {
  Jackd jd(unique_server());
  ASSERT_EQ(jd.start(), "");
  const auto list = list_jack_ports(jd.name());
  bool capture = false, playback = false;
  for (const auto& d : list) {
    EXPECT_EQ(d.backend, "jack");
    EXPECT_EQ(d.kind, "port");
    if (d.id == "system:capture_1") capture = d.description.find("output") == 0 && d.description.find("physical") != std::string::npos;
    if (d.id == "system:playback_1") playback = d.description.find("input") == 0;
  }
  EXPECT_TRUE(capture);
  EXPECT_TRUE(playback);
  jd.stop();
  const auto gone = list_jack_ports(jd.name());
  ASSERT_EQ(gone.size(), 1u);
  EXPECT_EQ(gone[0].kind, "unavailable");
}

}  // namespace
}  // namespace locus::hal::jack
