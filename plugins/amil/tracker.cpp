// AMIL movement tracking: see tracker.hpp for the algorithm and why it deviates from the paper.
#include "tracker.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include "locus/numbers.hpp"

namespace locus::plugins::amil {

namespace {

Eigen::Quaterniond rotation_vector(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  if (angle < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * v.x(), 0.5 * v.y(), 0.5 * v.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle));
}

}  // namespace

bool Session::speaker_at(double t_s, Eigen::Vector3d& out_m, bool* in_pause, double* std_m) const {
  for (const Pause& p : pauses) {
    if (t_s >= p.t_start_s && t_s < p.t_end_s) {
      out_m = p.speaker_m;
      if (in_pause != nullptr) *in_pause = true;
      if (std_m != nullptr) *std_m = p.position_std_m;
      return true;
    }
  }
  for (std::size_t k = 0; k < movements.size(); ++k) {
    const Movement& m = movements[k];
    if (t_s < m.t_start_s || t_s > m.t_end_s || m.t_s.empty() || k + 1 >= pauses.size()) continue;
    const auto it = std::upper_bound(m.t_s.begin(), m.t_s.end(), t_s);
    Eigen::Vector3d body;
    if (it == m.t_s.begin()) {
      body = m.body_m.front();
    } else if (it == m.t_s.end()) {
      body = m.body_m.back();
    } else {
      const std::size_t i = static_cast<std::size_t>(it - m.t_s.begin());
      const double u = (t_s - m.t_s[i - 1]) / (m.t_s[i] - m.t_s[i - 1]);
      body = m.body_m[i - 1] + u * (m.body_m[i] - m.body_m[i - 1]);
    }
    const Pause& after = pauses[k + 1];
    out_m = body + (after.speaker_m - after.body_m);
    if (std_m != nullptr) *std_m = std::max(pauses[k].position_std_m, after.position_std_m);
    if (in_pause != nullptr) *in_pause = t_s < m.t_active_start_s || t_s > m.t_active_end_s;
    return true;
  }
  return false;
}

GestureTracker::GestureTracker(TrackerConfig cfg) : cfg_(std::move(cfg)) {
  if (!(cfg_.bin_s > 0.0) || !(cfg_.motion_threshold_mps2 > 0.0) || cfg_.quiet_bins < 1 || cfg_.min_rest_s < 0.0 ||
      !(cfg_.session_gap_s > 0.0) || !(cfg_.max_gap_s > 0.0) || !cfg_.speaker_body_m.allFinite()) {
    throw std::invalid_argument(
        "amil tracker: bin_s, motion_threshold_mps2, session_gap_s, max_gap_s must be > 0, quiet_bins >= 1, "
        "min_rest_s >= 0 and the speaker position finite");
  }
}

double GestureTracker::rest_s() const noexcept {
  if (moving_ || !std::isfinite(rest_start_) || !std::isfinite(last_t_)) return 0.0;
  return std::max(0.0, last_t_ - rest_start_);
}

void GestureTracker::reset_state() {
  bin_start_ = std::numeric_limits<double>::quiet_NaN();
  bin_.clear();
  prev_bin_.clear();
  rest_tail_.clear();
  rest_start_ = std::numeric_limits<double>::quiet_NaN();
  rest_a_sum_.setZero();
  rest_a_sq_sum_.setZero();
  rest_d2_sum_.setZero();
  rest_d2_n_ = 0;
  rest_prev_n_ = 0;
  rest_w_sum_.setZero();
  rest_n_ = 0;
  have_rest_ = false;
  moving_ = false;
  quiet_run_ = 0;
  move_.clear();
  if (session_open_) {
    // The open session cannot be completed: drop it (its beeps cannot be placed).
    sessions_.pop_back();
    ++counters_.abandoned_sessions;
  }
  session_open_ = false;
  q_ = Eigen::Quaterniond::Identity();
}

void GestureTracker::add(double t_s, const Eigen::Vector3d& accel_mps2, const Eigen::Vector3d& gyro_radps) {
  if (!std::isfinite(t_s) || !accel_mps2.allFinite() || !gyro_radps.allFinite()) {
    ++counters_.non_finite;
    return;
  }
  ++counters_.samples;
  if (std::isfinite(last_t_) && (t_s <= last_t_ || t_s - last_t_ > cfg_.max_gap_s)) {
    ++counters_.gaps;
    reset_state();
  }
  last_t_ = t_s;
  if (!std::isfinite(bin_start_)) {
    bin_start_ = t_s;
    if (!std::isfinite(rest_start_)) rest_start_ = t_s;
  }
  while (t_s >= bin_start_ + cfg_.bin_s) {
    end_bin();
    bin_start_ += cfg_.bin_s;
  }
  bin_.push_back(Sample{t_s, accel_mps2, gyro_radps});
  if (moving_) move_.push_back(bin_.back());
}

void GestureTracker::end_bin() {
  if (bin_.empty()) {
    // An empty bin (IMU slower than bins): nothing to judge.
    return;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Sample& s : bin_) mean += s.a;
  mean /= static_cast<double>(bin_.size());
  if (!have_rest_) {
    rest_a_ = mean;
    have_rest_ = true;
  }
  double dev2 = 0.0;
  for (const Sample& s : bin_) dev2 += (s.a - rest_a_).squaredNorm();
  const double dev = std::sqrt(dev2 / static_cast<double>(bin_.size()));
  const bool active = dev > cfg_.motion_threshold_mps2;
  const double bin_end = bin_start_ + cfg_.bin_s;

  if (!moving_) {
    if (active) {
      // Movement: starts (conservatively) at the previous bin, which is not part of the rest.
      const double start = prev_bin_.empty() ? bin_.front().t : prev_bin_.front().t;
      move_.clear();
      const double keep_from = rest_tail_.empty() ? 0.0 : rest_tail_.back().t - cfg_.rest_window_s;
      for (const Sample& s : rest_tail_)  // the rest before (at most rest_window_s): zero-mean velocity
        if (s.t >= keep_from) move_.push_back(s);
      for (const Sample& s : prev_bin_) move_.push_back(s);
      for (const Sample& s : bin_) move_.push_back(s);
      active_start_ = bin_start_;
      active_end_ = bin_end;
      start_movement(start);
    } else {
      // The previous bin is confirmed rest (one bin of lag keeps a movement's onset out of it).
      for (const Sample& s : prev_bin_) {
        rest_tail_.push_back(s);
        rest_a_sum_ += s.a;
        rest_a_sq_sum_ += s.a.cwiseProduct(s.a);
        if (rest_prev_n_ >= 2) {
          const Eigen::Vector3d d2 = s.a - 2.0 * rest_prev_[0] + rest_prev_[1];
          rest_d2_sum_ += d2.cwiseProduct(d2);
          ++rest_d2_n_;
        }
        rest_prev_[1] = rest_prev_[0];
        rest_prev_[0] = s.a;
        ++rest_prev_n_;
        rest_w_sum_ += s.w;
        ++rest_n_;
      }
      if (rest_n_ > 0) rest_a_ = rest_a_sum_ / static_cast<double>(rest_n_);
      if (!rest_tail_.empty()) {
        const double keep_from = rest_tail_.back().t - cfg_.rest_window_s;
        std::size_t drop = 0;
        while (drop < rest_tail_.size() && rest_tail_[drop].t < keep_from) ++drop;
        rest_tail_.erase(rest_tail_.begin(), rest_tail_.begin() + static_cast<std::ptrdiff_t>(drop));
      }
      if (session_open_ && bin_end - rest_start_ >= cfg_.session_gap_s) {
        Session& s = sessions_.back();
        s.closed = true;
        s.t_end_s = s.movements.empty() ? s.t_start_s : s.movements.back().t_end_s;
        session_open_ = false;
        if (on_closed_) on_closed_(s, bin_end);
      }
    }
  } else {
    quiet_run_ = active ? 0 : quiet_run_ + 1;
    if (active) active_end_ = bin_end;
    if (quiet_run_ >= cfg_.quiet_bins) {
      end_movement(bin_end);  // the quiet bins belong to the movement, not to the new rest
      bin_.clear();
      return;
    }
  }
  prev_bin_.swap(bin_);
  bin_.clear();
}

Eigen::Matrix3d GestureTracker::level_from_gravity(const Eigen::Vector3d& up_body) const {
  const Eigen::Vector3d z = up_body.normalized();
  Eigen::Vector3d y = Eigen::Vector3d::UnitY() - z * z.y();  // body y, horizontal part
  if (y.norm() < std::sin(11.5 * M_PI / 180.0)) y = -Eigen::Vector3d::UnitZ() - z * (-z.z());  // upright: body -z
  y.normalize();
  const Eigen::Vector3d x = y.cross(z);
  Eigen::Matrix3d m;
  m.row(0) = x.transpose();
  m.row(1) = y.transpose();
  m.row(2) = z.transpose();
  return m;
}

void GestureTracker::start_movement(double t_start) {
  moving_ = true;
  quiet_run_ = 0;
  move_start_ = t_start;
  const double rest_len = rest_n_ > 0 ? t_start - rest_start_ : 0.0;
  // Gyro bias: the mean rate over every rest of the session so far (the bias barely moves over a
  // gesture, ~1e-4 rad/s per √s, while a hand's rotational tremor leaves ~3e-3 rad/s in the mean of
  // one short pause: pooling the rests keeps that out of the heading). A new session starts the pool.
  if (!session_open_) {
    bias_w_sum_.setZero();
    bias_n_ = 0;
  }
  bias_w_sum_ += rest_w_sum_;
  bias_n_ += rest_n_;
  if (bias_n_ > 0) gyro_bias_ = bias_w_sum_ / static_cast<double>(bias_n_);
  if (rest_n_ > 1) {
    // Per-axis sample variance at rest (the horizontal axes' mean is what the integration sees).
    const double n = static_cast<double>(rest_n_);
    const Eigen::Vector3d mean = rest_a_sum_ / n;
    const Eigen::Vector3d var = (rest_a_sq_sum_ / n - mean.cwiseProduct(mean)).cwiseMax(0.0) * (n / (n - 1.0));
    // The white part only: second differences (var = 6 sigma² for white noise) all but remove a hand's
    // tremor (8-12 Hz), whose double integral is tens of µm, not the noise bridge's millimetres.
    if (rest_d2_n_ >= 5) accel_noise_mps2_ = std::sqrt(std::min(var.mean(), (rest_d2_sum_ / static_cast<double>(rest_d2_n_)).mean() / 6.0));
    else accel_noise_mps2_ = std::sqrt(var.mean());
  }
  if (!session_open_) {
    if (rest_n_ == 0 || rest_len + 1e-9 < cfg_.min_rest_s) return;  // no rest to learn gravity from: untracked
    // Open a session: T = the start of this movement.
    Session s;
    s.id = ++counters_.sessions;
    s.t_start_s = t_start;
    s.level = level_from_gravity(rest_a_);
    q_ = Eigen::Quaterniond::Identity();
    Pause p0;
    p0.t_start_s = rest_start_;
    p0.t_end_s = t_start;
    p0.body_m.setZero();
    p0.speaker_m = s.level * cfg_.speaker_body_m;
    p0.position_std_m = 0.0;  // the origin of the frame: exact by definition
    session_var_m2_ = 0.0;
    s.pauses.push_back(p0);
    // The previous closed session's last pause ends where this one starts.
    if (!sessions_.empty() && sessions_.back().closed && !sessions_.back().pauses.empty() &&
        sessions_.back().pauses.back().t_end_s == kInf) {
      sessions_.back().pauses.back().t_end_s = t_start;
    }
    sessions_.push_back(std::move(s));
    session_open_ = true;
  } else {
    sessions_.back().pauses.back().t_end_s = t_start;
  }
}

void GestureTracker::end_movement(double t_end) {
  moving_ = false;
  quiet_run_ = 0;
  if (session_open_ && !move_.empty()) {
    Session& s = sessions_.back();
    Movement m;
    m.t_start_s = move_start_;
    m.t_end_s = t_end;
    m.t_active_start_s = active_start_;
    m.t_active_end_s = std::max(active_start_, active_end_);
    const Eigen::Matrix3d& L = s.level;
    const Eigen::Vector3d g_ref = L * (q_ * rest_a_);  // gravity + accelerometer bias, start frame
    const std::size_t n = move_.size();
    std::vector<Eigen::Vector3d> acc(n), vel(n);
    Eigen::Quaterniond q = q_;
    for (std::size_t i = 0; i < n; ++i) {
      if (i > 0) {
        const double dt = move_[i].t - move_[i - 1].t;
        const Eigen::Vector3d w = 0.5 * (move_[i].w + move_[i - 1].w) - gyro_bias_;
        q = (q * rotation_vector(w * dt)).normalized();
      }
      acc[i] = L * (q * move_[i].a) - g_ref;
    }
    vel[0].setZero();
    for (std::size_t i = 1; i < n; ++i) vel[i] = vel[i - 1] + 0.5 * (acc[i] + acc[i - 1]) * (move_[i].t - move_[i - 1].t);
    // Velocity compensation (paper Sec. II-C; "Deviation" in tracker.hpp): the linear velocity error
    // that makes the velocity zero-mean over the rests on both sides, else zero at both ends.
    const double t0 = move_.front().t, span = move_.back().t - t0;
    const Eigen::Vector3d v_end = vel[n - 1];
    m.end_speed_mps = v_end.norm();
    double s0 = 0, s1 = 0, s2 = 0;
    Eigen::Vector3d sv = Eigen::Vector3d::Zero(), stv = Eigen::Vector3d::Zero();
    std::size_t lead = 0, trail = 0;
    auto is_lead = [&](std::size_t i) { return move_[i].t < move_start_; };
    auto is_trail = [&](std::size_t i) { return move_[i].t >= m.t_active_end_s; };
    for (std::size_t i = 0; i < n; ++i) {
      if (!is_lead(i) && !is_trail(i)) continue;
      (is_lead(i) ? lead : trail) += 1;
      const double t = move_[i].t - t0;
      s0 += 1, s1 += t, s2 += t * t;
      sv += vel[i];
      stv += t * vel[i];
    }
    const double det = s0 * s2 - s1 * s1;
    const bool rests = lead >= 3 && trail >= 3 && det > 1e-12;
    const Eigen::Vector3d alpha = rests ? Eigen::Vector3d((s2 * sv - s1 * stv) / det) : Eigen::Vector3d::Zero();
    const Eigen::Vector3d beta =
        rests ? Eigen::Vector3d((s0 * stv - s1 * sv) / det) : (span > 0.0 ? Eigen::Vector3d(v_end / span) : Eigen::Vector3d::Zero());
    for (std::size_t i = 0; i < n; ++i) vel[i] -= alpha + beta * (move_[i].t - t0);
    // what the de-drift removed over the movement itself (the uncertainty's drift term)
    const double moving_s = std::max(0.0, m.t_end_s - move_start_);
    if (rests) m.end_speed_mps = (beta * moving_s).norm();
    if (!rests && !(span > 0.0)) vel[n - 1].setZero();
    std::vector<Eigen::Vector3d> pos(n);
    pos[0].setZero();
    for (std::size_t i = 1; i < n; ++i) pos[i] = pos[i - 1] + 0.5 * (vel[i] + vel[i - 1]) * (move_[i].t - move_[i - 1].t);
    // The previous pause is where the rest before was on average; this pause where the rest after is.
    Eigen::Vector3d lead_mean = Eigen::Vector3d::Zero(), trail_mean = Eigen::Vector3d::Zero();
    if (rests) {
      for (std::size_t i = 0; i < n; ++i) {
        if (is_lead(i)) lead_mean += pos[i];
        if (is_trail(i)) trail_mean += pos[i];
      }
      lead_mean /= static_cast<double>(lead);
      trail_mean /= static_cast<double>(trail);
    } else {
      trail_mean = pos[n - 1];
    }
    const Eigen::Vector3d start_body = s.pauses.back().body_m;
    m.t_s.reserve(n);
    m.body_m.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (move_[i].t < move_start_) continue;  // the rest before belongs to the previous pause
      m.t_s.push_back(move_[i].t);
      m.body_m.push_back(start_body + pos[i] - lead_mean);
    }
    const Eigen::Vector3d p = trail_mean - lead_mean;
    m.displacement_m = p;
    // Uncertainty (tracker.hpp): noise bridge + de-drift residual accumulate; scale error ~ displacement.
    const double dt_mean = n > 1 ? span / static_cast<double>(n - 1) : 0.0;
    const double noise_sd = accel_noise_mps2_ * std::sqrt(dt_mean * moving_s * moving_s * moving_s / 12.0);
    const double drift_sd = cfg_.drift_shape_factor * m.end_speed_mps * moving_s;
    m.accumulated_var_m2 = noise_sd * noise_sd + drift_sd * drift_sd;
    session_var_m2_ += m.accumulated_var_m2;
    q_ = q;
    Pause next;
    next.t_start_s = t_end;
    next.t_end_s = kInf;
    next.body_m = start_body + p;
    next.speaker_m = next.body_m + L * (q_ * cfg_.speaker_body_m);
    const double scale_sd = cfg_.accel_scale_error * next.body_m.head<2>().norm();
    next.position_std_m = std::sqrt(session_var_m2_ + scale_sd * scale_sd + cfg_.position_floor_m * cfg_.position_floor_m);
    s.movements.push_back(std::move(m));
    s.pauses.push_back(next);
  }
  // The movement's quiet bins (after its last moving bin) are rest as well: they open the next
  // movement's lead rest, so a short pause (0.3 s, of which the quiet bins and the next movement's
  // one-bin margin take most) still gives that movement a zero-mean-velocity window instead of the
  // two-instant rule, which pins a trembling hand's velocity (a few mm/s) at one instant.
  rest_tail_.clear();
  for (const Sample& smp : move_)
    if (smp.t >= active_end_) rest_tail_.push_back(smp);
  move_.clear();
  // A new rest starts after the movement.
  rest_start_ = t_end;
  rest_a_sum_.setZero();
  rest_a_sq_sum_.setZero();
  rest_d2_sum_.setZero();
  rest_d2_n_ = 0;
  rest_prev_n_ = 0;
  rest_w_sum_.setZero();
  rest_n_ = 0;
  prev_bin_.clear();  // its samples belong to the movement
  if (session_open_ && on_pause_) on_pause_(sessions_.back(), t_end);
  // A gesture of known strokes is complete at its last pause (its last beep is still to come: the
  // session's last pause stays open, t_end_s = +inf, until the next session starts).
  if (session_open_ && cfg_.session_movements > 0 &&
      sessions_.back().movements.size() >= static_cast<std::size_t>(cfg_.session_movements)) {
    Session& s = sessions_.back();
    s.closed = true;
    s.t_end_s = s.movements.back().t_end_s;
    session_open_ = false;
    if (on_closed_) on_closed_(s, t_end);
  }
}

void GestureTracker::close_session() {
  if (moving_) {
    // The stream ended mid-movement: integrate what there is (the de-drift assumes it stopped).
    end_movement(std::isfinite(last_t_) ? last_t_ : move_start_);
  }
  if (session_open_) {
    Session& s = sessions_.back();
    s.closed = true;
    s.t_end_s = s.movements.empty() ? s.t_start_s : s.movements.back().t_end_s;
    session_open_ = false;
    if (on_closed_) on_closed_(s, last_t_);
  }
}

}  // namespace locus::plugins::amil
