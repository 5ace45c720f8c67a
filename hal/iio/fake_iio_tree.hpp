// A fake IIO sysfs tree in a directory (the layout of /work/shared/docs/real-components.md, IIO):
//   <root>/sys/bus/iio/devices/iio:deviceN/{name, sampling_frequency, in_<type>_<axis>_raw,
//       in_<type>_scale, buffer/{enable,length,watermark}, scan_elements/in_<ch>_{en,index,type}}
//   <root>/dev/iio:deviceN   a FIFO standing in for the buffered character device
// plus a writer for the FIFO and the packing of scans the way the kernel does them.
//
// Why it lives in hal/iio (header-only, compiled only where included): the IIO tests, the soak test
// and `locus room` (tools/room: the IMU of every device of a hardware-in-the-loop run) all play an
// IMU through the real `iio` source this way; one copy of the layout keeps them in step with it.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "iio/iio_parse.hpp"

namespace locus::iio_fake {

class FakeIioTree {
 public:
  /// A tree in a fresh private temp dir ($TMPDIR or /tmp), removed by the destructor.
  FakeIioTree() {
    const char* tmp = std::getenv("TMPDIR");
    std::string templ = std::string(tmp && *tmp ? tmp : "/tmp") + "/locus-iio-XXXXXX";
    if (::mkdtemp(templ.data()) == nullptr) throw std::runtime_error("mkdtemp failed: " + std::string(std::strerror(errno)));
    root_ = templ;
  }
  /// A tree in `root` (created; must not hold a tree already), removed by the destructor.
  explicit FakeIioTree(const std::string& root) : root_(root) {
    std::filesystem::create_directories(root_);
  }
  ~FakeIioTree() {
    std::error_code ec;
    std::filesystem::remove_all(root_, ec);
  }
  FakeIioTree(const FakeIioTree&) = delete;
  FakeIioTree& operator=(const FakeIioTree&) = delete;

  const std::string& root() const noexcept { return root_; }
  std::string path(const std::string& rel) const { return root_ + "/" + rel; }

  /// Replaces the file at once (written aside, then renamed): a source polling it meanwhile reads the
  /// old or the new content, never an empty file (a sysfs attribute is never seen half-written).
  void write(const std::string& rel, const std::string& content) const {
    const std::filesystem::path p = path(rel);
    std::filesystem::create_directories(p.parent_path());
    const std::filesystem::path tmp = root_ + "/.write-in-progress";  // outside every listed directory
    {
      std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
      f << content;
      if (!f) throw std::runtime_error("cannot write " + tmp.string());
    }
    std::filesystem::rename(tmp, p);
  }
  std::string read(const std::string& rel) const {
    std::ifstream f(path(rel), std::ios::binary);
    if (!f) throw std::runtime_error("cannot read " + path(rel));
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }
  void remove(const std::string& rel) const { std::filesystem::remove(path(rel)); }
  void mkfifo(const std::string& rel) const {
    const std::filesystem::path p = path(rel);
    std::filesystem::create_directories(p.parent_path());
    if (::mkfifo(p.c_str(), 0600) != 0) throw std::runtime_error("mkfifo " + p.string() + ": " + std::strerror(errno));
  }

  /// sys/bus/iio/devices/iio:device<n>/
  static std::string dev_rel(int n) { return "sys/bus/iio/devices/iio:device" + std::to_string(n) + "/"; }

  struct ImuOptions {
    std::string name = "lsm6dsl";
    std::string accel_scale = "0.000598550";  // m/s^2 per LSB (+-2 g on a 16-bit part)
    std::string gyro_scale = "0.000152716";   // rad/s per LSB
    std::string type = "le:s16/16>>0";
    bool timestamp = true;
    bool magn = false;
    std::string magn_scale = "0.000146";      // Gauss per LSB
    std::string sampling_frequency = "104.000000";
    bool buffered = true;
    /// Content of current_timestamp_clock ("" = no such file). A real device has it (the kernel's
    /// default is realtime); the `iio` source writes `monotonic` into it and only then takes the scan
    /// timestamps as CLOCK_MONOTONIC (moved onto the audio timeline of a live node).
    std::string timestamp_clock;
  };

  /// A complete accel + gyro (+ magn) device at index n with a FIFO at dev/iio:device<n>. Scan indices:
  /// accel x/y/z 0..2, anglvel x/y/z 3..5, magn x/y/z 6..8 (when present), timestamp last. Every scan
  /// element starts disabled (the source must enable what it needs). A temperature channel is present
  /// and enabled to check that the source disables what it does not use.
  void add_imu(int n) const { add_imu(n, ImuOptions()); }
  void add_imu(int n, const ImuOptions& o) const {
    const std::string d = dev_rel(n);
    write(d + "name", o.name + "\n");
    if (!o.sampling_frequency.empty()) write(d + "sampling_frequency", o.sampling_frequency + "\n");
    if (!o.timestamp_clock.empty()) write(d + "current_timestamp_clock", o.timestamp_clock + "\n");
    write(d + "in_accel_scale", o.accel_scale + "\n");
    write(d + "in_anglvel_scale", o.gyro_scale + "\n");
    const char* axes[] = {"x", "y", "z"};
    int index = 0;
    auto scan_element = [&](const std::string& ch, const std::string& type, const char* en) {
      write(d + "scan_elements/" + ch + "_en", std::string(en) + "\n");
      write(d + "scan_elements/" + ch + "_index", std::to_string(index++) + "\n");
      write(d + "scan_elements/" + ch + "_type", type + "\n");
    };
    std::vector<std::string> types{"accel", "anglvel"};
    if (o.magn) {
      types.push_back("magn");
      write(d + "in_magn_scale", o.magn_scale + "\n");
    }
    for (const std::string& t : types) {
      for (const char* a : axes) {
        write(d + "in_" + t + "_" + a + "_raw", "0\n");
        if (o.buffered) scan_element("in_" + t + "_" + a, o.type, "0");
      }
    }
    if (o.buffered) {
      scan_element("in_temp", "le:s16/16>>0", "1");
      if (o.timestamp) scan_element("in_timestamp", "le:s64/64>>0", "0");
      write(d + "buffer/enable", "0\n");
      write(d + "buffer/length", "128\n");
      write(d + "buffer/watermark", "1\n");
      mkfifo("dev/iio:device" + std::to_string(n));
    }
  }

 private:
  std::string root_;
};

/// A reading in LSB of a channel of `scale` units per LSB, saturated to the s16 range (as the part does).
inline std::int16_t to_lsb(double value, double scale) {
  return static_cast<std::int16_t>(std::clamp(std::llround(value / scale), -32768LL, 32767LL));
}

/// One scan of `n` le:s16 readings in LSB (`raw`), zero padding to 8 bytes, then the le:s64 timestamp
/// (ns): the layout add_imu() gives the enabled channels, in scan-index order.
inline std::vector<std::uint8_t> pack_s16_scan(const std::int16_t* raw, std::size_t n, std::int64_t timestamp_ns) {
  const std::size_t ts_at = (2 * n + 7) / 8 * 8;
  std::vector<std::uint8_t> b(ts_at + 8, 0);
  for (std::size_t i = 0; i < n; ++i) {
    b[2 * i] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(raw[i]) & 0xff);
    b[2 * i + 1] = static_cast<std::uint8_t>(static_cast<std::uint16_t>(raw[i]) >> 8);
  }
  const auto ns = static_cast<std::uint64_t>(timestamp_ns);
  for (std::size_t i = 0; i < 8; ++i) b[ts_at + i] = static_cast<std::uint8_t>(ns >> (8 * i));
  return b;
}

/// One scan of add_imu()'s default layout with accel and gyro enabled (what the `iio` source enables):
/// accel x/y/z, anglvel x/y/z as le:s16 (12 bytes), 4 bytes of padding, the le:s64 timestamp (ns):
/// 24 bytes. `raw` are the six readings in LSB (value = raw * scale).
inline std::vector<std::uint8_t> pack_accel_gyro_scan(const std::int16_t (&raw)[6], std::int64_t timestamp_ns) {
  return pack_s16_scan(raw, 6, timestamp_ns);
}

/// One scan of add_imu()'s layout with magn (ImuOptions::magn) and accel, gyro and magn enabled: the nine
/// le:s16 readings (18 bytes), 6 bytes of padding, the le:s64 timestamp (ns): 32 bytes. `raw`: accel
/// x/y/z, anglvel x/y/z, magn x/y/z in LSB.
inline std::vector<std::uint8_t> pack_accel_gyro_magn_scan(const std::int16_t (&raw)[9], std::int64_t timestamp_ns) {
  return pack_s16_scan(raw, 9, timestamp_ns);
}

/// Writes to a FIFO (the device side): connects once the reader has opened it (within a deadline).
class FifoWriter {
 public:
  explicit FifoWriter(std::string path) : path_(std::move(path)) {}
  ~FifoWriter() { close(); }
  FifoWriter(const FifoWriter&) = delete;
  FifoWriter& operator=(const FifoWriter&) = delete;

  /// Opens for writing; false when no reader appeared within `timeout`.
  bool connect(std::chrono::milliseconds timeout = std::chrono::milliseconds(10000)) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      fd_ = ::open(path_.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
      if (fd_ >= 0) {
        const int flags = ::fcntl(fd_, F_GETFL);
        ::fcntl(fd_, F_SETFL, flags & ~O_NONBLOCK);
        return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }
  bool write(const std::vector<std::uint8_t>& bytes) {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    return true;
  }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  std::string path_;
  int fd_ = -1;
};

}  // namespace locus::iio_fake
