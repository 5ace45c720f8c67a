// Pedestrian model: steps with s = a·f + b, inverted-pendulum bounce, sway, smooth turns, phone attitude.
#include "locus/sim/motion/pedestrian.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "locus/angles.hpp"
#include "locus/sim/rng.hpp"
#include "locus/numbers.hpp"

namespace locus::sim::motion {
namespace {

// Quintic smoothstep: 0 → 1 on [0, 1] with zero first and second derivatives at both ends.
double smooth5(double u) {
  u = std::clamp(u, 0.0, 1.0);
  return u * u * u * (10.0 + u * (-15.0 + 6.0 * u));
}

// Quintic Hermite interpolation on [0, 1] of value/derivative/second derivative at both ends.
double hermite5(double u, double p0, double v0, double a0, double p1, double v1, double a1) {
  const double u2 = u * u, u3 = u2 * u, u4 = u3 * u, u5 = u4 * u;
  const double h0 = 1 - 10 * u3 + 15 * u4 - 6 * u5, h1 = u - 6 * u3 + 8 * u4 - 3 * u5;
  const double h2 = 0.5 * u2 - 1.5 * u3 + 1.5 * u4 - 0.5 * u5, h3 = 0.5 * u3 - u4 + 0.5 * u5;
  const double h4 = -4 * u3 + 7 * u4 - 3 * u5, h5 = 10 * u3 - 15 * u4 + 6 * u5;
  return p0 * h0 + v0 * h1 + a0 * h2 + a1 * h3 + v1 * h4 + p1 * h5;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("pedestrian: " + what);
}

}  // namespace

PedestrianTrajectory::PedestrianTrajectory(const PedestrianParams& params, double t0_s, std::uint64_t seed)
    : params_(params), t0_s_(t0_s) {
  const auto& p = params_;
  require(p.path_m.size() >= 2, "path needs at least 2 points");
  require(p.height_m >= 0.5 && p.height_m <= 2.5, "height_m must be in 0.5..2.5 m");
  require(p.step_freq_hz >= 0.5 && p.step_freq_hz <= 4.0, "step_freq_hz must be in 0.5..4 Hz");
  require(p.step_freq_cv >= 0.0 && p.step_freq_cv < 0.3, "step_freq_cv must be in [0, 0.3)");
  require(p.stride_noise_m >= 0.0 && p.sway_m >= 0.0 && p.wobble_rad >= 0.0 && p.bounce_gain >= 0.0,
          "noise, sway, wobble and bounce gain must be >= 0");
  require(p.surge >= 0.0 && p.surge < 0.5, "surge must be in [0, 0.5)");
  require(p.turn_length_m > 0.0, "turn_length_m must be > 0");
  require(p.start_rest_s >= 0.0 && p.end_rest_s >= 0.0, "rest durations must be >= 0");

  Rng rng(seed);
  a_ = p.stride_a_m_s.value_or(0.143 * p.height_m);
  b_ = p.stride_b_m.value_or(0.143 * p.height_m);
  leg_m_ = 0.53 * p.height_m;
  phone_z_m_ = p.floor_z_m + (p.phone_height_m > 0.0 ? p.phone_height_m : 0.62 * p.height_m);

  // --- smoothed path: heading as a smooth function of arclength, integrated to x, y.
  const std::size_t m = p.path_m.size();
  std::vector<double> seg_len, seg_heading, corner_s;
  double total = 0.0;
  for (std::size_t i = 0; i + 1 < m; ++i) {
    const Eigen::Vector2d d = p.path_m[i + 1] - p.path_m[i];
    const double len = d.norm();
    require(len > 1e-6, "path has a zero-length segment at point " + std::to_string(i + 1));
    seg_len.push_back(len);
    seg_heading.push_back(std::atan2(d.y(), d.x()));
    total += len;
    corner_s.push_back(total);  // corner at the end of segment i (last one unused)
  }
  path_len_ = total;
  struct Turn {
    double centre, width, delta;
  };
  std::vector<Turn> turns;
  for (std::size_t i = 1; i < seg_len.size(); ++i) {
    const double w = std::min({p.turn_length_m, seg_len[i - 1], seg_len[i]});
    turns.push_back({corner_s[i - 1], w, wrap_pi(seg_heading[i] - seg_heading[i - 1])});
  }
  auto heading_at = [&](double s) {
    double h = seg_heading[0];
    for (const auto& t : turns) h += t.delta * smooth5((s - t.centre + 0.5 * t.width) / t.width);
    return h;
  };
  const std::size_t n_table = static_cast<std::size_t>(std::ceil(total / ds_)) + 2;
  path_.resize(n_table);
  double x = p.path_m[0].x(), y = p.path_m[0].y();
  for (std::size_t i = 0; i < n_table; ++i) {
    const double s = static_cast<double>(i) * ds_;
    path_[i] = {x, y, heading_at(s)};
    const double hm = heading_at(s + 0.5 * ds_);  // midpoint rule
    x += ds_ * std::cos(hm);
    y += ds_ * std::sin(hm);
  }

  // --- steps: frequency, length (s = a·f + b + noise), until the path is walked.
  std::vector<double> freq;
  double walked = 0.0;
  while (walked < total - 1e-9) {
    const double f = std::clamp(p.step_freq_hz * (1.0 + p.step_freq_cv * rng.normal()), 0.3, 5.0);
    double s = std::max(0.1, a_ * f + b_ + p.stride_noise_m * rng.normal());
    if (walked + s > total) s = total - walked;
    if (s < 0.25 && !step_len_.empty()) {  // a tiny remainder joins the previous step
      step_len_.back() += s;
      walked = total;
      break;
    }
    freq.push_back(f);
    step_len_.push_back(s);
    walked += s;
  }
  const std::size_t n = step_len_.size();
  t_walk0_s_ = t0_s + p.start_rest_s;
  step_t0_.assign(n + 1, t_walk0_s_);
  step_d0_.assign(n + 1, 0.0);
  for (std::size_t k = 0; k < n; ++k) {
    step_t0_[k + 1] = step_t0_[k] + 1.0 / freq[k];
    step_d0_[k + 1] = step_d0_[k] + step_len_[k];
    steps_.push_back({step_t0_[k + 1], step_len_[k], freq[k]});
    max_speed_ = std::max(max_speed_, step_len_[k] * freq[k]);
  }
  // Surge, first/last-step profiles, sway and bounce stay well within 1.6x the mean step speed.
  max_speed_ = 1.6 * (1.0 + p.surge) * max_speed_ + 0.2;
  t_walk1_s_ = step_t0_[n];
  t_end_s_ = t_walk1_s_ + p.end_rest_s;

  for (int i = 0; i < 3; ++i) {
    wobble_phase_[i] = rng.uniform(0.0, kTwoPi);
    wander_phase_[i] = rng.uniform(0.0, kTwoPi);
    wander_freq_[i] = rng.uniform(0.1, 0.3);
  }
}

double PedestrianTrajectory::bounce_for_stride_m(double stride_m) const noexcept {
  const double sin_phi = std::clamp(stride_m / (2.0 * leg_m_), 0.0, 0.95);
  return params_.bounce_gain * leg_m_ * (1.0 - std::sqrt(1.0 - sin_phi * sin_phi));
}

void PedestrianTrajectory::path_at(double s_m, double& x, double& y, double& heading) const {
  const double fi = std::clamp(s_m / ds_, 0.0, static_cast<double>(path_.size() - 1));
  const std::size_t i = std::min(static_cast<std::size_t>(fi), path_.size() - 2);
  const double u = fi - static_cast<double>(i);
  const auto& a = path_[i];
  const auto& b = path_[i + 1];
  x = a.x + u * (b.x - a.x);
  y = a.y + u * (b.y - a.y);
  heading = a.heading + u * (b.heading - a.heading);
}

void PedestrianTrajectory::gait_at(double t, double& dist, double& phase, double& bounce) const {
  const std::size_t n = step_len_.size();
  if (n == 0 || t <= t_walk0_s_) {
    dist = 0.0;
    phase = 0.0;
    bounce = 0.0;
    return;
  }
  if (t >= t_walk1_s_) {
    dist = path_len_;
    phase = static_cast<double>(n);
    bounce = 0.0;
    return;
  }
  const auto it = std::upper_bound(step_t0_.begin(), step_t0_.end(), t);
  const std::size_t k = std::min<std::size_t>(static_cast<std::size_t>(it - step_t0_.begin()) - 1, n - 1);
  const double T = step_t0_[k + 1] - step_t0_[k];
  const double u = std::clamp((t - step_t0_[k]) / T, 0.0, 1.0);
  const double alpha = params_.surge;
  // Speed at a middle step's boundaries: s·f·(1 + surge); first/last steps join it with quintics.
  auto v_mid = [&](std::size_t j) { return step_len_[j] / (step_t0_[j + 1] - step_t0_[j]) * (1.0 + alpha); };
  const double sf = step_len_[k] / T;  // normaliser: g is in units of the step length
  double g;
  if (n == 1) {
    g = smooth5(u);
  } else if (k == 0) {
    g = hermite5(u, 0, 0, 0, 1, v_mid(1) / sf, 0);
  } else if (k == n - 1) {
    g = hermite5(u, 0, v_mid(n - 2) / sf, 0, 1, 0, 0);
  } else {
    g = u + alpha / kTwoPi * std::sin(kTwoPi * u);
  }
  dist = step_d0_[k] + step_len_[k] * g;
  phase = static_cast<double>(k) + u;

  // Bounce amplitude: per-step values placed at mid-stance, smoothly interpolated in between;
  // faded in over the first step and out over the last.
  const double pk = static_cast<double>(k) + u - 0.5;  // position between mid-stances
  const std::size_t j0 = static_cast<std::size_t>(std::clamp(std::floor(pk), 0.0, static_cast<double>(n - 1)));
  const std::size_t j1 = std::min(j0 + 1, n - 1);
  const double w = pk < 0.0 ? 0.0 : smooth5(pk - static_cast<double>(j0));
  double amp = (1.0 - w) * bounce_for_stride_m(step_len_[j0]) + w * bounce_for_stride_m(step_len_[j1]);
  double env = 1.0;
  if (n == 1) {
    env = std::sin(kPi * u) * std::sin(kPi * u);
  } else if (k == 0) {
    env = smooth5(u);
  } else if (k == n - 1) {
    env = 1.0 - smooth5(u);
  }
  bounce = amp * env;
}

Pose PedestrianTrajectory::pose(double t_s) const {
  double dist, phase, bounce;
  gait_at(t_s, dist, phase, bounce);
  double x, y, heading;
  path_at(dist, x, y, heading);
  const double n = static_cast<double>(step_len_.size());
  // Gait envelope for sway and wobble: 0 standing, 1 walking (smooth over the first and last step).
  double env = 0.0;
  if (phase > 0.0 && phase < n) env = n <= 1.0 ? std::sin(kPi * phase) : smooth5(phase) * smooth5(n - phase);
  const double sway = params_.sway_m * env * std::sin(kPi * phase);
  // Lowest at heel strike (integer phase), highest at mid-stance.
  const double z = phone_z_m_ - 0.5 * bounce * (1.0 + std::cos(kTwoPi * phase));
  Pose out;
  out.position_m = Eigen::Vector3d(x - sway * std::sin(heading), y + sway * std::cos(heading), z);
  const double w = params_.wobble_rad * env;
  const double pitch = params_.hold_pitch_rad + w * std::sin(kTwoPi * phase + wobble_phase_[0]) +
                       0.5 * w * std::sin(kTwoPi * wander_freq_[0] * t_s + wander_phase_[0]);
  const double roll = w * std::sin(kPi * phase + wobble_phase_[1]) +
                      0.5 * w * std::sin(kTwoPi * wander_freq_[1] * t_s + wander_phase_[1]);
  const double yaw = heading + 0.5 * w * std::sin(kPi * phase + wobble_phase_[2]) +
                     w * std::sin(kTwoPi * wander_freq_[2] * t_s + wander_phase_[2]);
  out.attitude = heading_pitch_roll(yaw, pitch, roll);
  return out;
}

}  // namespace locus::sim::motion
