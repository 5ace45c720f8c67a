// TUM maths: see solver.hpp.
#include "solver.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include "locus/numbers.hpp"

namespace locus::plugins::tum {

namespace {

Eigen::Matrix3d relative_rotation(const DeviceExchange& d1, const DeviceExchange& d) {
  if (!d1.attitude || !d.attitude) return Eigen::Matrix3d::Identity();
  return (d1.attitude->conjugate() * *d.attitude).normalized().toRotationMatrix();  // Eq. 5: R1^-1 R2
}

double mean_finite(const std::vector<double>& v) {
  double s = 0.0;
  int n = 0;
  for (double x : v)
    if (std::isfinite(x)) s += x, ++n;
  return n ? s / n : kNaN;
}

double lever_sigma(double timing_m, const Eigen::Vector3d& lever, double attitude_std_rad) {
  const double a = lever.norm() * attitude_std_rad;
  return std::sqrt(timing_m * timing_m + a * a);
}

}  // namespace

double reference_time_s(const std::vector<double>& t1_s) {
  double sum = 0.0;
  int n = 0;
  for (double t : t1_s)
    if (std::isfinite(t)) sum += t, ++n;
  return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

double own_emission_time(const DeviceExchange& d, const std::vector<double>& t_own, double c) {
  if (!d.speaker) return kNaN;
  double s = 0.0;
  int n = 0;
  for (std::size_t k = 0; k < d.mics.size() && k < t_own.size(); ++k) {
    if (!std::isfinite(t_own[k])) continue;
    s += t_own[k] - (d.mics[k] - *d.speaker).norm() / c;
    ++n;
  }
  return n ? s / n : kNaN;
}

std::vector<dsp::RangeEquation> pair_equations(const DeviceExchange& d1, const DeviceExchange& d2,
                                               const Eigen::Matrix3d& r12, const SolverConfig& cfg) {
  std::vector<dsp::RangeEquation> eqs;
  const double c = cfg.speed_of_sound_mps;
  const double tm1 = own_emission_time(d1, d1.t1_s, c);  // M's emission, device 1 clock
  const double tn2 = own_emission_time(d2, d2.t2_s, c);  // N's emission, device 2 clock
  if (!std::isfinite(tm1) || !std::isfinite(tn2) || !d1.speaker || !d2.speaker) return eqs;
  const double timing_m = c * cfg.timing_std_s;
  const Eigen::Vector3d m = *d1.speaker;
  const Eigen::Vector3d s2 = r12 * *d2.speaker;
  for (std::size_t a = 0; a < d1.mics.size() && a < d1.t2_s.size(); ++a) {  // device 1 hears N
    if (!std::isfinite(d1.t2_s[a])) continue;
    dsp::RangeEquation e;
    e.offset = s2;
    e.target = d1.mics[a];
    e.sign = -1.0;
    e.y = c * (d1.t2_s[a] - tn2);
    e.sigma = lever_sigma(timing_m, s2, cfg.attitude_std_rad);
    eqs.push_back(e);
  }
  for (std::size_t j = 0; j < d2.mics.size() && j < d2.t1_s.size(); ++j) {  // device 2 hears M
    if (!std::isfinite(d2.t1_s[j])) continue;
    dsp::RangeEquation e;
    e.offset = r12 * d2.mics[j];
    e.target = m;
    e.sign = 1.0;
    e.y = c * (d2.t1_s[j] - tm1);
    e.sigma = lever_sigma(timing_m, e.offset, cfg.attitude_std_rad);
    eqs.push_back(e);
  }
  return eqs;
}

std::vector<dsp::RangeEquation> monitor_equations(const DeviceExchange& d1, const DeviceExchange& d2,
                                                  const DeviceExchange& p, const Eigen::Matrix3d& r1p,
                                                  const Eigen::Vector3d& m, const Eigen::Vector3d& n,
                                                  double rho2_m, double n_sigma_m, const SolverConfig& cfg) {
  std::vector<dsp::RangeEquation> eqs;
  const double c = cfg.speed_of_sound_mps;
  const double tm1 = own_emission_time(d1, d1.t1_s, c);
  const double tn2 = own_emission_time(d2, d2.t2_s, c);
  if (!std::isfinite(tm1) || !std::isfinite(tn2)) return eqs;
  const double timing_m = c * cfg.timing_std_s;
  for (std::size_t k = 0; k < p.mics.size(); ++k) {
    const Eigen::Vector3d off = r1p * p.mics[k];
    const double base = lever_sigma(timing_m, off, cfg.attitude_std_rad);
    if (k < p.t1_s.size() && std::isfinite(p.t1_s[k])) {
      dsp::RangeEquation e;
      e.offset = off;
      e.target = m;
      e.sign = 1.0;
      e.y = c * (p.t1_s[k] - tm1);
      e.sigma = base;
      eqs.push_back(e);
    }
    if (k < p.t2_s.size() && std::isfinite(p.t2_s[k])) {
      dsp::RangeEquation e;
      e.offset = off;
      e.target = n;
      e.sign = 1.0;
      e.y = c * (p.t2_s[k] - tn2) + rho2_m;  // N's emission on device 1's clock: tn2 - rho/c
      e.sigma = std::sqrt(base * base + n_sigma_m * n_sigma_m);
      eqs.push_back(e);
    }
  }
  return eqs;
}

int choose_root(const std::vector<dsp::RangeRoot>& roots, const std::optional<Eigen::Vector3d>& prior, double chi2_slack) {
  if (roots.empty()) return -1;
  if (!prior) return 0;
  int best = 0;
  double best_d = (roots[0].x - *prior).norm();
  for (std::size_t i = 1; i < roots.size(); ++i) {
    if (roots[i].cost > roots[0].cost + chi2_slack) break;
    const double d = (roots[i].x - *prior).norm();
    if (d < best_d) best = static_cast<int>(i), best_d = d;
  }
  return best;
}

ExchangeResult solve_exchange(const std::vector<DeviceExchange>& devices, const SolverConfig& cfg,
                              const std::vector<std::optional<Eigen::Vector3d>>& priors) {
  ExchangeResult out;
  if (devices.size() < 2) return out;
  const double c = cfg.speed_of_sound_mps;
  const DeviceExchange& d1 = devices[0];
  const DeviceExchange& d2 = devices[1];
  auto prior = [&](std::size_t i) -> std::optional<Eigen::Vector3d> {
    return i < priors.size() ? priors[i] : std::nullopt;
  };
  out.t_ref_s = own_emission_time(d1, d1.t1_s, c);
  out.devices.resize(devices.size());
  for (std::size_t i = 0; i < devices.size(); ++i) {
    out.devices[i].id = devices[i].id;
    out.devices[i].rotation = relative_rotation(d1, devices[i]);
  }
  Placement& p1 = out.devices[0];
  p1.ok = d1.speaker.has_value() && std::isfinite(out.t_ref_s);
  p1.why = p1.ok ? "" : "device 1 did not hear its own tone";
  p1.origin.setZero();
  if (d1.speaker) p1.speaker = *d1.speaker;
  if (!p1.ok) return out;

  // Working pair.
  Placement& p2 = out.devices[1];
  const std::vector<dsp::RangeEquation> eqs = pair_equations(d1, d2, p2.rotation, cfg);
  if (!d1.attitude || !d2.attitude) {
    p2.why = "no attitude for the working pair";
  } else if (eqs.size() < 4) {
    p2.why = "fewer than 4 cross arrivals in the working pair (" + std::to_string(eqs.size()) + ")";
  } else {
    dsp::RangeSolveOptions opt;
    double sum = 0.0;  // Eq. 3: the distance sums give the range; start the search there
    for (const auto& e : eqs) sum += e.y;
    const double range0 = std::clamp(sum / static_cast<double>(eqs.size()), 0.05, cfg.max_range_m);
    opt.radii = {range0};
    opt.directions = cfg.directions;
    opt.centre = Eigen::Vector3d::Zero();
    p2.roots = dsp::solve_ranges(eqs, opt);
    p2.equations = eqs;
    std::erase_if(p2.roots, [&](const dsp::RangeRoot& r) { return r.x.norm() > cfg.max_range_m; });
    const int k = choose_root(p2.roots, prior(1));
    if (k < 0) {
      p2.why = "the working pair's equations have no root within max_range_m";
    } else {
      const dsp::RangeRoot& r = p2.roots[static_cast<std::size_t>(k)];
      p2.ok = true;
      p2.origin = r.x;
      p2.speaker = r.x + p2.rotation * *d2.speaker;
      p2.cov = r.cov.topLeftCorner<3, 3>();
      p2.rms_m = r.rms_m;
      p2.rho_m = r.rho;
    }
  }
  if (!p2.ok) return out;
  const double tn2 = own_emission_time(d2, d2.t2_s, c);
  out.t_n_minus_t_m_s = (tn2 - p2.rho_m / c) - out.t_ref_s;  // Eq. 20
  const double n_sigma = std::sqrt(std::max(0.0, p2.cov.trace()) / 3.0);

  // Monitoring devices.
  for (std::size_t i = 2; i < devices.size(); ++i) {
    Placement& pp = out.devices[i];
    const DeviceExchange& dp = devices[i];
    if (!dp.attitude) {
      pp.why = "no attitude";
      continue;
    }
    const std::vector<dsp::RangeEquation> me =
        monitor_equations(d1, d2, dp, pp.rotation, *d1.speaker, p2.speaker, p2.rho_m, n_sigma, cfg);
    if (me.size() < 4) {
      pp.why = "fewer than 4 arrivals (" + std::to_string(me.size()) + ")";
      continue;
    }
    dsp::RangeSolveOptions opt;
    opt.centre = 0.5 * (*d1.speaker + p2.speaker);
    opt.radii = {0.5, 1.5, 3.0};
    opt.directions = cfg.directions;
    pp.roots = dsp::solve_ranges(me, opt);
    pp.equations = me;
    std::erase_if(pp.roots, [&](const dsp::RangeRoot& r) { return r.x.norm() > cfg.max_range_m; });
    const int k = choose_root(pp.roots, prior(i));
    if (k < 0) {
      pp.why = "no root within max_range_m";
      continue;
    }
    const dsp::RangeRoot& r = pp.roots[static_cast<std::size_t>(k)];
    pp.ok = true;
    pp.origin = r.x;
    pp.speaker = dp.speaker ? Eigen::Vector3d(r.x + pp.rotation * *dp.speaker) : r.x;
    pp.cov = r.cov.topLeftCorner<3, 3>();
    pp.rms_m = r.rms_m;
    pp.rho_m = r.rho;
  }
  return out;
}

Stamp stamp_of(const DeviceExchange& d) { return Stamp{mean_finite(d.t1_s), mean_finite(d.t2_s)}; }

int match_stamp(const Stamp& r, const std::vector<Stamp>& dev, double offset_s, double tolerance_s,
                double interval_tolerance_s, double interval_diff_s) {
  int best = -1;
  double best_err = std::numeric_limits<double>::infinity();
  const bool r1 = std::isfinite(r.t1), r2 = std::isfinite(r.t2);
  for (std::size_t j = 0; j < dev.size(); ++j) {
    const Stamp& d = dev[j];
    double err;
    if (r1 && std::isfinite(d.t1)) err = std::abs(d.t1 - r.t1 - offset_s);
    else if (r2 && std::isfinite(d.t2)) err = std::abs(d.t2 - r.t2 - offset_s);
    else continue;
    if (err > tolerance_s) continue;
    if (r1 && r2 && std::isfinite(d.t1) && std::isfinite(d.t2)) {
      const double diff = (d.t2 - d.t1) - (r.t2 - r.t1);
      if (std::abs(diff) > interval_tolerance_s) continue;
      if (std::isfinite(interval_diff_s) && std::abs(diff - interval_diff_s) > tolerance_s) continue;
    }
    if (err < best_err) best = static_cast<int>(j), best_err = err;
  }
  return best;
}

namespace {

bool both_tones(const Stamp& s) { return std::isfinite(s.t1) && std::isfinite(s.t2); }

/// One candidate's agreement: how many of ref's exchanges pair, their tone-1 residuals' sum and square sum.
struct Agreement {
  int n = 0;
  double sum = 0.0, sq = 0.0;
};

Agreement agreement(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double offset_s, double interval_diff_s,
                    double tolerance_s, double interval_tolerance_s) {
  Agreement a;
  for (const Stamp& rr : ref) {
    const int j = match_stamp(rr, dev, offset_s, tolerance_s, interval_tolerance_s, interval_diff_s);
    if (j < 0) continue;
    ++a.n;
    const double e = dev[static_cast<std::size_t>(j)].t1 - rr.t1 - offset_s;
    if (std::isfinite(e)) a.sq += e * e, a.sum += e;
  }
  return a;
}

/// Calls f(offset, interval difference) for every candidate: a pair of exchanges that heard both tones
/// and whose intervals agree within `interval_tolerance_s`.
template <class F>
void for_each_candidate(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double interval_tolerance_s, F&& f) {
  for (const Stamp& r : ref) {
    if (!both_tones(r)) continue;
    for (const Stamp& d : dev) {
      if (!both_tones(d)) continue;
      const double diff = (d.t2 - d.t1) - (r.t2 - r.t1);
      if (std::abs(diff) <= interval_tolerance_s) f(d.t1 - r.t1, diff);
    }
  }
}

}  // namespace

ClockPairing align_clocks(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double tolerance_s,
                          double interval_tolerance_s, int min_pairs, int min_margin) {
  struct Candidate {
    double offset_s;
    Agreement a;
  };
  std::vector<Candidate> candidates;
  for_each_candidate(ref, dev, interval_tolerance_s, [&](double o, double diff) {
    candidates.push_back({o, agreement(ref, dev, o, diff, tolerance_s, interval_tolerance_s)});
  });
  ClockPairing out;
  const Candidate* best = nullptr;
  for (const Candidate& c : candidates)
    if (best == nullptr || c.a.n > best->a.n || (c.a.n == best->a.n && c.a.sq < best->a.sq)) best = &c;
  if (best == nullptr) return out;
  out.pairs = best->a.n;
  // Another round: tone-1 offsets of one round differ by at most the propagation over the spread.
  for (const Candidate& c : candidates)
    if (std::abs(c.offset_s - best->offset_s) > interval_tolerance_s && c.a.n > out.runner_up_pairs)
      out.runner_up_pairs = c.a.n, out.runner_up_offset_s = c.offset_s;
  if (out.pairs < min_pairs || out.pairs - out.runner_up_pairs < min_margin) return out;
  out.offset_s = best->offset_s + (best->a.n ? best->a.sum / best->a.n : 0.0);
  return out;
}

int count_pairs(const std::vector<Stamp>& ref, const std::vector<Stamp>& dev, double offset_s, double tolerance_s,
                double interval_tolerance_s) {
  int best = 0;
  for_each_candidate(ref, dev, interval_tolerance_s, [&](double o, double diff) {
    if (std::abs(o - offset_s) <= tolerance_s)
      best = std::max(best, agreement(ref, dev, offset_s, diff, tolerance_s, interval_tolerance_s).n);
  });
  return best;
}

std::optional<double> speed_of_sound_sample(const DeviceExchange& d, const std::vector<double>& t_own, double min_baseline_m) {
  if (!d.speaker) return std::nullopt;
  int near = -1, far = -1;
  for (std::size_t k = 0; k < d.mics.size() && k < t_own.size(); ++k) {
    if (!std::isfinite(t_own[k])) continue;
    const double dk = (d.mics[k] - *d.speaker).norm();
    if (near < 0 || dk < (d.mics[static_cast<std::size_t>(near)] - *d.speaker).norm()) near = static_cast<int>(k);
    if (far < 0 || dk > (d.mics[static_cast<std::size_t>(far)] - *d.speaker).norm()) far = static_cast<int>(k);
  }
  if (near < 0 || far < 0 || near == far) return std::nullopt;
  const double base = (d.mics[static_cast<std::size_t>(far)] - *d.speaker).norm() -
                      (d.mics[static_cast<std::size_t>(near)] - *d.speaker).norm();
  const double dt = t_own[static_cast<std::size_t>(far)] - t_own[static_cast<std::size_t>(near)];
  if (base < min_baseline_m || !(dt > 0)) return std::nullopt;
  return base / dt;
}

}  // namespace locus::plugins::tum
