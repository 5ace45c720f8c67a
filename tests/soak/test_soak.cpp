// The fault-injection soak (issue 20): one live node with every real component, and a schedule of the
// faults a board meets in a week, checked after each one.
//
// The node is a real `locusd` (board config written here):
//   - audio: JACK capture from a dummy-driver jackd, into which a second JACK client ("soakplayer")
//     plays a 2-8 kHz chirp every 0.5 s over low noise; the `chirp` detector finds them;
//   - playback: a JACK sink on the same client (rendering silence, counting its xruns);
//   - imu: the `iio` source on a fake IIO tree whose FIFO a feeder thread writes at 200 Hz;
//   - ble: the `bluez` scanner on a private dbus-daemon with python3-dbusmock's bluez5 template as
//     bluetoothd, whose device RSSI the test changes every 200 ms;
//   - link: MQTT to a real mosquitto, with two localizers from tests/integration/live: e2e_link
//     `publish` sends every detection over the link, e2e_link `receive` turns each one it gets back
//     from the broker into an estimate (so a detection, a broker round trip and an estimate are one
//     chain that can be checked end to end); an MQTT output publishes the estimates as well;
//   - output: JSON lines into a FIFO read by this test (the "consumer", which the test can slow down).
// Faults, in a cycle until the run's time is up (LOCUS_SOAK_MINUTES, default 2):
//   jackd      jackd SIGKILLed, down 1 s, started again (the player comes back with it)
//   broker     mosquitto SIGKILLed, down 1.5 s, started again on the same port
//   bluez      the bluetoothd mock killed, down 1 s, started again with its adapter and device
//   iio_stall  the IMU FIFO gets nothing for 3 s
//   cpu        an xrun storm: the node is SIGSTOPped 5 x 0.4 s (a starved CPU)
//   hostile    malformed link messages on the node's topic: text, empty, 256 KiB of random bytes
//   slow       the output's consumer stops reading for 6 s (the pipe fills, the writer blocks)
//   gone       the output's consumer goes away for 2 s (EPIPE: lines counted as not written, logged)
//              and comes back (the node writes to it again)
// After each fault: the node is alive; detections, estimates, IMU samples and BLE adverts each resume
// within a stated time (kResume*); RSS and open file descriptors are sampled. At the end (SIGTERM):
// exit 0; the lost frames are reported (and cover the jackd outages); every malformed message counted;
// every detection came back as an estimate through the broker except those in the seconds around a
// broker restart or an output gap, or in flight at the stop (nothing accepted is lost); the lines the gone consumer missed are
// reported; RSS and fds flat. A table and soak-report.json (in the
// working directory) give the figures. `./run soak [MINUTES]` runs it by hand.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <map>
#include <mutex>
#include <random>
#include <regex>
#include <set>

#include <sdbus-c++/sdbus-c++.h>

#include "iio/fake_iio_tree.hpp"
#include "integration/live/live_support.hpp"
#include "integration/mqtt/broker.hpp"

namespace locus::testing::soak {
namespace {

using namespace locus::testing::live;
using locus::testing::Broker;
using locus::testing::TempDir;

const std::string kLocusd = LOCUSD_BIN;
const std::string kPluginDir = LIVE_PLUGIN_DIR;
constexpr int kRate = 44100;
constexpr double kChirpPeriodS = 0.5;
constexpr const char* kTagMac = "AA:BB:CC:DD:EE:51";

// How long each stream may take to come back after a fault ends (stated in docs/reliability.md).
// Audio and link in chirps the player played after the fault (server time: 0.5 s each), as the node
// can only hear what the server runs; IMU and BLE in wall time (they do not go through JACK).
constexpr int kResumeAudioChirps = 8;   // jackd restart: reconnect backoff 0.2 s, ports, 2 detections
constexpr int kResumeLinkChirps = 16;   // broker restart: reconnect_max_s 1 s, queue resent, 2 estimates
constexpr auto kResumeImu = 10s;
constexpr auto kResumeBle = 10s;        // bluetoothd restart: restart_backoff_s 0.5 s, adapter re-found
constexpr auto kResumeWall = 60s;       // anything: a server starved this long fails the run

double seconds_since(SteadyClock::time_point t0) {
  return std::chrono::duration<double>(SteadyClock::now() - t0).count();
}

// ------------------------------------------------------------------ the sound: a JACK chirp player

/// JACK client `soakplayer` with out_1: a linear chirp 2-8 kHz, 40 ms, amplitude 0.5, every 0.5 s of
/// its own frames, over uniform noise of 1e-3 (the node's `connect` pattern finds the port).
class ChirpPlayer {
 public:
  explicit ChirpPlayer(const std::string& server) {
    const int n = static_cast<int>(0.04 * kRate);
    chirp_.resize(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      const double t = static_cast<double>(i) / kRate;
      chirp_[static_cast<std::size_t>(i)] =
          static_cast<float>(0.5 * std::sin(2.0 * M_PI * (2000.0 * t + 0.5 * (6000.0 / 0.04) * t * t)));
    }
    jack_status_t st{};
    jc_ = jack_client_open("soakplayer", static_cast<jack_options_t>(JackNoStartServer | JackServerName | JackUseExactName),
                           &st, server.c_str());
    if (jc_ == nullptr) throw std::runtime_error("soakplayer: jack_client_open failed");
    out_ = jack_port_register(jc_, "out_1", JACK_DEFAULT_AUDIO_TYPE, JackPortIsOutput, 0);
    if (out_ == nullptr) throw std::runtime_error("soakplayer: cannot register out_1");
    jack_set_process_callback(jc_, [](jack_nframes_t n, void* a) { return static_cast<ChirpPlayer*>(a)->process(n); }, this);
    if (jack_activate(jc_) != 0) throw std::runtime_error("soakplayer: jack_activate failed");
  }
  ~ChirpPlayer() {
    if (jc_ != nullptr) {
      jack_deactivate(jc_);
      jack_client_close(jc_);
    }
  }
  ChirpPlayer(const ChirpPlayer&) = delete;
  ChirpPlayer& operator=(const ChirpPlayer&) = delete;
  std::uint64_t chirps() const { return chirps_.load(std::memory_order_relaxed); }
  std::uint64_t frames() const { return frames_.load(std::memory_order_relaxed); }

 private:
  int process(jack_nframes_t n) {
    auto* out = static_cast<float*>(jack_port_get_buffer(out_, n));
    const std::uint64_t period = static_cast<std::uint64_t>(kChirpPeriodS * kRate);
    for (jack_nframes_t i = 0; i < n; ++i) {
      seed_ ^= seed_ << 13;
      seed_ ^= seed_ >> 17;
      seed_ ^= seed_ << 5;
      float x = 1e-3f * (static_cast<float>(seed_) * (2.0f / 4294967296.0f) - 1.0f);
      const std::uint64_t k = frame_ % period;
      if (frame_ >= period && k < chirp_.size()) {
        x += chirp_[k];
        if (k == 0) chirps_.fetch_add(1, std::memory_order_relaxed);
      }
      out[i] = x;
      ++frame_;
    }
    frames_.store(frame_, std::memory_order_relaxed);
    return 0;
  }
  std::vector<float> chirp_;
  std::uint64_t frame_ = 0;
  std::uint32_t seed_ = 0x9e3779b9u;
  jack_client_t* jc_ = nullptr;
  jack_port_t* out_ = nullptr;
  std::atomic<std::uint64_t> chirps_{0}, frames_{0};
};

/// The player across jackd restarts (a new client each time): chirps and frames it played in total,
/// i.e. how far the server's clock went. A starved dummy-driver jackd runs slower than the wall clock
/// (its xruns delay cycles instead of skipping frames), so resumption is judged in server time.
class Players {
 public:
  explicit Players(const std::string& server) { start(server); }
  void start(const std::string& server) { current_ = std::make_unique<ChirpPlayer>(server); }
  void stop() {
    if (current_) {
      done_chirps_ += current_->chirps();
      done_frames_ += current_->frames();
    }
    current_.reset();
  }
  std::uint64_t chirps() const { return done_chirps_ + (current_ ? current_->chirps() : 0); }
  std::uint64_t frames() const { return done_frames_ + (current_ ? current_->frames() : 0); }

 private:
  std::unique_ptr<ChirpPlayer> current_;
  std::uint64_t done_chirps_ = 0, done_frames_ = 0;
};

// ------------------------------------------------------------------ the IMU: a fake IIO device

/// Writes 24-byte scans (accel, gyro: le:s16; CLOCK_MONOTONIC timestamp: le:s64) at 200 Hz into the
/// fake tree's FIFO once the node opened it; `stall` stops writing (the FIFO stays open).
class ImuFeeder {
 public:
  explicit ImuFeeder(std::string fifo) : fifo_(std::move(fifo)), thread_([this] { run(); }) {}
  ~ImuFeeder() {
    stop_ = true;
    thread_.join();
  }
  void stall(bool on) { stalled_ = on; }
  std::uint64_t written() const { return written_.load(); }

 private:
  void run() {
    locus::iio_fake::FifoWriter w(fifo_);
    bool connected = false;
    auto next = SteadyClock::now();
    for (std::int64_t k = 0; !stop_; ++k) {
      next += 5ms;
      std::this_thread::sleep_until(next);
      if (!connected) connected = w.connect(50ms);
      if (!connected || stalled_) continue;
      const std::int16_t raw[6]{static_cast<std::int16_t>(k % 200), 16384, 0, 0, 0, static_cast<std::int16_t>(k % 50)};
      timespec ts{};
      clock_gettime(CLOCK_MONOTONIC, &ts);
      const std::int64_t ns = static_cast<std::int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
      if (w.write(locus::iio_fake::pack_accel_gyro_scan(raw, ns))) {
        written_.fetch_add(1);
      } else {
        w.close();  // the reader went away (EPIPE; SIGPIPE is ignored): wait for it to open again
        connected = false;
      }
    }
  }
  std::string fifo_;
  std::atomic<bool> stop_{false}, stalled_{false};
  std::atomic<std::uint64_t> written_{0};
  std::thread thread_;
};

// ------------------------------------------------------------------ BLE: a private bus and dbusmock's bluez5

/// A private system bus with python3-dbusmock playing bluetoothd (adapter hci0, one tag), and a thread
/// that sets the tag's RSSI every 200 ms (each change is one advert for the node's scanner).
class BluezMock {
 public:
  explicit BluezMock(const fs::path& dir) : dir_(dir) {
    const fs::path sock = dir_ / "bus.sock";
    write_text(dir_ / "bus.conf",
               "<!DOCTYPE busconfig PUBLIC \"-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN\"\n"
               " \"http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd\">\n"
               "<busconfig>\n  <type>system</type>\n  <listen>unix:path=" + sock.string() +
               "</listen>\n  <auth>EXTERNAL</auth>\n  <policy context=\"default\">\n    <allow user=\"*\"/>\n"
               "    <allow own=\"*\"/>\n    <allow send_type=\"method_call\"/>\n    <allow send_type=\"signal\"/>\n"
               "    <allow send_type=\"method_return\"/>\n    <allow send_type=\"error\"/>\n"
               "    <allow receive_type=\"method_call\"/>\n    <allow receive_type=\"signal\"/>\n"
               "    <allow receive_type=\"method_return\"/>\n    <allow receive_type=\"error\"/>\n"
               "  </policy>\n</busconfig>\n");
    bus_ = std::make_unique<Process>(std::vector<std::string>{"dbus-daemon", "--config-file=" + (dir_ / "bus.conf").string(),
                                                              "--nofork", "--nopidfile"},
                                     dir_ / "dbus.out", dir_ / "dbus.err");
    address_ = "unix:path=" + sock.string();
    ::setenv("DBUS_SYSTEM_BUS_ADDRESS", address_.c_str(), 1);
    if (!wait_until([&] {
          try {
            client_ = sdbus::createSystemBusConnection();
            return true;
          } catch (const sdbus::Error&) {
            return false;
          }
        }, 15s)) {
      throw std::runtime_error("the private dbus-daemon did not come up: " + bus_->err());
    }
    dbus_ = sdbus::createProxy(*client_, "org.freedesktop.DBus", "/org/freedesktop/DBus");
  }
  ~BluezMock() {
    stop_rssi();
    std::lock_guard<std::mutex> lock(mu_);
    mock_.reset();
    dbus_.reset();
    client_.reset();
    bus_.reset();
    ::unsetenv("DBUS_SYSTEM_BUS_ADDRESS");
  }
  const std::string& address() const { return address_; }

  /// dbusmock owning org.bluez, with hci0 and the tag. "" or what went wrong.
  std::string start() {
    std::lock_guard<std::mutex> lock(mu_);
    mock_ = std::make_unique<Process>(std::vector<std::string>{"/usr/bin/python3", "-m", "dbusmock", "--system", "--template", "bluez5"},
                                      dir_ / "mock.out", dir_ / "mock.err",
                                      std::vector<std::string>{"DBUS_SYSTEM_BUS_ADDRESS=" + address_});
    if (!wait_until([&] { return on_bus(); }, 20s)) return "dbusmock did not take org.bluez: " + mock_->err();
    try {
      auto root = sdbus::createProxy(*client_, "org.bluez", "/");
      std::string path;
      root->callMethod("AddAdapter").onInterface("org.bluez.Mock").withArguments(std::string("hci0"), std::string("soak"))
          .storeResultsTo(path);
      root->callMethod("AddDevice").onInterface("org.bluez.Mock")
          .withArguments(std::string("hci0"), std::string(kTagMac), std::string("tag"))
          .storeResultsTo(path);
    } catch (const sdbus::Error& e) {
      return std::string("dbusmock AddAdapter/AddDevice: ") + e.what();
    }
    return "";
  }
  /// bluetoothd dies (SIGKILL): org.bluez leaves the bus.
  void kill() {
    std::lock_guard<std::mutex> lock(mu_);
    if (mock_) mock_->stop(SIGKILL, 5s);
    mock_.reset();
  }
  void start_rssi() {
    rssi_thread_ = std::thread([this] {
      for (int i = 0; !stop_rssi_; ++i) {
        std::this_thread::sleep_for(200ms);
        std::lock_guard<std::mutex> lock(mu_);
        if (!mock_) continue;
        try {
          auto dev = sdbus::createProxy(*client_, "org.bluez", "/org/bluez/hci0/dev_AA_BB_CC_DD_EE_51");
          dev->callMethod("Set").onInterface("org.freedesktop.DBus.Properties")
              .withArguments(std::string("org.bluez.Device1"), std::string("RSSI"),
                             sdbus::Variant(static_cast<std::int16_t>(-50 - i % 20)));
          ++set_;
        } catch (const sdbus::Error&) {
          ++failed_;  // the mock is restarting
        }
      }
    });
  }
  void stop_rssi() {
    stop_rssi_ = true;
    if (rssi_thread_.joinable()) rssi_thread_.join();
  }

 private:
  bool on_bus() {
    bool has = false;
    try {
      dbus_->callMethod("NameHasOwner").onInterface("org.freedesktop.DBus").withArguments(std::string("org.bluez"))
          .storeResultsTo(has);
    } catch (const sdbus::Error&) {
      return false;
    }
    return has;
  }
  fs::path dir_;
  std::string address_;
  std::unique_ptr<Process> bus_, mock_;
  std::unique_ptr<sdbus::IConnection> client_;
  std::unique_ptr<sdbus::IProxy> dbus_;
  std::mutex mu_;  // test side only: the RSSI thread vs. restarts
  std::thread rssi_thread_;
  std::atomic<bool> stop_rssi_{false};
  std::atomic<std::uint64_t> set_{0}, failed_{0};
};

// ------------------------------------------------------------------ the consumer of the node's output

/// Reads the node's JSON-lines output from a FIFO (copying it to out.jsonl), counts events by type,
/// and keeps each detection's frame with the time it was read. pause() stops reading (a slow consumer).
class OutputReader {
 public:
  struct Counts {
    std::uint64_t detections = 0, estimates = 0, imu = 0, ble = 0;
  };
  struct Detection {
    double frame;
    double read_s;  // seconds since the run's start when read
  };

  OutputReader(fs::path fifo, fs::path copy, SteadyClock::time_point t0)
      : fifo_(std::move(fifo)), copy_(copy), t0_(t0), thread_([this] { run(); }) {}
  ~OutputReader() {
    stop_ = true;
    thread_.join();
  }
  void pause(bool on) { paused_ = on; }
  /// The consumer goes away for `gap` (drains what is there, closes the FIFO, opens it again): the
  /// node's writes fail with EPIPE meanwhile. Returns when it is reading again.
  void go_away(std::chrono::milliseconds gap) {
    gone_ms_ = static_cast<int>(gap.count());
    wait_until([&] { return gone_ms_ == 0; }, gap + 10s);
  }
  Counts counts() const {
    std::lock_guard<std::mutex> lock(mu_);
    return counts_;
  }
  std::vector<Detection> detections() const {
    std::lock_guard<std::mutex> lock(mu_);
    return detections_;
  }
  std::multiset<double> estimate_frames() const {
    std::lock_guard<std::mutex> lock(mu_);
    return estimate_frames_;
  }
  bool eof() const { return eof_; }
  std::uint64_t bad_lines() const { return bad_lines_; }

 private:
  void run() {
    int fd = -1;
    while (!stop_ && fd < 0) {  // non-blocking open: returns at once; the writer appears later
      fd = ::open(fifo_.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
      if (fd < 0) std::this_thread::sleep_for(20ms);
    }
    std::ofstream copy(copy_);
    std::string pending;
    bool writer_seen = false;
    while (!stop_ || !eof_) {
      if (const int gap = gone_ms_; gap > 0) {
        drain(fd, copy, pending);
        ::close(fd);
        std::this_thread::sleep_for(std::chrono::milliseconds(gap));
        fd = ::open(fifo_.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
        gone_ms_ = 0;
        continue;
      }
      if (paused_) {
        std::this_thread::sleep_for(20ms);
        continue;
      }
      const ssize_t n = read_some(fd, copy, pending);
      if (n > 0) {
        writer_seen = true;
        continue;
      }
      if (n == 0 && writer_seen) {  // the writer closed: the node ended
        eof_ = true;
        break;
      }
      if (stop_ && !writer_seen) break;
      std::this_thread::sleep_for(10ms);
    }
    copy.flush();
    if (fd >= 0) ::close(fd);
  }
  ssize_t read_some(int fd, std::ofstream& copy, std::string& pending) {
    char buf[65536];
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n <= 0) return n;
    copy.write(buf, n);
    pending.append(buf, static_cast<std::size_t>(n));
    std::size_t nl;
    while ((nl = pending.find('\n')) != std::string::npos) {
      take(pending.substr(0, nl));
      pending.erase(0, nl + 1);
    }
    return n;
  }
  void drain(int fd, std::ofstream& copy, std::string& pending) {
    while (read_some(fd, copy, pending) > 0) {
    }
    pending.clear();  // a partial line of a writer cut off mid-line is not an event
  }
  void take(const std::string& line) {
    auto j = nlohmann::json::parse(line, nullptr, false);
    if (j.is_discarded() || !j.is_object()) {
      ++bad_lines_;
      return;
    }
    const std::string type = j.value("type", "");
    std::lock_guard<std::mutex> lock(mu_);
    if (type == "audio_detection") {
      ++counts_.detections;
      if (j.value("channel", -1) == 0) detections_.push_back({j.at("frame").get<double>(), seconds_since(t0_)});
    } else if (type == "estimate") {
      ++counts_.estimates;
      if (j.value("plugin", "") == "e2e_link" && j.contains("position_m") && j["position_m"].is_array() &&
          !j["position_m"].empty() && j["position_m"][0].is_number()) {
        estimate_frames_.insert(j["position_m"][0].get<double>());
      }
    } else if (type == "imu_sample") {
      ++counts_.imu;
    } else if (type == "ble_advertisement") {
      ++counts_.ble;
    }
  }

  fs::path fifo_, copy_;
  SteadyClock::time_point t0_;
  std::atomic<bool> stop_{false}, paused_{false}, eof_{false};
  std::atomic<int> gone_ms_{0};
  std::atomic<std::uint64_t> bad_lines_{0};
  mutable std::mutex mu_;  // test side only
  Counts counts_;
  std::vector<Detection> detections_;
  std::multiset<double> estimate_frames_;
  std::thread thread_;
};

// ------------------------------------------------------------------ process figures

struct ProcFigures {
  double rss_mb = 0.0;
  int fds = 0;
};

ProcFigures proc_figures(pid_t pid) {
  ProcFigures f;
  std::istringstream status(read_text("/proc/" + std::to_string(pid) + "/status"));
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) f.rss_mb = std::stod(line.substr(6)) / 1024.0;
  }
  std::error_code ec;
  for (auto it = fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    ++f.fds;
  }
  return f;
}

// ------------------------------------------------------------------ the soak

struct FaultRecord {
  std::string kind;
  double start_s = 0.0, end_s = 0.0;
  // Seconds from the fault's end until each stream resumed; < 0: did not within its limit.
  double audio_s = -1.0, link_s = -1.0, imu_s = -1.0, ble_s = -1.0;
  ProcFigures after;
};

double soak_minutes() {
  const char* m = std::getenv("LOCUS_SOAK_MINUTES");
  if (m == nullptr || *m == '\0') return 2.0;
  char* end = nullptr;
  const double v = std::strtod(m, &end);
  if (end == m || *end != '\0' || !(v >= 1.0 && v <= 24 * 60.0)) {
    throw std::runtime_error(std::string("LOCUS_SOAK_MINUTES: expected minutes in [1, 1440], got '") + m + "'");
  }
  return v;
}

int free_jack_suffix() { return static_cast<int>(::getpid() % 100000); }

TEST(Soak, EveryFaultKindIsSurvivedAndEveryStreamResumes) {
  ::signal(SIGPIPE, SIG_IGN);
  jack_set_error_function([](const char*) {});
  jack_set_info_function([](const char*) {});
  const double minutes = soak_minutes();
  TempDir tmp;
  const fs::path dir = tmp.path();
  const auto t0 = SteadyClock::now();

  // Components.
  Broker broker(dir, {});
  broker.start();
  Jackd jackd("soak" + std::to_string(free_jack_suffix()), dir, 256);
  ASSERT_EQ(jackd.start(), "");
  Players player(jackd.name());
  BluezMock bluez(dir);
  ASSERT_EQ(bluez.start(), "");
  locus::iio_fake::FakeIioTree iio;
  iio.add_imu(0);

  const fs::path out_fifo = dir / "out.fifo";
  ASSERT_EQ(::mkfifo(out_fifo.c_str(), 0600), 0) << std::strerror(errno);
  const std::string port = std::to_string(broker.port());
  const fs::path cfg = dir / "node.yaml";
  write_text(cfg,
             "sample_rate_hz: 44100\n"
             "plugin_dirs: [" + kPluginDir + "]\n"
             "output: {path: " + out_fifo.string() + ", events: [audio_detection, estimate, imu_sample, ble_advertisement]}\n"
             "link: {type: mqtt, params: {host: 127.0.0.1, port: " + port +
             ", qos: 1, connect_timeout_s: 10, reconnect_min_s: 0.2, reconnect_max_s: 1}}\n"
             "outputs:\n"
             "  - type: mqtt\n"
             "    events: [estimate]\n"
             "    params: {host: 127.0.0.1, port: " + port + ", node: soak, reconnect_min_s: 0.2, reconnect_max_s: 1}\n"
             "devices:\n"
             "  - id: soak\n"
             "    audio:\n"
             "      source: jack\n"
             "      params: {server: " + jackd.name() + ", client_name: soaknode, channels: 1, connect: 'soakplayer:out_1', "
             "reconnect_backoff_s: 0.2}\n"
             "    playback:\n"
             "      sink: jack\n"
             "      params: {server: " + jackd.name() + ", client_name: soaknode, channels: 1, reconnect_backoff_s: 0.2}\n"
             "    imu: {source: iio, params: {root: " + iio.root() + ", device: lsm6dsl, mode: buffered}}\n"
             "    ble: {source: bluez, params: {adapter: hci0, restart_backoff_s: 0.5}}\n"
             "    detectors:\n"
             "      - plugin: chirp\n"
             "        params: {f0_hz: 2000, f1_hz: 8000, duration_s: 0.04}\n"
             "localizers:\n"
             "  - plugin: e2e_link\n"
             "    name: sender\n"
             "    params: {role: publish, topic: soak}\n"
             "  - plugin: e2e_link\n"
             "    name: receiver\n"
             "    params: {role: receive, topic: soak}\n");

  OutputReader reader(out_fifo, dir / "out.jsonl", t0);
  ImuFeeder imu(iio.path("dev/iio:device0"));
  bluez.start_rssi();
  Process node({kLocusd, "--config", cfg.string()}, dir / "node.out", dir / "node.err",
               {"DBUS_SYSTEM_BUS_ADDRESS=" + bluez.address()}, dir);
  auto keep_dir_on_failure = [&] {
    if (::testing::Test::HasFailure()) {
      const fs::path keep = fs::temp_directory_path() / ("locus-soak-failed-" + std::to_string(::getpid()));
      std::error_code ec;
      fs::create_directories(keep, ec);
      for (const auto& e : fs::directory_iterator(dir, ec)) {
        if (e.is_regular_file()) fs::copy_file(e.path(), keep / e.path().filename(), fs::copy_options::overwrite_existing, ec);
      }
      std::cerr << "kept the node's log and output in " << keep << "\n";
    }
  };

  // Warm-up: every stream flowing before the first fault.
  auto all_flowing = [&](const OutputReader::Counts& from, int det, int est, int imu_n, int ble) {
    const auto c = reader.counts();
    return c.detections >= from.detections + det && c.estimates >= from.estimates + est && c.imu >= from.imu + imu_n &&
           c.ble >= from.ble + ble;
  };
  const bool warm = wait_until([&] { return !node.running() || all_flowing({}, 4, 2, 200, 3); }, 60s);
  if (!warm || !node.running()) {
    const auto c = reader.counts();
    ADD_FAILURE() << "the node did not get every stream flowing within 60 s (detections " << c.detections << ", estimates "
                  << c.estimates << ", imu " << c.imu << ", ble " << c.ble << "; running " << node.running()
                  << ")\nnode stderr:\n" << node.err();
    keep_dir_on_failure();
    return;
  }

  // Faults.
  std::vector<FaultRecord> records;
  // [start, end] of broker restarts and output gaps (run seconds): what the dead broker held, and the
  // lines written while no consumer was there, are gone (and counted by the node, for the latter).
  std::vector<std::pair<double, double>> broker_down;
  double jack_outage_s = 0.0;
  int hostile_sent = 0;
  const std::vector<std::string> kinds{"jackd", "broker", "bluez", "iio_stall", "cpu", "hostile", "slow", "gone"};
  const double end_s = minutes * 60.0 - 8.0;
  std::set<std::string> done_kinds;
  for (std::size_t step = 0; seconds_since(t0) < end_s || done_kinds.size() < kinds.size(); ++step) {
    const std::string kind = kinds[step % kinds.size()];
    FaultRecord r;
    r.kind = kind;
    r.start_s = seconds_since(t0);
    if (kind == "jackd") {
      player.stop();
      jackd.kill_hard();
      std::this_thread::sleep_for(1s);
      ASSERT_EQ(jackd.start(), "") << "jackd did not come back";
      player.start(jackd.name());
    } else if (kind == "broker") {
      broker.kill_hard();
      std::this_thread::sleep_for(1500ms);
      broker.start();
    } else if (kind == "bluez") {
      bluez.kill();
      std::this_thread::sleep_for(1s);
      ASSERT_EQ(bluez.start(), "");
    } else if (kind == "iio_stall") {
      imu.stall(true);
      std::this_thread::sleep_for(3s);
      imu.stall(false);
    } else if (kind == "cpu") {
      for (int i = 0; i < 5; ++i) {
        ::kill(node.pid(), SIGSTOP);
        std::this_thread::sleep_for(400ms);
        ::kill(node.pid(), SIGCONT);
        std::this_thread::sleep_for(300ms);
      }
    } else if (kind == "hostile") {
      std::string big(256 * 1024, '\0');
      std::mt19937 rng(static_cast<unsigned>(step));
      for (char& ch : big) ch = static_cast<char>(rng());
      write_text(dir / "big.bin", big);
      const std::string topic = "locus/link/soak";
      const std::vector<std::vector<std::string>> pubs{
          {"mosquitto_pub", "-h", "127.0.0.1", "-p", port, "-q", "1", "-t", topic, "-m", "soak not-a-frame 44100"},
          {"mosquitto_pub", "-h", "127.0.0.1", "-p", port, "-q", "1", "-t", topic, "-n"},
          {"mosquitto_pub", "-h", "127.0.0.1", "-p", port, "-q", "1", "-t", topic, "-f", (dir / "big.bin").string()}};
      for (const auto& argv : pubs) {
        Process pub(argv, dir / "pub.out", dir / "pub.err");
        const auto st = pub.wait(10s);
        ASSERT_TRUE(st.has_value() && *st == 0) << "mosquitto_pub failed: " << pub.err();
        ++hostile_sent;
      }
    } else if (kind == "slow") {
      reader.pause(true);
      std::this_thread::sleep_for(6s);
      reader.pause(false);
    } else if (kind == "gone") {
      reader.go_away(2s);
    }
    r.end_s = seconds_since(t0);
    if (kind == "jackd") jack_outage_s += r.end_s - r.start_s;
    if (kind == "broker" || kind == "gone") broker_down.emplace_back(r.start_s, r.end_s);

    ASSERT_TRUE(node.running()) << "the node died during fault '" << kind << "' (status " << node.status().value_or(-1)
                                << ")\n" << node.err();
    // Resumption: each stream must show new events after the fault's end.
    const auto base = reader.counts();
    const auto t_end = SteadyClock::now();
    const std::uint64_t chirps_at_end = player.chirps();
    bool audio = false, link = false, imu_ok = false, ble = false;
    int audio_chirps = -1, link_chirps = -1;
    wait_until([&] {
      const auto c = reader.counts();
      const double dt = seconds_since(t_end);
      const int played = static_cast<int>(player.chirps() - chirps_at_end);
      if (!audio && c.detections >= base.detections + 2) { audio = true; r.audio_s = dt; audio_chirps = played; }
      if (!link && c.estimates >= base.estimates + 2) { link = true; r.link_s = dt; link_chirps = played; }
      if (!imu_ok && c.imu >= base.imu + 100) { imu_ok = true; r.imu_s = dt; }
      if (!ble && c.ble >= base.ble + 2) { ble = true; r.ble_s = dt; }
      const bool audio_late = !audio && played > kResumeAudioChirps;
      const bool link_late = !link && played > kResumeLinkChirps;
      return (audio && link && imu_ok && ble) || audio_late || link_late || !node.running();
    }, kResumeWall);
    r.after = proc_figures(node.pid());
    records.push_back(r);
    done_kinds.insert(kind);
    EXPECT_TRUE(audio && audio_chirps <= kResumeAudioChirps)
        << kind << ": detections did not resume within " << kResumeAudioChirps << " chirps played ("
        << player.chirps() - chirps_at_end << " played, " << seconds_since(t_end) << " s)";
    EXPECT_TRUE(link && link_chirps <= kResumeLinkChirps)
        << kind << ": estimates (detections through the broker) did not resume within " << kResumeLinkChirps
        << " chirps played (" << player.chirps() - chirps_at_end << " played, " << seconds_since(t_end) << " s)";
    EXPECT_TRUE(imu_ok && r.imu_s <= std::chrono::duration<double>(kResumeImu).count())
        << kind << ": IMU samples did not resume within " << kResumeImu.count() << " s";
    EXPECT_TRUE(ble && r.ble_s <= std::chrono::duration<double>(kResumeBle).count())
        << kind << ": BLE adverts did not resume within " << kResumeBle.count() << " s";
    if (::testing::Test::HasFailure()) break;
    std::this_thread::sleep_for(1s);
  }

  // The end: a clean stop, everything flushed.
  const auto final_fig = proc_figures(node.pid());
  const double stop_s = seconds_since(t0);
  const int status = node.stop(SIGTERM, 30s);
  ASSERT_TRUE(wait_until([&] { return reader.eof(); }, 20s)) << "the output FIFO was not closed by the node";
  EXPECT_EQ(status, 0) << "locusd exit status after SIGTERM\n" << node.err();
  EXPECT_FALSE(node.killed());
  const std::string log = node.err() + node.out();
  EXPECT_EQ(reader.bad_lines(), 0u) << "lines of the output that are not JSON objects";

  // Lost frames are counted and reported, and cover the jackd outages.
  std::smatch m;
  const std::regex stats_re(R"(device soak: (\d+) frames processed, (\d+) lost in (\d+) overruns, (\d+) sensor events \((\d+) dropped[^)]*\), (\d+) events dropped, playback: (\d+) xruns)");
  ASSERT_TRUE(std::regex_search(log, m, stats_re)) << "no device stats line in the node's log:\n" << log;
  const double frames_processed = std::stod(m[1]);
  const double frames_lost = std::stod(m[2]);
  EXPECT_GE(frames_lost, 0.5 * jack_outage_s * kRate) << "the jackd outages (" << jack_outage_s
                                                      << " s) are not in the lost-frame count";
  // Every frame the server ran is processed or counted lost (the node's counter bridges outages by
  // wall time, so it may count more than the player played, never much less).
  EXPECT_GE(frames_processed + frames_lost, 0.95 * static_cast<double>(player.frames()))
      << "frames neither processed nor counted lost";

  // The lines the gone consumer missed are counted and reported, and the node wrote to it again.
  const int gone_faults = static_cast<int>(std::count_if(records.begin(), records.end(), [](const FaultRecord& r) {
    return r.kind == "gone";
  }));
  std::smatch mo;
  ASSERT_TRUE(std::regex_search(log, mo, std::regex(R"(output '[^']*': (\d+) lines written, (\d+) not written \(last error: Broken pipe\))")))
      << "no report of the lines the gone consumer missed:\n" << log;
  EXPECT_GT(std::stod(mo[2]), 0.0);
  std::size_t resumed = 0;
  for (std::size_t at = 0; (at = log.find("writing again after", at)) != std::string::npos; ++at) ++resumed;
  EXPECT_EQ(resumed, static_cast<std::size_t>(gone_faults));

  // Every malformed link message was counted, none turned into an estimate.
  std::smatch mr;
  ASSERT_TRUE(std::regex_search(log, mr, std::regex(R"(received (\d+) messages, published (\d+) estimates, (\d+) malformed)")))
      << log;
  EXPECT_EQ(std::stoi(mr[3]), hostile_sent) << "malformed link messages counted";

  // Nothing accepted is lost: every detection came back through the broker as an estimate, except
  // around a broker restart (what the dead broker held is gone: docs/mqtt.md).
  const auto detections = reader.detections();
  const auto estimates = reader.estimate_frames();
  int missing = 0, excused = 0;
  for (const auto& d : detections) {
    if (estimates.count(d.frame) > 0) continue;
    bool near_restart = false;
    for (const auto& [a, b] : broker_down) near_restart = near_restart || (d.read_s >= a - 3.0 && d.read_s <= b + 3.0);
    // The last detections were still on their way through the broker when the node stopped.
    near_restart = near_restart || d.read_s >= stop_s - 2.0;
    (near_restart ? excused : missing) += 1;
  }
  EXPECT_EQ(missing, 0) << missing << " of " << detections.size()
                        << " detections away from a broker restart never came back as an estimate";

  // Detection rate: detections against the chirps the player played (outside jackd outages, whose
  // chirps nobody played). A starved node loses frames (counted above) and the chirps in them.
  const double expected = static_cast<double>(player.chirps());
  EXPECT_GE(static_cast<double>(detections.size()), 0.7 * expected);

  // RSS and file descriptors flat: the second half of the run against the first fault's figures.
  ASSERT_FALSE(records.empty());
  const ProcFigures base = records.front().after;
  double rss_max = 0.0;
  int fds_max = 0;
  for (std::size_t i = records.size() / 2; i < records.size(); ++i) {
    rss_max = std::max(rss_max, records[i].after.rss_mb);
    fds_max = std::max(fds_max, records[i].after.fds);
  }
  EXPECT_LE(rss_max, base.rss_mb * 1.25 + 8.0) << "RSS grew from " << base.rss_mb << " MB";
  EXPECT_LE(fds_max, base.fds + 3) << "open file descriptors grew from " << base.fds;

  // Report.
  nlohmann::json report;
  report["minutes"] = minutes;
  report["run_s"] = seconds_since(t0);
  report["frames_processed"] = frames_processed;
  report["frames_lost"] = frames_lost;
  report["overruns"] = std::stod(m[3]);
  report["sensor_events"] = std::stod(m[4]);
  report["sensor_dropped"] = std::stod(m[5]);
  report["events_dropped"] = std::stod(m[6]);
  report["playback_xruns"] = std::stod(m[7]);
  report["jack_outage_s"] = jack_outage_s;
  report["detections"] = detections.size();
  report["chirps_played"] = expected;
  report["player_frames"] = player.frames();
  report["detections_missing_estimate"] = missing;
  report["detections_lost_with_broker"] = excused;
  report["hostile_messages"] = hostile_sent;
  report["output_lines_written"] = std::stod(mo[1]);
  report["output_lines_not_written"] = std::stod(mo[2]);
  report["rss_mb"] = {base.rss_mb, final_fig.rss_mb};
  report["fds"] = {base.fds, final_fig.fds};
  std::printf("%-10s %8s %8s %8s %8s %8s %8s %8s %5s\n", "fault", "start_s", "dur_s", "audio_s", "link_s", "imu_s",
              "ble_s", "rss_MB", "fds");
  for (const auto& r : records) {
    std::printf("%-10s %8.1f %8.1f %8.2f %8.2f %8.2f %8.2f %8.1f %5d\n", r.kind.c_str(), r.start_s, r.end_s - r.start_s,
                r.audio_s, r.link_s, r.imu_s, r.ble_s, r.after.rss_mb, r.after.fds);
    report["faults"].push_back({{"kind", r.kind}, {"start_s", r.start_s}, {"duration_s", r.end_s - r.start_s},
                                {"resume_audio_s", r.audio_s}, {"resume_link_s", r.link_s}, {"resume_imu_s", r.imu_s},
                                {"resume_ble_s", r.ble_s}, {"rss_mb", r.after.rss_mb}, {"fds", r.after.fds}});
  }
  std::printf("%s\n", report.dump().c_str());
  write_text("soak-report.json", report.dump(2) + "\n");
  keep_dir_on_failure();
}

}  // namespace
}  // namespace locus::testing::soak
