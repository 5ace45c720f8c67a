// Shared IMU plugin helpers (see motion_common.hpp).
#include "motion_common.hpp"

#include <cmath>
#include <numbers>

namespace locus::plugins::motion_common {

void append_ahrs_params(ParamSchema& schema, double default_gain) {
  schema.push_back(enum_param("ahrs", std::string("mahony"), {"madgwick", "mahony"},
                              "Attitude filter: Madgwick gradient descent or Mahony complementary filter."));
  schema.push_back(float_param("ahrs_gain", default_gain, 0.0, 50.0, "1/s",
                               "Madgwick beta (rad/s) or Mahony kp (1/s): how fast gravity/field correct the gyro."));
  schema.push_back(float_param("ahrs_ki", 0.0, 0.0, 10.0, "1/s^2", "Mahony integral gain (gyro bias estimation); 0 = off."));
  schema.push_back(bool_param("use_mag", true, "Use the magnetometer when samples carry one (absolute heading)."));
  schema.push_back(float_param("max_gap_s", 0.5, 0.001, 60.0, "s",
                               "A larger gap between IMU samples restarts the attitude from gravity."));
  schema.push_back(bool_param("mag_calibration", false,
                              "Learn the magnetometer's hard iron from the device's own turns (gyro-aided, "
                              "docs/detectors.md) and remove it before the AHRS; a device that never turns keeps its readings."));
  schema.push_back(float_param("mag_calibration_tau_s", 120.0, 1.0, 1e6, "s",
                               "Forgetting time constant of the hard-iron estimate."));
}

void AttitudeTracker::configure(const Params& params) {
  const bool madgwick = params.get_string("ahrs") == "madgwick";
  ahrs_.configure(madgwick ? dsp::Ahrs::Kind::Madgwick : dsp::Ahrs::Kind::Mahony, params.get_float("ahrs_gain"),
                  params.get_float("ahrs_ki"));
  use_mag_ = params.get_bool("use_mag");
  calibrate_ = params.get_bool("mag_calibration");
  dsp::HardIronCalibrator::Config hc;
  hc.tau_s = params.get_float("mag_calibration_tau_s");
  calib_.configure(hc);
  max_gap_s_ = params.get_float("max_gap_s");
  valid_ = false;
  rejected_ = gaps_ = 0;
}

bool AttitudeTracker::update(const ImuSample& s) noexcept {
  const Eigen::Vector3d a(s.accel_mps2[0], s.accel_mps2[1], s.accel_mps2[2]);
  const Eigen::Vector3d g(s.gyro_radps[0], s.gyro_radps[1], s.gyro_radps[2]);
  Eigen::Vector3d m(s.mag_ut[0], s.mag_ut[1], s.mag_ut[2]);
  const bool mag = use_mag_ && s.has_mag && m.allFinite() && m.squaredNorm() > 0;
  if (!a.allFinite() || !g.allFinite() || !std::isfinite(s.t_s)) {
    ++rejected_;
    return false;
  }
  const double dt = s.t_s - t_;
  restarted_ = !valid_ || !(dt >= 0.0) || dt > max_gap_s_;
  if (mag && calibrate_) {
    // The estimate survives gaps (the hard iron is the device's); an interval restarts after one.
    calib_.update(g, m, restarted_ ? -1.0 : dt);
    m -= calib_.hard_iron();
  }
  if (restarted_) {
    if (valid_) ++gaps_;
    ahrs_.reset(mag ? dsp::attitude_from_accel_mag(a, m) : dsp::attitude_from_accel(a));
    dt_ = 0.0;
  } else {
    dt_ = dt;
    if (dt > 0) ahrs_.update(g, a, mag ? &m : nullptr, dt);
  }
  t_ = s.t_s;
  valid_ = true;
  return true;
}

}  // namespace locus::plugins::motion_common
