// HTTP requests to the live map (`locusd --http`, tools/map): every input is sent, as it is, to a real
// MapServer on a loopback port over a real TCP connection, and the answer is read until the server
// closes or goes quiet (an SSE stream stays open: it is cut after 50 ms). What is fuzzed is everything
// of ours behind the socket: cpp-httplib's request parsing as the map configures it (header and URI
// limits, payload limit), our pre-routing Host check, the routes (/, assets, /api/state, /healthz,
// /events with Last-Event-ID), the error and exception handlers. A crash, a sanitizer report or a
// server that stops answering (the next input's connect fails: abort) is a finding.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string_view>

#include "locus/host.hpp"
#include "map_server.hpp"

namespace {

class QuietLog final : public locus::Logger {
 public:
  void log(locus::LogLevel, std::string_view) override {}
};

QuietLog g_log;
std::unique_ptr<locus::map::MapServer> g_server;
int g_port = 0;

int connect_to_map() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) std::abort();
  timeval tv{0, 50 * 1000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(g_port));
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  for (int attempt = 0; attempt < 50; ++attempt) {
    if (::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0) return fd;
    ::usleep(1000);
  }
  std::abort();  // the map stopped accepting connections: a finding
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  locus::map::MapOptions opt;
  opt.port = 0;
  opt.read_timeout_s = 0.2;
  opt.write_timeout_s = 0.2;
  opt.max_clients = 4;
  g_server = std::make_unique<locus::map::MapServer>(opt, g_log);
  g_server->start();
  g_port = g_server->port();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const int fd = connect_to_map();
  std::size_t sent = 0;
  while (sent < size) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server answered early and closed: fine
    sent += static_cast<std::size_t>(n);
  }
  ::shutdown(fd, SHUT_WR);
  char buf[4096];
  for (int reads = 0; reads < 64; ++reads) {
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
  }
  ::close(fd);
  return 0;
}
