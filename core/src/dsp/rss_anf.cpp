// LocBLE's adaptive noise filter (see rss_anf.hpp).
#include "locus/dsp/rss_anf.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace locus::dsp {

RssAnf::RssAnf(const RssAnfOptions& opt) : opt_(opt) {
  if (!(opt.grid_rate_hz > 0.0) || !(opt.lowpass_hz > 0.0))
    throw std::invalid_argument("RssAnf: grid_rate_hz and lowpass_hz must be > 0");
  grid_dt_ = 1.0 / opt.grid_rate_hz;
  if (opt.lowpass_hz >= 0.5 * opt.grid_rate_hz)
    throw std::invalid_argument("RssAnf: lowpass_hz (" + std::to_string(opt.lowpass_hz) +
                                ") must be below half of grid_rate_hz (" + std::to_string(0.5 * opt.grid_rate_hz) + ")");
  bf_ = SosFilter(butter_lowpass(opt.lowpass_order, opt.lowpass_hz, opt.grid_rate_hz));
}

double RssAnf::filter(double time, double rssi) noexcept {
  const double gap = time - last_t_;
  if (!(gap >= 0.0) || gap > opt_.restart_gap_s) {
    bf_.set_steady_state(rssi);
    bf_out_ = bf_prev_ = rssi;
    next_grid_t_ = time + grid_dt_;
    x_ = rssi;
    r_ = opt_.measurement_var_db2;
    p_ = opt_.measurement_var_db2;
    q_ = opt_.q_min_db2;
  } else {
    for (; next_grid_t_ <= time; next_grid_t_ += grid_dt_) {
      const double v = gap > 0 ? last_rssi_ + (rssi - last_rssi_) * (next_grid_t_ - last_t_) / gap : rssi;
      bf_out_ = bf_.process_double(v);
    }
    const double u = bf_out_ - bf_prev_;
    bf_prev_ = bf_out_;
    const double xp = x_ + u;
    const double pp = p_ + q_;
    const double nu = rssi - xp;
    const double k = pp / (pp + r_);
    x_ = xp + k * nu;
    p_ = (1.0 - k) * pp;
    q_ = (1.0 - opt_.akf_alpha) * q_ + opt_.akf_alpha * std::max(k * nu * k * nu, opt_.q_min_db2);
    r_ = (1.0 - opt_.akf_alpha_r) * r_ + opt_.akf_alpha_r * std::max(nu * nu - pp, opt_.r_min_db2);
  }
  last_t_ = time;
  last_rssi_ = rssi;
  return x_;
}

}  // namespace locus::dsp
