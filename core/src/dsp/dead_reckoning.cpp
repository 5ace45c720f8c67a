// Pedestrian dead reckoning (see dead_reckoning.hpp for the frame and why it is shared).
#include "locus/dsp/dead_reckoning.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace locus::dsp {

double wrap_pi(double a) {
  a = std::fmod(a + std::numbers::pi, 2.0 * std::numbers::pi);
  if (a < 0) a += 2.0 * std::numbers::pi;
  return a - std::numbers::pi;
}

void DeadReckoning::add_heading(double t_s, double heading_rad) {
  if (!std::isfinite(t_s) || !std::isfinite(heading_rad)) return;
  if (!has_ref_) {
    has_ref_ = true;
    ref_t_s_ = t_s;
    ref_heading_ = heading_rad;
    last_raw_ = heading_rad;
    unwrapped_ = 0.0;
    head_t_.push_back(t_s);
    head_rel_.push_back(0.0);
    return;
  }
  if (t_s < head_t_.back()) return;
  unwrapped_ += wrap_pi(heading_rad - last_raw_);
  last_raw_ = heading_rad;
  head_t_.push_back(t_s);
  head_rel_.push_back(unwrapped_);
}

double DeadReckoning::mean_heading(double t0, double t1) const {
  if (head_t_.empty()) return 0.0;
  const auto lo = std::lower_bound(head_t_.begin(), head_t_.end(), t0);
  const auto hi = std::upper_bound(head_t_.begin(), head_t_.end(), t1);
  if (lo < hi) {
    double s = 0.0;
    for (auto it = lo; it != hi; ++it) s += head_rel_[static_cast<std::size_t>(it - head_t_.begin())];
    return s / static_cast<double>(hi - lo);
  }
  // No sample inside: the latest one at or before t1 (or the first one).
  const std::size_t i = hi == head_t_.begin() ? 0 : static_cast<std::size_t>(hi - head_t_.begin()) - 1;
  return head_rel_[i];
}

bool DeadReckoning::add_step(double t_s, double stride_m, double frequency_hz) {
  if (!std::isfinite(t_s) || !std::isfinite(stride_m) || stride_m <= 0.0) return false;
  if (!step_t_.empty() && t_s <= step_t_.back()) return false;
  double begin = 0.0;
  if (step_t_.empty()) {
    const double period = (std::isfinite(frequency_hz) && frequency_hz > 0.2) ? 1.0 / frequency_hz : 0.55;
    begin = t_s - std::min(period, 2.0);
    first_begin_s_ = begin;
  } else {
    begin = step_t_.back();
  }
  const double h = mean_heading(begin, t_s);
  const Eigen::Vector2d prev = step_pos_.empty() ? Eigen::Vector2d{0.0, 0.0} : step_pos_.back();
  step_t_.push_back(t_s);
  step_heading_.push_back(h);
  step_pos_.push_back(prev + stride_m * step_direction(h));
  cum_len_.push_back((cum_len_.empty() ? 0.0 : cum_len_.back()) + stride_m);
  return true;
}

Eigen::Vector2d DeadReckoning::position_at(double t_s) const {
  if (step_t_.empty() || t_s <= first_begin_s_) return {0.0, 0.0};
  if (t_s >= step_t_.back()) return step_pos_.back();
  const auto it = std::upper_bound(step_t_.begin(), step_t_.end(), t_s);
  const std::size_t i = static_cast<std::size_t>(it - step_t_.begin());  // t_s < step_t_[i]
  const double t0 = i == 0 ? first_begin_s_ : step_t_[i - 1];
  const Eigen::Vector2d p0 = i == 0 ? Eigen::Vector2d{0.0, 0.0} : step_pos_[i - 1];
  const double f = (t_s - t0) / (step_t_[i] - t0);
  return p0 + f * (step_pos_[i] - p0);
}

double DeadReckoning::path_length_at(double t_s) const {
  if (step_t_.empty() || t_s <= first_begin_s_) return 0.0;
  if (t_s >= step_t_.back()) return cum_len_.back();
  const auto it = std::upper_bound(step_t_.begin(), step_t_.end(), t_s);
  const std::size_t i = static_cast<std::size_t>(it - step_t_.begin());
  const double t0 = i == 0 ? first_begin_s_ : step_t_[i - 1];
  const double l0 = i == 0 ? 0.0 : cum_len_[i - 1];
  return l0 + (t_s - t0) / (step_t_[i] - t0) * (cum_len_[i] - l0);
}

std::optional<std::size_t> DeadReckoning::turn_step(double turn_rad) const {
  if (step_heading_.empty()) return std::nullopt;
  for (std::size_t i = 1; i < step_heading_.size(); ++i)
    if (std::abs(step_heading_[i] - step_heading_[0]) > turn_rad) return i;
  return std::nullopt;
}

}  // namespace locus::dsp
