// A real mosquitto broker for tests: started by the test on a free loopback port (18830-18899) in a
// private temp dir, optionally with a password file (mosquitto_passwd) and a TLS listener (a CA and a
// server certificate made with openssl), stopped by PID in the destructor, also when an assertion fails;
// PR_SET_PDEATHSIG kills it if the test process dies. Used by tests/integration/mqtt and
// tests/bench/bench_mqtt.cpp.
#pragma once

#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <netinet/in.h>
#include <arpa/inet.h>
#include <fcntl.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace locus::testing {

namespace fs = std::filesystem;

/// Runs a shell command; true on exit status 0.
inline bool run_command(const std::string& cmd) { return std::system(cmd.c_str()) == 0; }

inline bool port_accepts(int port) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return false;
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(s);
  return ok;
}

inline bool port_free(int port) {
  const int s = ::socket(AF_INET, SOCK_STREAM, 0);
  if (s < 0) return false;
  int one = 1;
  ::setsockopt(s, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const bool ok = ::bind(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  ::close(s);
  return ok;
}

/// A private temp directory removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "locus-mqtt-XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

class Broker {
 public:
  struct Options {
    std::string username;  ///< non-empty: password file with this user, anonymous refused
    std::string password;
    bool tls = false;      ///< TLS listener with a certificate for 127.0.0.1/localhost
    std::vector<std::pair<std::string, std::string>> more_users;  ///< more (user, password) in the password file
    std::string acl_file;  ///< non-empty: mosquitto's acl_file (with a username)
  };

  Broker(fs::path dir, Options options) : dir_(std::move(dir)), opt_(std::move(options)) {
    if (!opt_.username.empty()) {
      if (!run_command("mosquitto_passwd -c -b '" + (dir_ / "passwd").string() + "' '" + opt_.username + "' '" +
                       opt_.password + "' >/dev/null 2>&1")) {
        throw std::runtime_error("mosquitto_passwd failed");
      }
      for (const auto& [user, password] : opt_.more_users) {
        if (!run_command("mosquitto_passwd -b '" + (dir_ / "passwd").string() + "' '" + user + "' '" + password +
                         "' >/dev/null 2>&1")) {
          throw std::runtime_error("mosquitto_passwd failed for " + user);
        }
      }
    }
    if (opt_.tls) make_certificates();
  }
  ~Broker() { stop(); }
  Broker(const Broker&) = delete;
  Broker& operator=(const Broker&) = delete;

  /// Starts on a free port (the first time) or on the same port again (a restart). Throws if the broker
  /// does not accept connections within 10 s.
  void start() {
    if (port_ == 0) {
      const int base = 18830 + static_cast<int>(::getpid() % 70);
      for (int i = 0; i < 70 && port_ == 0; ++i) {
        const int p = 18830 + (base - 18830 + i) % 70;
        if (!port_free(p)) continue;
        port_ = p;
        if (!launch()) port_ = 0;  // lost a race for the port with another test: try the next one
      }
      if (port_ == 0) throw std::runtime_error("no free port in 18830-18899 for mosquitto");
    } else {
      for (int attempt = 0; attempt < 20; ++attempt) {
        if (launch()) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
      }
      throw std::runtime_error("mosquitto did not restart on port " + std::to_string(port_) + "; log:\n" + log());
    }
  }

  /// SIGTERM (then SIGKILL after 5 s) and wait.
  void stop() { signal_and_wait(SIGTERM); }
  /// SIGKILL, as a crash or power loss of the broker's host.
  void kill_hard() { signal_and_wait(SIGKILL); }

  int port() const { return port_; }
  bool running() const { return pid_ > 0; }
  const fs::path& dir() const { return dir_; }
  fs::path ca_file() const { return dir_ / "ca.crt"; }
  std::string log() const {
    std::ifstream in(dir_ / "mosquitto.log");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

 private:
  void make_certificates() {
    const std::string d = "'" + dir_.string() + "'";
    const std::string cmd =
        "cd " + d + " && "
        "openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.crt -days 2 -subj /CN=locus-test-ca "
        ">/dev/null 2>&1 && "
        "openssl req -newkey rsa:2048 -nodes -keyout server.key -out server.csr -subj /CN=localhost >/dev/null 2>&1 && "
        "printf 'subjectAltName=IP:127.0.0.1,DNS:localhost\\n' > san.ext && "
        "openssl x509 -req -in server.csr -CA ca.crt -CAkey ca.key -CAcreateserial -out server.crt -days 2 "
        "-extfile san.ext >/dev/null 2>&1";
    if (!run_command(cmd)) throw std::runtime_error("openssl could not make the test certificates in " + dir_.string());
  }

  void write_config() const {
    std::ofstream c(dir_ / "mosquitto.conf");
    c << "persistence false\n";
    c << "log_dest file " << (dir_ / "mosquitto.log").string() << "\n";
    c << "log_type error\nlog_type warning\nlog_type notice\nlog_type information\n";
    if (::geteuid() == 0) c << "user root\n";  // else mosquitto drops to 'mosquitto', who cannot read dir_
    c << "listener " << port_ << " 127.0.0.1\n";
    if (opt_.username.empty()) {
      c << "allow_anonymous true\n";
    } else {
      c << "allow_anonymous false\npassword_file " << (dir_ / "passwd").string() << "\n";
      if (!opt_.acl_file.empty()) c << "acl_file " << opt_.acl_file << "\n";
    }
    if (opt_.tls) {
      c << "cafile " << (dir_ / "ca.crt").string() << "\n";
      c << "certfile " << (dir_ / "server.crt").string() << "\n";
      c << "keyfile " << (dir_ / "server.key").string() << "\n";
    }
  }

  bool launch() {
    write_config();
    const std::string conf = (dir_ / "mosquitto.conf").string();
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid < 0) throw std::runtime_error("fork failed");
    if (pid == 0) {
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(127);
      const std::string err = (dir_ / "mosquitto.stderr").string();
      const int fd = ::open(err.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
        ::close(fd);
      }
      ::execlp("mosquitto", "mosquitto", "-c", conf.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    pid_ = pid;
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (std::chrono::steady_clock::now() < until) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {  // exited: port taken or bad config
        pid_ = -1;
        return false;
      }
      if (port_accepts(port_)) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    signal_and_wait(SIGKILL);
    return false;
  }

  void signal_and_wait(int sig) {
    if (pid_ <= 0) return;
    ::kill(pid_, sig);
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > until) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid_ = -1;
  }

  fs::path dir_;
  Options opt_;
  int port_ = 0;
  pid_t pid_ = -1;
};

}  // namespace locus::testing
