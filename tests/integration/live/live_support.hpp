// Helpers for the end-to-end tests of live nodes (test_live.cpp): child processes (locusd, jackd,
// mosquitto_sub) started with fork/exec into a private temp dir, their output in files, stopped by PID
// (SIGTERM, then SIGKILL after a timeout) also when an assertion fails, and killed by the kernel
// (PR_SET_PDEATHSIG) if the test process dies; a dummy jackd; an in-process JACK "wire" client (the
// air between a device's speaker and its microphone); JSON-lines reading. The MQTT broker is the one of
// tests/integration/mqtt/broker.hpp.
#pragma once

#include <jack/jack.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace locus::testing::live {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + p.string());
}

inline bool wait_until(const std::function<bool()>& cond, std::chrono::milliseconds timeout) {
  const auto end = SteadyClock::now() + timeout;
  while (SteadyClock::now() < end) {
    if (cond()) return true;
    std::this_thread::sleep_for(20ms);
  }
  return cond();
}

/// Every line of a JSON-lines file that parses (a line being written may be incomplete).
inline std::vector<nlohmann::json> read_json_lines(const fs::path& p) {
  std::vector<nlohmann::json> out;
  std::ifstream in(p);
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    auto j = nlohmann::json::parse(line, nullptr, false);
    if (!j.is_discarded()) out.push_back(std::move(j));
  }
  return out;
}

inline std::vector<nlohmann::json> of_type(const std::vector<nlohmann::json>& events, const std::string& type) {
  std::vector<nlohmann::json> out;
  for (const auto& e : events) {
    if (e.value("type", "") == type) out.push_back(e);
  }
  return out;
}

/// A child process: argv[0] looked up in PATH, stdout and stderr into files, extra environment.
class Process {
 public:
  Process(std::vector<std::string> argv, fs::path out, fs::path err, std::vector<std::string> env = {},
          fs::path cwd = {})
      : argv_(std::move(argv)), out_(std::move(out)), err_(std::move(err)) {
    const pid_t parent = ::getpid();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
      // The test binary may have signals blocked (gtest does not; be safe): a daemon must see SIGTERM.
      sigset_t none;
      sigemptyset(&none);
      ::sigprocmask(SIG_SETMASK, &none, nullptr);
      if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
      const int o = ::open(out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int e = ::open(err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (o < 0 || e < 0) ::_exit(126);
      ::dup2(o, 1);
      ::dup2(e, 2);
      ::close(o);
      ::close(e);
      const int devnull = ::open("/dev/null", O_RDONLY);
      if (devnull >= 0) ::dup2(devnull, 0);
      for (const std::string& kv : env) ::putenv(const_cast<char*>(kv.c_str()));
      std::vector<char*> args;
      for (std::string& a : argv_) args.push_back(a.data());
      args.push_back(nullptr);
      ::execvp(args[0], args.data());
      ::_exit(127);
    }
  }
  ~Process() { stop(); }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  bool running() {
    poll();
    return !status_.has_value();
  }
  /// The exit status (0-255), 128 + signal if it was killed by one, nullopt if still running.
  std::optional<int> status() {
    poll();
    return status_;
  }
  /// Waits up to `timeout` for the process to exit by itself.
  std::optional<int> wait(std::chrono::milliseconds timeout) {
    wait_until([this] { return !running(); }, timeout);
    return status_;
  }
  /// Sends `sig` and waits up to `timeout`; SIGKILL after that. Returns the exit status.
  int stop(int sig = SIGTERM, std::chrono::milliseconds timeout = 10s) {
    if (!running()) return status_.value_or(-1);
    ::kill(pid_, sig);
    if (!wait(timeout)) {
      ::kill(pid_, SIGKILL);
      int st = 0;
      ::waitpid(pid_, &st, 0);
      record(st);
      killed_ = true;
    }
    return *status_;
  }
  /// True if stop() had to SIGKILL it.
  bool killed() const { return killed_; }
  std::string out() const { return read_text(out_); }
  std::string err() const { return read_text(err_); }
  const fs::path& out_path() const { return out_; }

 private:
  void poll() {
    if (status_ || pid_ <= 0) return;
    int st = 0;
    if (::waitpid(pid_, &st, WNOHANG) == pid_) record(st);
  }
  void record(int st) { status_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st); }

  std::vector<std::string> argv_;
  fs::path out_, err_;
  pid_t pid_ = -1;
  std::optional<int> status_;
  bool killed_ = false;
};

/// A dummy jackd: synchronous (-S, frame positions exact through xruns, docs/hal-jack.md),
/// non-realtime scheduling (-r), fixed period. Stopped by SIGTERM in the destructor.
class Jackd {
 public:
  Jackd(std::string name, fs::path dir, std::uint32_t period = 256, int rate = 44100)
      : name_(std::move(name)), dir_(std::move(dir)), period_(period), rate_(rate) {}
  ~Jackd() {
    if (proc_) proc_->stop(SIGTERM, 10s);
    remove_shm();
  }
  const std::string& name() const { return name_; }
  std::uint32_t period() const { return period_; }

  /// "" once a client can connect (within 15 s), else why not.
  std::string start() {
    proc_ = std::make_unique<Process>(
        std::vector<std::string>{"jackd", "-n", name_, "-r", "-S", "-d", "dummy", "-r", std::to_string(rate_), "-p",
                                 std::to_string(period_)},
        dir_ / ("jackd-" + name_ + ".out"), dir_ / ("jackd-" + name_ + ".err"),
        std::vector<std::string>{"JACK_NO_AUDIO_RESERVATION=1"});
    const auto end = SteadyClock::now() + 15s;
    while (SteadyClock::now() < end) {
      if (!proc_->running()) return "jackd exited early (status " + std::to_string(*proc_->status()) + "): " + log();
      jack_status_t st{};
      jack_client_t* jc = jack_client_open("live_probe", static_cast<jack_options_t>(JackNoStartServer | JackServerName),
                                           &st, name_.c_str());
      if (jc != nullptr) {
        jack_client_close(jc);
        return "";
      }
      std::this_thread::sleep_for(50ms);
    }
    return "jackd did not answer within 15 s: " + log();
  }
  std::string log() const { return proc_ ? proc_->out() + proc_->err() : std::string(); }
  /// SIGKILL, as a crashed server, and what it leaves in /dev/shm removed; start() brings it back.
  void kill_hard() {
    if (proc_) proc_->stop(SIGKILL, 10s);
    proc_.reset();
    remove_shm();
  }
  bool running() const { return proc_ && proc_->running(); }

 private:
  void remove_shm() {  // what a killed jackd leaves behind, for this server name only
    std::error_code ec;
    for (const auto& e : fs::directory_iterator("/dev/shm", ec)) {
      const std::string n = e.path().filename().string();
      if (n.find("_" + name_ + "_") != std::string::npos) fs::remove(e.path(), ec);
    }
  }
  std::string name_;
  fs::path dir_;
  std::uint32_t period_;
  int rate_;
  std::unique_ptr<Process> proc_;
};

/// A JACK client `name` with in_1 and out_1 that copies its input to its output every cycle (the
/// acoustic path of a device hearing its own speaker) plus white noise of `noise_amplitude` (a room is
/// never digitally silent; detectors are tuned for a noise floor), counting xruns, cycles and the
/// non-silent input samples that went through.
class JackWire {
 public:
  JackWire(const std::string& server, const std::string& name, float noise_amplitude = 1e-3f)
      : noise_(noise_amplitude) {
    jack_status_t st{};
    jc_ = jack_client_open(name.c_str(), static_cast<jack_options_t>(JackNoStartServer | JackServerName | JackUseExactName),
                           &st, server.c_str());
    if (jc_ == nullptr) throw std::runtime_error("wire client '" + name + "': jack_client_open failed");
    in_ = jack_port_register(jc_, "in_1", JACK_DEFAULT_AUDIO_TYPE, JackPortIsInput, 0);
    out_ = jack_port_register(jc_, "out_1", JACK_DEFAULT_AUDIO_TYPE, JackPortIsOutput, 0);
    if (in_ == nullptr || out_ == nullptr) throw std::runtime_error("wire client: cannot register its ports");
    jack_set_process_callback(jc_, [](jack_nframes_t n, void* a) { return static_cast<JackWire*>(a)->process(n); }, this);
    jack_set_xrun_callback(jc_, [](void* a) {
      static_cast<JackWire*>(a)->xruns_.fetch_add(1, std::memory_order_relaxed);
      return 0;
    }, this);
    if (jack_activate(jc_) != 0) throw std::runtime_error("wire client: jack_activate failed");
  }
  ~JackWire() {
    if (jc_ != nullptr) {
      jack_deactivate(jc_);
      jack_client_close(jc_);
    }
  }
  JackWire(const JackWire&) = delete;
  JackWire& operator=(const JackWire&) = delete;

  std::uint64_t xruns() const { return xruns_.load(std::memory_order_relaxed); }
  std::uint64_t cycles() const { return cycles_.load(std::memory_order_relaxed); }
  /// Samples with |x| > 1e-6 that went through.
  std::uint64_t loud_samples() const { return loud_.load(std::memory_order_relaxed); }

 private:
  int process(jack_nframes_t n) {
    const auto* in = static_cast<const float*>(jack_port_get_buffer(in_, n));
    auto* out = static_cast<float*>(jack_port_get_buffer(out_, n));
    std::uint64_t loud = 0;
    for (jack_nframes_t i = 0; i < n; ++i) {
      seed_ ^= seed_ << 13;  // xorshift32: uniform noise in [-noise_, noise_]
      seed_ ^= seed_ >> 17;
      seed_ ^= seed_ << 5;
      out[i] = in[i] + noise_ * (static_cast<float>(seed_) * (2.0f / 4294967296.0f) - 1.0f);
      if (std::abs(in[i]) > 1e-6f) ++loud;
    }
    loud_.fetch_add(loud, std::memory_order_relaxed);
    cycles_.fetch_add(1, std::memory_order_relaxed);
    return 0;
  }
  float noise_;
  std::uint32_t seed_ = 0x12345678u;
  jack_client_t* jc_ = nullptr;
  jack_port_t* in_ = nullptr;
  jack_port_t* out_ = nullptr;
  std::atomic<std::uint64_t> xruns_{0}, cycles_{0}, loud_{0};
};

}  // namespace locus::testing::live
