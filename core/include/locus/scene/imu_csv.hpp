// imu.csv of a scene device (docs/scene-format.md): ImuSample rows, read and written.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "locus/events.hpp"
#include "locus/scene/csv.hpp"

namespace locus::scene {

/// imu.csv: t, ax, ay, az, gx, gy, gz required; mx, my, mz optional (all three or none; a row with
/// all three cells empty has has_mag = false). Rows must be in non-decreasing t.
class ImuCsvReader {
 public:
  ImuCsvReader(const std::string& path, DeviceId device);
  /// Next sample; false at the end. Throws SceneError.
  bool next(ImuSample& out);
  bool has_mag_columns() const noexcept { return mag_[0].has_value(); }

 private:
  CsvReader csv_;
  DeviceId device_;
  std::size_t t_, a_[3], g_[3];
  std::optional<std::size_t> mag_[3];
  double last_t_ = -1e300;
  int last_line_ = 0;
};

/// Writes imu.csv (t, ax..gz, and mx,my,mz when `with_mag`; samples without has_mag get empty cells).
class ImuCsvWriter : public CsvWriter {
 public:
  ImuCsvWriter(const std::string& path, bool with_mag);
  void write(const ImuSample& s);

 private:
  bool with_mag_;
};

}  // namespace locus::scene
