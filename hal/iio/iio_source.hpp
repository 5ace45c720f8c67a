// `iio`: an IMU read from a Linux IIO device (accelerometer + gyroscope, optionally a magnetometer),
// the SensorSource that turns a board's sensor into ImuSample events (docs/hal-iio.md).
//
// Two modes:
//   buffered (default)  the kernel's buffered interface: open() enables the scan elements it needs
//                       (accel x/y/z, anglvel x/y/z, magn x/y/z when present, timestamp) and disables
//                       the others, sets buffer/length, the sampling frequency and trigger when asked,
//                       opens <root>/dev/iio:deviceN; start() writes buffer/enable 1 and a thread reads
//                       packed scans (poll() with a short timeout, so stop() is prompt even when the
//                       device stalls), converts them and pushes one ImuSample per scan. stop() writes
//                       buffer/enable 0. t_s = the scan's in_timestamp in seconds (device-local clock,
//                       `timestamp_clock`), or sample count / sampling_frequency without a timestamp.
//   polled              reads in_<type>_<axis>_raw from sysfs at poll_hz; t_s = CLOCK_MONOTONIC.
// Values are (raw + offset) * scale per the kernel ABI: accel m/s^2, anglvel rad/s, magn Gauss
// (x100 -> µT); the device's mount matrix (in_<type>_mount_matrix or mount_matrix) is applied when
// present so vectors are in the body frame. A magnetometer comes from the main device's magn channels
// or from a second device (`mag_device`, read the same way; its latest value rides on each sample).
//
// Why the root prefix: every path is <root>/sys/... and <root>/dev/..., so tests build a fake sysfs
// tree and a FIFO in a temp dir and drive the real code path (no kernel IIO support needed).
//
// Errors: a malformed tree (missing scale, bad type string, missing channel) throws from open() naming
// the file and what was expected. A device error while running (file vanished, read error, EOF of the
// stream, a partial scan at EOF) ends the stream: finished() becomes true and error() names the path
// and what was expected. The reading thread never allocates, locks or logs in its loop (the scan
// decoding is covered by the real-time safety test).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "iio/iio_devices.hpp"
#include "iio/iio_parse.hpp"
#include "locus/registry.hpp"
#include "locus/sensor_source.hpp"

namespace locus::hal::iio {

/// The parameter schema of the `iio` source.
const ParamSchema& iio_schema();

/// How one channel's raw value becomes SI: si = (raw + offset) * scale * unit.
struct ChannelConversion {
  double scale = 1.0;
  double offset = 0.0;
  double unit = 1.0;  ///< 100 for magn (Gauss -> µT), else 1
  double apply(std::int64_t raw) const noexcept { return (static_cast<double>(raw) + offset) * scale * unit; }
};

/// An x/y/z triple of one channel type ("accel", "anglvel", "magn") of a device.
struct VectorChannel {
  std::string type;                           ///< "accel", "anglvel", "magn"
  std::array<ChannelConversion, 3> conv{};    ///< x, y, z
  Matrix3 mount = kIdentity3;                 ///< applied after scaling
  /// Reads scale/offset (per axis "in_<type>_<axis>_scale", else shared "in_<type>_scale"; offset
  /// likewise, default 0) and the mount matrix from `device_dir`. Throws IioError naming the files
  /// when no scale exists or a value is malformed.
  static VectorChannel load(const std::string& device_dir, const std::string& type, bool use_mount_matrix);
  /// [RT] Converts raw x/y/z into the body frame.
  void convert(const std::array<std::int64_t, 3>& raw, std::array<float, 3>& out) const noexcept;
};

/// [RT] Decodes the scans of one device (layout + conversions, fixed after construction).
struct ScanDecoder {
  std::size_t scan_bytes = 0;
  bool has_accel = false, has_gyro = false, has_magn = false, has_timestamp = false;
  VectorChannel accel, gyro, magn;
  std::array<ScanSlot, 3> accel_slot{}, gyro_slot{}, magn_slot{};
  ScanSlot timestamp_slot;

  /// Binds the layout's slots of the loaded channels. Throws IioError when a loaded channel type is
  /// not enabled in `layout`.
  void bind(const ScanLayout& layout);
  /// [RT] The three converted axes of a vector channel from one scan.
  static void read_vector(const std::uint8_t* scan, const std::array<ScanSlot, 3>& slots, const VectorChannel& ch,
                          std::array<float, 3>& out) noexcept;
  /// [RT] in_timestamp of a scan in seconds.
  double timestamp_s(const std::uint8_t* scan) const noexcept;
  /// [RT] Fills out.accel_mps2 / gyro_radps / mag_ut (+ has_mag) from the bound channels and t_s from
  /// the timestamp when there is one (else leaves t_s alone).
  void decode(const std::uint8_t* scan, ImuSample& out) const noexcept;
};

class IioImuSource final : public SensorSource {
 public:
  enum class Mode : std::uint8_t { Buffered, Polled };

  IioImuSource();
  ~IioImuSource() override;

  void open(const Params& params, HostContext& ctx) override;
  SensorKind kind() const override { return SensorKind::Imu; }
  bool live() const override { return true; }
  /// True when t_s is CLOCK_MONOTONIC: polled, or buffered with scan timestamps whose
  /// current_timestamp_clock is (set to, or kept at) "monotonic". False for other clocks and for
  /// timestamp-less scans (t_s = count / sampling frequency, from 0 at start()).
  bool monotonic_time() const override { return monotonic_time_; }
  void start(SensorQueue& queue) override;
  void stop() override;
  bool finished() const noexcept override { return finished_.load(std::memory_order_acquire); }
  std::string error() const override;

  /// [any] Samples pushed (dropped ones included in queue.dropped(), not here).
  std::uint64_t samples_produced() const noexcept { return produced_.load(std::memory_order_acquire); }
  /// [any] Scans whose timestamp went backwards (pushed with the previous time, to keep order).
  std::uint64_t timestamp_regressions() const noexcept { return regressions_.load(std::memory_order_relaxed); }
  /// [main] What open() resolved (for logs and tests).
  const IioDeviceEntry& device() const noexcept { return dev_; }
  Mode mode() const noexcept { return mode_; }
  std::size_t scan_bytes() const noexcept { return main_.dec.scan_bytes; }
  double sampling_frequency_hz() const noexcept { return rate_hz_; }

 private:
  struct Stream {  // one buffered device node
    IioDeviceEntry dev;
    ScanDecoder dec;
    int fd = -1;
    std::vector<std::uint8_t> buf;  // read buffer (preallocated)
    std::size_t have = 0;           // bytes of a partial scan at the front
    std::uint64_t scans = 0;
  };
  struct PolledAxis {
    std::string path;  // in_<type>_<axis>_raw
  };

  void open_buffered(const Params& params, const std::string& root);
  void open_polled(const std::string& root);
  void setup_buffer(Stream& s, const std::vector<std::string>& types, std::int64_t buffer_length);
  void run(SensorQueue* queue);
  void run_buffered(SensorQueue& queue);
  void run_polled(SensorQueue& queue);
  /// [RT] Drains one readable stream; false (after fail()) on EOF or a read error.
  bool drain(Stream& s, SensorQueue& queue, bool is_main);
  void emit(const std::uint8_t* scan, SensorQueue& queue);
  void fail(std::string message);
  void close_streams() noexcept;
  void disable_buffers() noexcept;

  Mode mode_ = Mode::Buffered;
  DeviceId device_id_;
  IioDeviceEntry dev_;
  Stream main_;  // the IMU device (accel, gyro, maybe magn); its decoder also holds the polled conversions
  Stream mag_;   // `mag_device` (magn only)
  bool have_mag_stream_ = false;
  // polled
  std::array<PolledAxis, 9> polled_{};  // accel xyz, gyro xyz, magn xyz
  bool polled_mag_ = false;
  double poll_hz_ = 100.0;
  double rate_hz_ = 0.0;  // sampling frequency (buffered) or poll_hz (polled)
  // state carried across scans by the reading thread
  std::array<float, 3> latest_mag_ut_{};
  bool latest_mag_valid_ = false;
  double last_t_s_ = -1e300;

  bool opened_ = false;
  bool monotonic_time_ = false;  // decided by open()
  bool enabled_ = false;  // buffer/enable written 1 (main side bookkeeping)
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> finished_{false};
  std::atomic<std::uint64_t> produced_{0};
  std::atomic<std::uint64_t> regressions_{0};
  mutable std::mutex error_mutex_;
  std::string error_;
};

/// Registers the `iio` sensor source (kind Imu).
void register_iio_source(Registry& registry);

}  // namespace locus::hal::iio
