// imu.csv (imu_csv.hpp).
#include "locus/scene/imu_csv.hpp"

#include <string>

#include "stream_detail.hpp"

namespace locus::scene {

using detail::to_float;

ImuCsvReader::ImuCsvReader(const std::string& path, DeviceId device) : csv_(path), device_(device) {
  t_ = csv_.require_column("t");
  const char* an[3] = {"ax", "ay", "az"};
  const char* gn[3] = {"gx", "gy", "gz"};
  const char* mn[3] = {"mx", "my", "mz"};
  for (int i = 0; i < 3; ++i) {
    a_[i] = csv_.require_column(an[i]);
    g_[i] = csv_.require_column(gn[i]);
    mag_[i] = csv_.find_column(mn[i]);
  }
  const int nmag = int(mag_[0].has_value()) + int(mag_[1].has_value()) + int(mag_[2].has_value());
  if (nmag != 0 && nmag != 3) {
    SceneIssue is{path, 1, 1, -1, "columns mx, my, mz must be given together (found " + std::to_string(nmag) + " of 3)"};
    throw SceneError({is});
  }
}

bool ImuCsvReader::next(ImuSample& out) {
  if (!csv_.next_row()) return false;
  ImuSample s;
  s.device = device_;
  s.t_s = csv_.number(t_);
  if (s.t_s < last_t_)
    csv_.fail(t_, "time " + format_double(s.t_s) + " is before " + format_double(last_t_) + " on line " +
                      std::to_string(last_line_) + " (rows must be in non-decreasing t)");
  for (int i = 0; i < 3; ++i) {
    s.accel_mps2[i] = to_float(csv_, a_[i]);
    s.gyro_radps[i] = to_float(csv_, g_[i]);
  }
  if (mag_[0]) {
    const int nblank = int(csv_.blank(*mag_[0])) + int(csv_.blank(*mag_[1])) + int(csv_.blank(*mag_[2]));
    if (nblank == 3) {
      s.has_mag = false;
    } else {
      for (int i = 0; i < 3; ++i) s.mag_ut[i] = to_float(csv_, *mag_[i]);
      s.has_mag = true;
    }
  }
  last_t_ = s.t_s;
  last_line_ = csv_.row_line();
  out = s;
  return true;
}

ImuCsvWriter::ImuCsvWriter(const std::string& path, bool with_mag)
    : CsvWriter(path, with_mag ? std::vector<std::string>{"t", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"}
                               : std::vector<std::string>{"t", "ax", "ay", "az", "gx", "gy", "gz"}),
      with_mag_(with_mag) {}

void ImuCsvWriter::write(const ImuSample& s) {
  std::string line = format_double(s.t_s);
  for (float v : s.accel_mps2) line += "," + format_float(v);
  for (float v : s.gyro_radps) line += "," + format_float(v);
  if (with_mag_) {
    for (float v : s.mag_ut) line += "," + (s.has_mag ? format_float(v) : std::string());
  }
  line += '\n';
  put(line);
}

}  // namespace locus::scene
