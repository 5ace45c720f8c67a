// The `iio` IMU source (see iio_source.hpp for modes, time base, units and error handling).
#include "iio/iio_source.hpp"

#include <fcntl.h>
#include <poll.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace locus::hal::iio {

namespace {

constexpr std::array<const char*, 3> kAxes{"x", "y", "z"};
constexpr int kPollTimeoutMs = 50;       // how long stop() may wait for the reading thread at most
constexpr std::size_t kScansPerRead = 64;

bool exists(const std::string& path) {
  std::error_code ec;
  return std::filesystem::exists(path, ec);
}

std::string unit_of(const std::string& type) {
  if (type == "accel") return "m/s^2";
  if (type == "anglvel") return "rad/s";
  if (type == "magn") return "Gauss";
  return "SI unit";
}

/// [RT] Reads one integer sysfs attribute without allocating. Returns 0 on success, else an errno
/// value (EINVAL: not an integer; `text` then holds what was read).
int read_raw_int(const char* path, std::int64_t& out, char (&text)[64]) noexcept {
  text[0] = '\0';
  const int fd = ::open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return errno;
  ssize_t n;
  do {
    n = ::read(fd, text, sizeof text - 1);
  } while (n < 0 && errno == EINTR);
  const int err = n < 0 ? errno : 0;
  ::close(fd);
  if (n < 0) return err;
  text[n] = '\0';
  const std::string_view s = trim_sysfs(std::string_view(text, static_cast<std::size_t>(n)));
  const char* first = s.data();
  const char* last = s.data() + s.size();
  if (first != last && *first == '+') ++first;
  const auto r = std::from_chars(first, last, out, 10);
  if (s.empty() || r.ec != std::errc() || r.ptr != last) return EINVAL;
  return 0;
}

double monotonic_s() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

/// First existing file of `dir`/<candidates>, "" when none.
std::string first_existing(const std::string& dir, std::initializer_list<std::string> candidates) {
  for (const std::string& c : candidates) {
    if (exists(dir + "/" + c)) return dir + "/" + c;
  }
  return {};
}

/// The device's sampling frequency attribute ("" when it has none).
std::string sampling_frequency_path(const std::string& dir) {
  return first_existing(dir, {"sampling_frequency", "in_accel_sampling_frequency", "in_anglvel_sampling_frequency"});
}

}  // namespace

// ------------------------------------------------------------------ schema

const ParamSchema& iio_schema() {
  static const ParamSchema schema{
      string_param("root", std::string("/"),
                   "Root prefix of the sysfs and /dev trees (<root>/sys/bus/iio/devices, <root>/dev); '/' on a board, "
                   "a temp dir with a fake tree in tests."),
      string_param("device", std::string(""),
                   "IIO device: 'iio:deviceN' or the content of its name file (e.g. lsm6dsl); '' = the first device "
                   "with accelerometer channels."),
      string_param("mag_device", std::string(""),
                   "Optional second IIO device providing the magnetometer (magn x/y/z); '' = none (the main "
                   "device's magn channels are used when it has them)."),
      enum_param("mode", std::string("buffered"), {"buffered", "polled"},
                 "buffered: packed scans from /dev/iio:deviceN with the device's timestamps; polled: read "
                 "in_*_raw from sysfs at poll_hz (monotonic host clock)."),
      float_param("sampling_frequency_hz", 0.0, 0.0, 100000.0, "Hz",
                  "Written to the device's sampling_frequency when > 0; 0 keeps the device's setting."),
      int_param("buffer_length", std::int64_t{256}, 2.0, 1048576.0, "",
                "Kernel buffer length in scans (buffer/length), buffered mode."),
      float_param("poll_hz", 100.0, 0.1, 10000.0, "Hz", "Sampling rate of polled mode."),
      string_param("trigger", std::string(""),
                   "Written to trigger/current_trigger when not empty (devices without a hardware FIFO need one)."),
      enum_param("timestamp_clock", std::string("monotonic"), {"keep", "monotonic", "monotonic_raw", "boottime", "realtime"},
                 "Written to current_timestamp_clock when the device has it: the clock of the scan timestamps "
                 "(device-local time)."),
      bool_param("apply_mount_matrix", true,
                 "Rotate vectors by the device's mount matrix (in_<type>_mount_matrix or mount_matrix) into the "
                 "body frame."),
  };
  return schema;
}

// ------------------------------------------------------------------ channels

VectorChannel VectorChannel::load(const std::string& dir, const std::string& type, bool use_mount_matrix) {
  VectorChannel v;
  v.type = type;
  const double unit = type == "magn" ? 100.0 : 1.0;  // kernel ABI: magn in Gauss; ImuSample wants µT
  for (std::size_t a = 0; a < 3; ++a) {
    const std::string axis = std::string("in_") + type + "_" + kAxes[a];
    const std::string shared = std::string("in_") + type;
    const std::string scale = first_existing(dir, {axis + "_scale", shared + "_scale"});
    if (scale.empty()) {
      throw IioError(dir + ": no " + axis + "_scale or " + shared + "_scale (expected the " + unit_of(type) +
                     " per LSB factor of " + type + ")");
    }
    v.conv[a].scale = read_sysfs_double(scale);
    const std::string offset = first_existing(dir, {axis + "_offset", shared + "_offset"});
    v.conv[a].offset = offset.empty() ? 0.0 : read_sysfs_double(offset);
    v.conv[a].unit = unit;
  }
  if (use_mount_matrix) {
    const std::string mm = first_existing(dir, {"in_" + type + "_mount_matrix", "mount_matrix"});
    if (!mm.empty()) v.mount = parse_mount_matrix(read_sysfs(mm), mm);
  }
  return v;
}

void VectorChannel::convert(const std::array<std::int64_t, 3>& raw, std::array<float, 3>& out) const noexcept {
  const double x = conv[0].apply(raw[0]), y = conv[1].apply(raw[1]), z = conv[2].apply(raw[2]);
  for (std::size_t r = 0; r < 3; ++r) {
    out[r] = static_cast<float>(mount[r][0] * x + mount[r][1] * y + mount[r][2] * z);
  }
}

void ScanDecoder::bind(const ScanLayout& layout) {
  scan_bytes = layout.scan_bytes;
  auto bind3 = [&](const VectorChannel& ch, std::array<ScanSlot, 3>& slots) {
    for (std::size_t a = 0; a < 3; ++a) {
      const std::string name = "in_" + ch.type + "_" + kAxes[a];
      const ScanSlot* s = layout.find(name);
      if (s == nullptr) throw IioError("scan layout: " + name + " is not enabled (expected it in every scan)");
      slots[a] = *s;
    }
  };
  if (has_accel) bind3(accel, accel_slot);
  if (has_gyro) bind3(gyro, gyro_slot);
  if (has_magn) bind3(magn, magn_slot);
  const ScanSlot* ts = layout.find("in_timestamp");
  has_timestamp = ts != nullptr;
  if (ts) timestamp_slot = *ts;
}

void ScanDecoder::read_vector(const std::uint8_t* scan, const std::array<ScanSlot, 3>& slots, const VectorChannel& ch,
                              std::array<float, 3>& out) noexcept {
  const std::array<std::int64_t, 3> raw{unpack_value(scan, slots[0].offset, slots[0].type),
                                        unpack_value(scan, slots[1].offset, slots[1].type),
                                        unpack_value(scan, slots[2].offset, slots[2].type)};
  ch.convert(raw, out);
}

double ScanDecoder::timestamp_s(const std::uint8_t* scan) const noexcept {
  return static_cast<double>(unpack_value(scan, timestamp_slot.offset, timestamp_slot.type)) * 1e-9;
}

void ScanDecoder::decode(const std::uint8_t* scan, ImuSample& out) const noexcept {
  if (has_accel) read_vector(scan, accel_slot, accel, out.accel_mps2);
  if (has_gyro) read_vector(scan, gyro_slot, gyro, out.gyro_radps);
  if (has_magn) {
    read_vector(scan, magn_slot, magn, out.mag_ut);
    out.has_mag = true;
  }
  if (has_timestamp) out.t_s = timestamp_s(scan);
}

// ------------------------------------------------------------------ source

IioImuSource::IioImuSource() = default;

IioImuSource::~IioImuSource() {
  stop();
  close_streams();
}

std::string IioImuSource::error() const {
  std::lock_guard lock(error_mutex_);
  return error_;
}

void IioImuSource::fail(std::string message) {
  std::lock_guard lock(error_mutex_);
  if (error_.empty()) error_ = std::move(message);
}

void IioImuSource::close_streams() noexcept {
  for (Stream* s : {&main_, &mag_}) {
    if (s->fd >= 0) ::close(s->fd);
    s->fd = -1;
  }
}

void IioImuSource::open(const Params& params, HostContext& ctx) {
  if (thread_.joinable()) throw std::runtime_error("iio: open() while running");
  close_streams();
  main_ = Stream{};
  mag_ = Stream{};
  have_mag_stream_ = false;
  polled_mag_ = false;
  opened_ = false;
  monotonic_time_ = false;
  {
    std::lock_guard lock(error_mutex_);
    error_.clear();
  }
  device_id_ = DeviceId(ctx.device);
  const std::string root = params.get_string("root");
  mode_ = params.get_string("mode") == "polled" ? Mode::Polled : Mode::Buffered;
  poll_hz_ = params.get_float("poll_hz");
  const bool mount = params.get_bool("apply_mount_matrix");

  try {
    const std::string spec = params.get_string("device");
    if (spec.empty()) {
      bool found = false;
      for (const IioDeviceEntry& e : enumerate_iio_devices(root)) {
        const auto ch = iio_channel_names(e);
        if (std::find(ch.begin(), ch.end(), "accel_x") != ch.end()) {
          dev_ = e;
          found = true;
          break;
        }
      }
      if (!found) {
        throw IioError("no IIO device with accelerometer channels (in_accel_x_raw or scan_elements/in_accel_x_en) in " +
                       iio_devices_dir(root) + " (set `device`, or check `root`)");
      }
    } else {
      dev_ = find_iio_device(root, spec);
    }
    main_.dev = dev_;
    IioDeviceEntry mag_dev;
    const std::string mag_spec = params.get_string("mag_device");
    const bool separate_mag = !mag_spec.empty();
    if (separate_mag) {
      mag_dev = find_iio_device(root, mag_spec);
      if (mag_dev.id == dev_.id) {
        throw IioError("mag_device '" + mag_spec + "' is the IMU device " + dev_.id +
                       " itself (leave mag_device empty to use its magn channels)");
      }
      mag_.dev = mag_dev;
    }

    // Sampling frequency first: the scan settings below do not depend on it.
    const double fs_hz = params.get_float("sampling_frequency_hz");
    const std::string fs_path = sampling_frequency_path(dev_.dir);
    if (fs_hz > 0.0) {
      if (fs_path.empty()) {
        throw IioError(dev_.dir + ": no sampling_frequency attribute to write sampling_frequency_hz " +
                       std::to_string(fs_hz) + " to (set sampling_frequency_hz: 0 to keep the device's rate)");
      }
      char text[64];
      const auto r = std::to_chars(text, text + sizeof text, fs_hz);
      write_sysfs(fs_path, std::string_view(text, static_cast<std::size_t>(r.ptr - text)));
    }

    main_.dec.accel = VectorChannel::load(dev_.dir, "accel", mount);
    main_.dec.gyro = VectorChannel::load(dev_.dir, "anglvel", mount);
    main_.dec.has_accel = main_.dec.has_gyro = true;

    if (mode_ == Mode::Buffered) {
      const std::string trigger = params.get_string("trigger");
      const std::string clock = params.get_string("timestamp_clock");
      const std::int64_t length = params.get_int("buffer_length");
      for (Stream* s : {&main_, &mag_}) {
        if (s == &mag_ && !separate_mag) continue;
        const std::string scan_dir = s->dev.dir + "/scan_elements";
        if (!std::filesystem::is_directory(scan_dir)) {
          throw IioError(scan_dir + ": missing (the device has no buffered interface; use mode: polled)");
        }
        if (!exists(s->dev.dir + "/buffer/enable")) {
          throw IioError(s->dev.dir + "/buffer/enable: missing (expected the buffered interface; use mode: polled)");
        }
        write_sysfs(s->dev.dir + "/buffer/enable", "0");  // scan elements can only change while disabled
        if (s == &main_ && !trigger.empty()) write_sysfs(s->dev.dir + "/trigger/current_trigger", trigger);
        if (clock != "keep" && exists(s->dev.dir + "/current_timestamp_clock")) {
          write_sysfs(s->dev.dir + "/current_timestamp_clock", clock);
        }
      }
      std::vector<std::string> types{"accel", "anglvel"};
      if (!separate_mag && exists(dev_.dir + "/scan_elements/in_magn_x_en")) {
        main_.dec.magn = VectorChannel::load(dev_.dir, "magn", mount);
        main_.dec.has_magn = true;
        types.push_back("magn");
      }
      setup_buffer(main_, types, length);
      if (separate_mag) {
        mag_.dec.magn = VectorChannel::load(mag_.dev.dir, "magn", mount);
        mag_.dec.has_magn = true;
        setup_buffer(mag_, {"magn"}, length);
        have_mag_stream_ = true;
      }
      rate_hz_ = 0.0;
      if (!fs_path.empty()) rate_hz_ = read_sysfs_double(fs_path);
      if (!main_.dec.has_timestamp && !(rate_hz_ > 0.0)) {
        throw IioError(dev_.dir + ": no in_timestamp scan element and no positive sampling_frequency (expected one "
                       "of them to time the scans)");
      }
      // The time base of t_s (pipeline.hpp "Time base"): the kernel's default clock is realtime, so only
      // a device whose current_timestamp_clock reads monotonic (as written above, or kept) counts.
      std::string ts_clock;
      monotonic_time_ = main_.dec.has_timestamp &&
                        read_sysfs_optional(dev_.dir + "/current_timestamp_clock", ts_clock) && ts_clock == "monotonic";
    } else {
      open_polled(root);
      if (separate_mag) {
        mag_.dec.magn = VectorChannel::load(mag_.dev.dir, "magn", mount);
        mag_.dec.has_magn = true;
        polled_mag_ = true;
      } else if (exists(dev_.dir + "/in_magn_x_raw")) {
        main_.dec.magn = VectorChannel::load(dev_.dir, "magn", mount);
        main_.dec.has_magn = true;
        polled_mag_ = true;
      }
      const std::string mag_dir = separate_mag ? mag_.dev.dir : dev_.dir;
      if (polled_mag_) {
        for (std::size_t a = 0; a < 3; ++a) {
          polled_[6 + a].path = mag_dir + "/in_magn_" + kAxes[a] + "_raw";
          if (!exists(polled_[6 + a].path)) {
            throw IioError(mag_dir + ": no in_magn_" + std::string(kAxes[a]) + "_raw (expected raw files for magn x/y/z)");
          }
          read_sysfs_int(polled_[6 + a].path);
        }
      }
      rate_hz_ = poll_hz_;
      monotonic_time_ = true;  // t_s = CLOCK_MONOTONIC at the read
    }
  } catch (const IioError& e) {
    close_streams();
    throw std::runtime_error(std::string("iio: ") + e.what());
  }
  opened_ = true;
  ctx.log.debug("iio: " + dev_.id + " (" + dev_.name + ") " + (mode_ == Mode::Buffered ? "buffered" : "polled") +
                (mode_ == Mode::Buffered ? ", " + std::to_string(main_.dec.scan_bytes) + "-byte scans" : std::string()) +
                (have_mag_stream_ || polled_mag_ || main_.dec.has_magn ? ", with magnetometer" : ""));
}

void IioImuSource::setup_buffer(Stream& s, const std::vector<std::string>& types, std::int64_t buffer_length) {
  const std::string scan_dir = s.dev.dir + "/scan_elements";
  std::vector<ScanChannel> channels = discover_scan_elements(scan_dir);
  auto wanted = [&](const std::string& name) {
    if (name == "in_timestamp") return true;
    for (const std::string& t : types) {
      for (const char* a : kAxes) {
        if (name == "in_" + t + "_" + a) return true;
      }
    }
    return false;
  };
  for (const std::string& t : types) {
    for (const char* a : kAxes) {
      const std::string name = "in_" + t + "_" + a;
      if (std::none_of(channels.begin(), channels.end(), [&](const ScanChannel& c) { return c.name == name; })) {
        throw IioError(scan_dir + ": no " + name + "_en (expected scan elements for " + t + " x/y/z)");
      }
    }
  }
  for (const ScanChannel& c : channels) {
    const bool want = wanted(c.name);
    if (c.enabled != want) write_sysfs(scan_dir + "/" + c.name + "_en", want ? "1" : "0");
  }
  channels = discover_scan_elements(scan_dir);  // what the device accepted
  for (const ScanChannel& c : channels) {
    if (c.enabled != wanted(c.name)) {
      throw IioError(scan_dir + "/" + c.name + "_en: wrote " + (wanted(c.name) ? "1" : "0") + " but it reads " +
                     (c.enabled ? "1" : "0") + " (the device refused the scan setup)");
    }
  }
  const ScanLayout layout = compute_layout(channels);
  s.dec.bind(layout);
  write_sysfs(s.dev.dir + "/buffer/length", std::to_string(buffer_length));
  s.fd = ::open(s.dev.dev_node.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (s.fd < 0) {
    const int err = errno;
    throw IioError("cannot open " + s.dev.dev_node + ": " + std::strerror(err) +
                   " (expected the buffered character device of " + s.dev.id + ")");
  }
  s.buf.assign(s.dec.scan_bytes * kScansPerRead, 0);
  s.have = 0;
  s.scans = 0;
}

void IioImuSource::open_polled(const std::string& /*root*/) {
  const std::array<const char*, 2> types{"accel", "anglvel"};
  for (std::size_t t = 0; t < types.size(); ++t) {
    for (std::size_t a = 0; a < 3; ++a) {
      PolledAxis& p = polled_[t * 3 + a];
      p.path = dev_.dir + "/in_" + types[t] + "_" + kAxes[a] + "_raw";
      if (!exists(p.path)) {
        throw IioError(dev_.dir + ": no in_" + std::string(types[t]) + "_" + kAxes[a] + "_raw (expected raw files for " +
                       types[t] + " x/y/z)");
      }
      read_sysfs_int(p.path);  // validates the value now (the polling thread reports later failures)
    }
  }
}

void IioImuSource::start(SensorQueue& queue) {
  if (!opened_) throw std::runtime_error("iio: start() before open()");
  if (thread_.joinable()) throw std::runtime_error("iio: start() while already running");
  stop_.store(false, std::memory_order_release);
  finished_.store(false, std::memory_order_release);
  produced_.store(0, std::memory_order_release);
  regressions_.store(0, std::memory_order_relaxed);
  latest_mag_valid_ = false;
  last_t_s_ = -1e300;
  main_.have = mag_.have = 0;
  main_.scans = mag_.scans = 0;
  thread_ = std::thread([this, &queue] { run(&queue); });
}

void IioImuSource::stop() {
  stop_.store(true, std::memory_order_release);
  if (thread_.joinable()) thread_.join();
  disable_buffers();
}

void IioImuSource::disable_buffers() noexcept {
  if (!enabled_) return;
  enabled_ = false;
  for (Stream* s : {&main_, &mag_}) {
    if (s == &mag_ && !have_mag_stream_) continue;
    try {
      write_sysfs(s->dev.dir + "/buffer/enable", "0");
    } catch (const std::exception& e) {
      try {
        fail(std::string("iio: stop: ") + e.what());
      } catch (...) {
      }
    }
  }
}

void IioImuSource::run(SensorQueue* queue) {
  try {
    if (mode_ == Mode::Buffered) {
      write_sysfs(main_.dev.dir + "/buffer/enable", "1");
      enabled_ = true;
      if (have_mag_stream_) write_sysfs(mag_.dev.dir + "/buffer/enable", "1");
      run_buffered(*queue);
    } else {
      run_polled(*queue);
    }
  } catch (const std::exception& e) {
    fail(std::string("iio: ") + e.what());
  }
  // Stopped on request: not finished (stop() returns, nothing more is pushed). Ended by an error: finished.
  if (!stop_.load(std::memory_order_acquire) || !error().empty()) finished_.store(true, std::memory_order_release);
}

void IioImuSource::run_buffered(SensorQueue& queue) {
  pollfd fds[2]{};
  Stream* streams[2]{&main_, &mag_};
  const nfds_t n = have_mag_stream_ ? 2 : 1;
  for (nfds_t i = 0; i < n; ++i) {
    fds[i].fd = streams[i]->fd;
    fds[i].events = POLLIN;
  }
  while (!stop_.load(std::memory_order_acquire)) {
    const int r = ::poll(fds, n, kPollTimeoutMs);
    if (r < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      fail("iio: poll " + main_.dev.dev_node + ": " + std::strerror(err));
      return;
    }
    for (nfds_t i = 0; i < n; ++i) {
      if (fds[i].revents & POLLNVAL) {
        fail("iio: " + streams[i]->dev.dev_node + ": file descriptor no longer valid");
        return;
      }
      if (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) {
        if (!drain(*streams[i], queue, i == 0)) return;
      }
    }
  }
}

bool IioImuSource::drain(Stream& s, SensorQueue& queue, bool is_main) {
  const std::size_t scan = s.dec.scan_bytes;
  for (;;) {
    const ssize_t n = ::read(s.fd, s.buf.data() + s.have, s.buf.size() - s.have);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      const int err = errno;
      fail("iio: read " + s.dev.dev_node + ": " + std::strerror(err) + " (expected " + std::to_string(scan) +
           "-byte scans)");
      return false;
    }
    if (n == 0) {
      std::string msg = "iio: " + s.dev.dev_node + ": end of stream (EOF) after " + std::to_string(s.scans) +
                        " scans; expected a continuous stream of " + std::to_string(scan) + "-byte scans";
      if (s.have > 0) {
        msg += "; short read: " + std::to_string(s.have) + " bytes of a partial scan left over";
      }
      fail(std::move(msg));
      return false;
    }
    s.have += static_cast<std::size_t>(n);
    std::size_t pos = 0;
    while (s.have - pos >= scan) {
      const std::uint8_t* p = s.buf.data() + pos;
      if (is_main) {
        emit(p, queue);
      } else {
        ScanDecoder::read_vector(p, s.dec.magn_slot, s.dec.magn, latest_mag_ut_);
        latest_mag_valid_ = true;
      }
      ++s.scans;
      pos += scan;
    }
    if (pos > 0 && pos < s.have) std::memmove(s.buf.data(), s.buf.data() + pos, s.have - pos);
    s.have -= pos;
    if (stop_.load(std::memory_order_acquire)) return true;
  }
}

void IioImuSource::emit(const std::uint8_t* scan, SensorQueue& queue) {
  ImuSample s;
  s.device = device_id_;
  const ScanDecoder& d = main_.dec;
  d.decode(scan, s);
  if (!d.has_magn && latest_mag_valid_) {
    s.mag_ut = latest_mag_ut_;
    s.has_mag = true;
  }
  if (!d.has_timestamp) s.t_s = static_cast<double>(main_.scans) / rate_hz_;
  double t = s.t_s;
  if (t < last_t_s_) {
    regressions_.fetch_add(1, std::memory_order_relaxed);
    t = last_t_s_;
  }
  last_t_s_ = t;
  s.t_s = t;
  if (!queue.try_push(Event(s))) queue.count_drop();
  produced_.fetch_add(1, std::memory_order_release);
}

void IioImuSource::run_polled(SensorQueue& queue) {
  using SteadyClock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(1.0 / poll_hz_));
  const auto t0 = SteadyClock::now();
  std::uint64_t k = 0;
  const std::size_t channels = polled_mag_ ? 9 : 6;
  char text[64];
  while (!stop_.load(std::memory_order_acquire)) {
    const auto due = t0 + period * static_cast<std::int64_t>(k);
    for (auto now = SteadyClock::now(); now < due; now = SteadyClock::now()) {
      if (stop_.load(std::memory_order_acquire)) return;
      std::this_thread::sleep_until(std::min(due, now + std::chrono::milliseconds(kPollTimeoutMs)));
    }
    if (stop_.load(std::memory_order_acquire)) return;
    std::array<std::int64_t, 9> raw{};
    for (std::size_t i = 0; i < channels; ++i) {
      const int err = read_raw_int(polled_[i].path.c_str(), raw[i], text);
      if (err != 0) {
        if (err == EINVAL) {
          fail("iio: " + polled_[i].path + ": '" + std::string(trim_sysfs(text)) + "' is not an integer (expected a raw reading)");
        } else {
          fail("iio: cannot read " + polled_[i].path + ": " + std::strerror(err) + " (expected a raw reading)");
        }
        return;
      }
    }
    ImuSample s;
    s.device = device_id_;
    s.t_s = monotonic_s();
    main_.dec.accel.convert({raw[0], raw[1], raw[2]}, s.accel_mps2);
    main_.dec.gyro.convert({raw[3], raw[4], raw[5]}, s.gyro_radps);
    if (polled_mag_) {
      const VectorChannel& m = main_.dec.has_magn ? main_.dec.magn : mag_.dec.magn;
      m.convert({raw[6], raw[7], raw[8]}, s.mag_ut);
      s.has_mag = true;
    }
    if (!queue.try_push(Event(s))) queue.count_drop();
    produced_.fetch_add(1, std::memory_order_release);
    ++k;
    // Fell behind by more than one period (a stalled read): skip the missed ticks instead of bursting.
    const auto now = SteadyClock::now();
    if (now > t0 + period * static_cast<std::int64_t>(k + 1)) {
      k = static_cast<std::uint64_t>((now - t0) / period) + 1;
    }
  }
}

// ------------------------------------------------------------------ registration

void register_iio_source(Registry& registry) {
  registry.add_sensor_source(SensorSourceDescriptor{
      "iio",
      "Linux IIO IMU (accel + gyro [+ magn]): buffered scans from /dev/iio:deviceN with device timestamps, or "
      "polled sysfs *_raw",
      SensorKind::Imu,
      iio_schema(),
      [] { return std::unique_ptr<SensorSource>(std::make_unique<IioImuSource>()); },
  });
}

}  // namespace locus::hal::iio
