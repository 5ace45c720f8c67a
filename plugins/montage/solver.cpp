// The maths of `montage` (see solver.hpp for the method).
#include "solver.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace locus::plugins::montage {

namespace {

Eigen::Matrix2d rot(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}
Eigen::Matrix2d drot(double a) {
  const double c = std::cos(a), s = std::sin(a);
  Eigen::Matrix2d r;
  r << -s, -c, c, -s;
  return r;
}
double huber_cost(double e, double k) {
  const double a = std::abs(e);
  return a <= k ? e * e : 2.0 * k * a - k * k;
}

}  // namespace

double etoa_distance_m(double dt_i_s, double dt_j_s, double self_i_m, double self_j_m, double c_mps) {
  return 0.5 * c_mps * (dt_i_s + dt_j_s) + 0.5 * (self_i_m + self_j_m);
}

std::size_t RoundBook::add(const RoundMessage& m) {
  std::size_t best = rounds_.size();
  double best_d = match_s_;
  for (std::size_t r = 0; r < rounds_.size(); ++r) {
    const double d = std::abs(rounds_[r].tau_s - m.tau_own_s);
    if (d < best_d && rounds_[r].reports.count(m.device) == 0) {
      best = r;
      best_d = d;
    }
  }
  if (best == rounds_.size()) {
    Round r;
    r.tau_s = m.tau_own_s;
    r.reports.emplace(m.device, m);
    const auto at = std::upper_bound(rounds_.begin(), rounds_.end(), m.tau_own_s,
                                     [](double t, const Round& x) { return t < x.tau_s; });
    const std::size_t idx = static_cast<std::size_t>(at - rounds_.begin());
    rounds_.insert(at, std::move(r));
    return idx;
  }
  Round& r = rounds_[best];
  r.reports.emplace(m.device, m);
  double sum = 0.0;
  for (const auto& [d, rep] : r.reports) sum += rep.tau_own_s;
  r.tau_s = sum / static_cast<double>(r.reports.size());
  return best;
}

namespace {

/// The arrival of `other`'s code in m (dt since m's own emission), if m heard it.
std::optional<double> dt_of(const RoundMessage& m, const std::string& other) {
  for (const auto& [u, dt] : m.arrivals)
    if (u == other) return dt;
  return std::nullopt;
}

/// Calls fn(i, j, report_i, report_j, dt_i(j), dt_j(i)) for every pair i < j of users that both
/// reported in the round (either arrival may be missing).
template <typename Fn>
void for_each_reported_pair(const Round& round, const std::vector<std::string>& users, Fn&& fn) {
  for (std::size_t i = 0; i < users.size(); ++i)
    for (std::size_t j = i + 1; j < users.size(); ++j) {
      const auto a = round.reports.find(users[i]), b = round.reports.find(users[j]);
      if (a == round.reports.end() || b == round.reports.end()) continue;
      fn(i, j, a->second, b->second, dt_of(a->second, users[j]), dt_of(b->second, users[i]));
    }
}

}  // namespace

std::vector<RangeObs> round_ranges(const Round& round, const std::vector<std::string>& users, double c_mps,
                                   double max_range_m) {
  std::vector<RangeObs> out;
  for_each_reported_pair(round, users, [&](std::size_t i, std::size_t j, const RoundMessage& mi, const RoundMessage& mj,
                                           std::optional<double> dti, std::optional<double> dtj) {
    if (!dti || !dtj) return;
    const double d = etoa_distance_m(*dti, *dtj, mi.self_m, mj.self_m, c_mps);
    if (!(d > 0.0) || d > max_range_m) return;
    out.push_back(RangeObs{i, j, d});
  });
  return out;
}

namespace {

/// rho_i(j) (solver.hpp, PairClocks): i's one-way view of the distance to j, before the clock term.
double one_way_rho(const RoundMessage& mi, const RoundMessage& mj, double dt_i, double c_mps) {
  return c_mps * (mi.tau_own_s + dt_i - mj.tau_own_s) + mj.self_m;
}

}  // namespace

void PairClocks::add(std::size_t i, std::size_t j, double tau_s, double eps_s) {
  if (!std::isfinite(tau_s) || !std::isfinite(eps_s)) return;
  auto& o = obs_[{std::min(i, j), std::max(i, j)}];
  o.emplace_back(tau_s, i < j ? eps_s : -eps_s);
  if (o.size() > std::max<std::size_t>(opt_.max_rounds, 2)) o.erase(o.begin());
}

std::optional<std::pair<double, double>> PairClocks::predict(std::size_t i, std::size_t j, double tau_s) const {
  const auto it = obs_.find({std::min(i, j), std::max(i, j)});
  if (it == obs_.end() || it->second.empty()) return std::nullopt;
  const auto& o = it->second;
  // Which rounds to trust: a wrong detection makes a two-way round whose eps is off by half its error
  // (tens of ms), so with 3 or more rounds the line through the pair of rounds that most others agree
  // with (within outlier_sigma · obs_std_s; slopes within 4 sd of the skew prior only) decides; a
  // wrong round among the first ones is outvoted instead of bending the line.
  std::vector<char> use(o.size(), 1);
  if (o.size() >= 3) {
    const double tol = opt_.outlier_sigma * opt_.obs_std_s;
    std::size_t best = 0;
    for (std::size_t k = 0; k < o.size(); ++k)
      for (std::size_t l = k + 1; l < o.size(); ++l) {
        const double dt = o[l].first - o[k].first;
        if (std::abs(dt) < 1e-6) continue;
        const double b = (o[l].second - o[k].second) / dt;
        if (std::abs(b) > 4.0 * opt_.skew_prior) continue;
        std::size_t in = 0;
        for (const auto& [t, e] : o) in += std::abs(o[k].second + b * (t - o[k].first) - e) <= tol;
        if (in > best) {
          best = in;
          for (std::size_t m = 0; m < o.size(); ++m)
            use[m] = std::abs(o[k].second + b * (o[m].first - o[k].first) - o[m].second) <= tol;
        }
      }
    if (best == 0) std::fill(use.begin(), use.end(), 1);  // no two rounds agree: all, and the prior
  }
  // Bayesian line eps = a + b·(tau − t0) (t0: the mean tau of the rounds used, so a and b decouple);
  // a second pass drops what lies far off the first fit.
  double t0 = 0.0, used = 0.0;
  for (std::size_t k = 0; k < o.size(); ++k)
    if (use[k]) {
      t0 += o[k].first;
      used += 1.0;
    }
  t0 /= std::max(used, 1.0);
  Eigen::Matrix2d cov;
  Eigen::Vector2d mean;
  for (int pass = 0; pass < 2; ++pass) {
    const double w = 1.0 / (opt_.obs_std_s * opt_.obs_std_s);
    // The prior on the offset is at the start (tau = 0): eps(0) = a − b·t0, so it couples a and b.
    const Eigen::Vector2d h0(1.0, -t0);
    Eigen::Matrix2d info = h0 * h0.transpose() / (opt_.offset_prior_s * opt_.offset_prior_s);
    info(1, 1) += 1.0 / (opt_.skew_prior * opt_.skew_prior);
    Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
    for (std::size_t k = 0; k < o.size(); ++k) {
      if (!use[k]) continue;
      const Eigen::Vector2d h(1.0, o[k].first - t0);
      info += w * h * h.transpose();
      rhs += w * h * o[k].second;
    }
    cov = info.inverse();
    mean = cov * rhs;
    if (pass == 1) break;
    bool any = false;
    for (std::size_t k = 0; k < o.size(); ++k) {
      if (!use[k]) continue;
      const Eigen::Vector2d h(1.0, o[k].first - t0);
      const double sd = std::sqrt(opt_.obs_std_s * opt_.obs_std_s + h.dot(cov * h));
      if (std::abs(o[k].second - h.dot(mean)) > opt_.outlier_sigma * sd && o.size() >= 3) {
        use[k] = 0;
        any = true;
      }
    }
    if (!any) break;
  }
  const Eigen::Vector2d h(1.0, tau_s - t0);
  const double eps = h.dot(mean), sd = std::sqrt(std::max(0.0, h.dot(cov * h)));
  return std::make_pair(i < j ? eps : -eps, sd);
}

std::size_t PairClocks::count(std::size_t i, std::size_t j) const {
  const auto it = obs_.find({std::min(i, j), std::max(i, j)});
  return it == obs_.end() ? 0 : it->second.size();
}

std::optional<std::pair<double, double>> PairClocks::last(std::size_t i, std::size_t j) const {
  const auto it = last_.find({std::min(i, j), std::max(i, j)});
  if (it == last_.end()) return std::nullopt;
  return it->second;
}

void learn_clocks(const Round& round, const std::vector<std::string>& users, double c_mps,
                  std::vector<RangeObs>& two_way, PairClocks& clocks) {
  const PairClockOptions& o = clocks.options();
  std::vector<RangeObs> kept;
  for (const RangeObs& ro : two_way) {
    const auto a = round.reports.find(users[ro.i]), b = round.reports.find(users[ro.j]);
    if (a == round.reports.end() || b == round.reports.end()) continue;
    const auto dti = dt_of(a->second, users[ro.j]), dtj = dt_of(b->second, users[ro.i]);
    if (!dti || !dtj) continue;
    const double rho_i = one_way_rho(a->second, b->second, *dti, c_mps), rho_j = one_way_rho(b->second, a->second, *dtj, c_mps);
    const double eps = (rho_j - rho_i) / (2.0 * c_mps);
    bool off_line = false;
    if (clocks.count(ro.i, ro.j) >= static_cast<std::size_t>(o.min_two_way)) {
      const auto line = clocks.predict(ro.i, ro.j, round.tau_s);
      off_line = line && std::abs(eps - line->first) > o.outlier_sigma * std::hypot(o.obs_std_s, line->second);
    }
    // Every round's eps is kept (the line's consensus judges them all again later: an early wrong
    // round must not make the good ones look wrong for good); the range only when it is on the line.
    clocks.add(ro.i, ro.j, round.tau_s, eps);
    if (off_line) continue;
    clocks.accept(ro.i, ro.j, round.tau_s, ro.distance_m);
    kept.push_back(ro);
  }
  two_way = std::move(kept);
}

std::vector<RangeObs> one_way_ranges(const Round& round, const std::vector<std::string>& users, double c_mps,
                                     double max_range_m, const PairClocks& clocks) {
  std::vector<RangeObs> out;
  const PairClockOptions& o = clocks.options();
  for_each_reported_pair(round, users, [&](std::size_t i, std::size_t j, const RoundMessage& mi, const RoundMessage& mj,
                                           std::optional<double> dti, std::optional<double> dtj) {
    if (dti.has_value() == dtj.has_value()) return;  // two-way (round_ranges) or nothing
    if (clocks.count(i, j) < static_cast<std::size_t>(o.min_two_way)) return;
    const auto eps = clocks.predict(i, j, round.tau_s);
    const auto last = clocks.last(i, j);
    if (!eps || !last || round.tau_s - last->first > o.max_gap_s) return;
    const double extra = c_mps * eps->second;
    if (extra > o.max_extra_std_m) return;
    // eps is eps_ij: rho_i(j) = d − c·eps, rho_j(i) = d + c·eps.
    const double d = dti ? one_way_rho(mi, mj, *dti, c_mps) + c_mps * eps->first : one_way_rho(mj, mi, *dtj, c_mps) - c_mps * eps->first;
    if (!(d > 0.0) || d > max_range_m) return;
    if (std::abs(d - last->second) > o.max_speed_mps * (round.tau_s - last->first) + 3.0 * extra + 0.3) return;
    out.push_back(RangeObs{i, j, d, extra});
  });
  return out;
}

Formation::Formation(std::vector<std::string> users, FormationConfig cfg)
    : users_(std::move(users)), cfg_(cfg), tracks_(users_.size()), delta_(users_.size(), 0.0),
      scale_(users_.size(), 1.0), localized_(users_.size(), 0) {}

void Formation::add_step(std::size_t u, double tau_s, double stride_m, double heading_rad,
                         std::optional<double> offset_rad) {
  Track& tr = tracks_.at(u);
  if (!tr.t.empty() && tau_s <= tr.t.back()) return;
  if (!std::isfinite(tau_s) || !std::isfinite(stride_m) || !std::isfinite(heading_rad) || stride_m < 0.0) return;
  const Eigen::Vector2d prev = tr.cum.empty() ? Eigen::Vector2d::Zero() : tr.cum.back();
  tr.t.push_back(tau_s);
  tr.stride.push_back(stride_m);
  tr.heading.push_back(heading_rad);
  tr.cum.push_back(prev + stride_m * Eigen::Vector2d(std::cos(heading_rad), std::sin(heading_rad)));
  tr.offset.push_back(offset_rad && std::isfinite(*offset_rad) ? *offset_rad : std::nan(""));
}

std::optional<double> Formation::prior_offset(std::size_t u, double tau_s) const {
  const Track& tr = tracks_[u];
  const auto it = std::upper_bound(tr.t.begin(), tr.t.end(), tau_s);
  for (auto i = static_cast<std::ptrdiff_t>(it - tr.t.begin()) - 1; i >= 0; --i)
    if (std::isfinite(tr.offset[static_cast<std::size_t>(i)])) return tr.offset[static_cast<std::size_t>(i)];
  return std::nullopt;
}

std::size_t Formation::add_round(double tau_s, std::vector<RangeObs> ranges) {
  RoundData r;
  r.tau_s = tau_s;
  r.dropped.assign(ranges.size(), 0);
  r.ranges = std::move(ranges);
  rounds_.push_back(std::move(r));
  positions_.emplace_back(users_.size(), Eigen::Vector2d::Zero());
  stds_.emplace_back(users_.size(), 0.0);
  return rounds_.size() - 1;
}

Eigen::Vector2d Formation::raw_at(std::size_t u, double t) const {
  const Track& tr = tracks_[u];
  if (tr.t.empty() || t <= tr.t.front()) return Eigen::Vector2d::Zero();
  if (t >= tr.t.back()) return tr.cum.back();
  const auto it = std::upper_bound(tr.t.begin(), tr.t.end(), t);
  const std::size_t i = static_cast<std::size_t>(it - tr.t.begin());  // t[i-1] <= t < t[i]
  const double f = (t - tr.t[i - 1]) / (tr.t[i] - tr.t[i - 1]);
  return tr.cum[i - 1] + f * (tr.cum[i] - tr.cum[i - 1]);
}

Eigen::Vector2d Formation::raw_move(std::size_t u, double a_s, double b_s, double* steps) const {
  if (steps != nullptr) {
    const Track& tr = tracks_[u];
    const auto lo = std::lower_bound(tr.t.begin(), tr.t.end(), std::min(a_s, b_s));
    const auto hi = std::lower_bound(tr.t.begin(), tr.t.end(), std::max(a_s, b_s));
    *steps = static_cast<double>(hi - lo);
  }
  return raw_at(u, b_s) - raw_at(u, a_s);
}

Eigen::Vector2d Formation::move(std::size_t u, double a_s, double b_s) const {
  return scale_[u] * (rot(delta_[u]) * raw_move(u, a_s, b_s));
}

std::vector<Formation::Candidate> Formation::pair_candidates(std::size_t i, std::size_t j, std::size_t base,
                                                             std::size_t k) const {
  struct Obs {
    std::size_t round;
    double r, extra;
  };
  std::vector<Obs> obs;
  const std::size_t a = std::min(i, j), b = std::max(i, j);
  for (std::size_t q = base; q <= k; ++q)
    for (std::size_t n = 0; n < rounds_[q].ranges.size(); ++n) {
      const RangeObs& ro = rounds_[q].ranges[n];
      if (ro.i == a && ro.j == b && !rounds_[q].dropped[n]) obs.push_back(Obs{q, ro.distance_m, ro.extra_std_m});
    }
  if (obs.size() < 2) return {};
  const std::size_t f = obs.front().round;
  const double tf = rounds_[f].tau_s;
  std::vector<Eigen::Vector2d> d(obs.size());
  std::vector<double> sig(obs.size());
  double max_rel = 0.0;
  for (std::size_t n = 0; n < obs.size(); ++n) {
    const double tq = rounds_[obs[n].round].tau_s;
    const Eigen::Vector2d mi = move(i, tf, tq), mj = move(j, tf, tq);
    d[n] = mj - mi;
    max_rel = std::max(max_rel, d[n].norm());
    const double drift = cfg_.drift_std_m_per_m * (mi.norm() + mj.norm()) + 0.03 * (mi.norm() + mj.norm());
    sig[n] = std::sqrt(cfg_.range_std_m * cfg_.range_std_m + drift * drift + obs[n].extra * obs[n].extra);
  }
  if (max_rel < 0.5) return {};  // the two moved alike: every orientation fits (infinite solutions)
  constexpr int kN = 360;
  std::vector<double> cost(kN);
  for (int a_deg = 0; a_deg < kN; ++a_deg) {
    const double th = 2.0 * std::numbers::pi * a_deg / kN;
    const Eigen::Vector2d rf = obs.front().r * Eigen::Vector2d(std::cos(th), std::sin(th));
    double c = 0.0;
    for (std::size_t n = 1; n < obs.size(); ++n) c += huber_cost(((rf + d[n]).norm() - obs[n].r) / sig[n], cfg_.huber_k);
    cost[static_cast<std::size_t>(a_deg)] = c;
  }
  auto at = [&](int x) { return cost[static_cast<std::size_t>(((x % kN) + kN) % kN)]; };
  int best = 0;
  for (int x = 1; x < kN; ++x)
    if (cost[static_cast<std::size_t>(x)] < cost[static_cast<std::size_t>(best)]) best = x;
  int second = -1;
  for (int x = 0; x < kN; ++x) {
    const int dist = std::min(std::abs(x - best), kN - std::abs(x - best));
    if (dist < 20) continue;
    if (at(x) <= at(x - 1) && at(x) <= at(x + 1) && (second < 0 || at(x) < at(second))) second = x;
  }
  const double tb = rounds_[base].tau_s;
  const Eigen::Vector2d back = move(j, tb, tf) - move(i, tb, tf);
  auto cand = [&](int x) {
    const double th = 2.0 * std::numbers::pi * x / kN;
    return Candidate{obs.front().r * Eigen::Vector2d(std::cos(th), std::sin(th)) - back, at(x)};
  };
  std::vector<Candidate> out{cand(best)};
  if (second >= 0 && at(second) - at(best) < cfg_.ambiguity_chi2) out.push_back(cand(second));
  return out;
}

void Formation::try_localize(std::size_t k) {
  const std::size_t n = users_.size();
  const std::size_t window = static_cast<std::size_t>(std::max(1, cfg_.window_rounds));
  const std::size_t b = origin_ ? std::max(base_, k + 1 > window ? k + 1 - window : 0) : (k + 1 > window ? k + 1 - window : 0);
  std::vector<std::vector<std::vector<Candidate>>> cand(n, std::vector<std::vector<Candidate>>(n));
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      if (i != j && (localized_[i] || localized_[j] || !origin_) && !(localized_[i] && localized_[j]))
        cand[i][j] = pair_candidates(i, j, b, k);
  std::vector<Eigen::Vector2d> pos_b(n, Eigen::Vector2d::Zero());
  std::vector<char> placed(localized_);
  if (origin_)
    for (std::size_t u = 0; u < n; ++u)
      if (localized_[u]) pos_b[u] = positions_[b][u];

  if (!origin_) {  // the start triangle (Eq. 3), else the best unambiguous pair
    double best = std::numeric_limits<double>::infinity();
    std::array<std::size_t, 3> tri{};
    std::array<Eigen::Vector2d, 3> tri_pos;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j)
        for (std::size_t l = j + 1; l < n; ++l) {
          if (cand[i][j].empty() || cand[j][l].empty() || cand[i][l].empty()) continue;
          for (const Candidate& rij : cand[i][j])
            for (const Candidate& rjl : cand[j][l])
              for (const Candidate& ril : cand[i][l]) {
                const double closure = (rij.r + rjl.r - ril.r).norm();
                if (closure < best) {
                  best = closure;
                  tri = {i, j, l};
                  tri_pos = {Eigen::Vector2d::Zero(), rij.r, 0.5 * (ril.r + rij.r + rjl.r)};
                }
              }
        }
    if (best <= cfg_.max_closure_m) {
      for (int m = 0; m < 3; ++m) {
        placed[tri[static_cast<std::size_t>(m)]] = 1;
        pos_b[tri[static_cast<std::size_t>(m)]] = tri_pos[static_cast<std::size_t>(m)];
      }
      origin_ = tri[0];
    } else {
      double bc = std::numeric_limits<double>::infinity();
      std::size_t bi = 0, bj = 0;
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = i + 1; j < n; ++j)
          if (cand[i][j].size() == 1 && cand[i][j][0].cost < bc) {
            bc = cand[i][j][0].cost;
            bi = i;
            bj = j;
          }
      if (!std::isfinite(bc)) return;
      placed[bi] = placed[bj] = 1;
      pos_b[bj] = cand[bi][bj][0].r;
      origin_ = bi;
    }
    base_ = b;
  }
  // Growth, breadth-first: two localized neighbours first, then one unambiguous neighbour.
  for (bool grew = true; grew;) {
    grew = false;
    for (int need = 2; need >= 1 && !grew; --need) {
      std::vector<std::pair<std::size_t, Eigen::Vector2d>> add;
      for (std::size_t u = 0; u < n; ++u) {
        if (placed[u]) continue;
        std::vector<std::size_t> nb;
        for (std::size_t m = 0; m < n; ++m)
          if (placed[m] && !cand[m][u].empty()) nb.push_back(m);
        if (nb.size() < static_cast<std::size_t>(need)) continue;
        if (need == 1) {
          if (nb.size() != 1 || cand[nb[0]][u].size() != 1) continue;
          add.emplace_back(u, pos_b[nb[0]] + cand[nb[0]][u][0].r);
          continue;
        }
        if (nb.size() > 6) nb.resize(6);
        // Every combination of the neighbours' candidates: the one whose positions agree best.
        std::size_t combos = 1;
        for (std::size_t m : nb) combos *= cand[m][u].size();
        double best = std::numeric_limits<double>::infinity();
        Eigen::Vector2d best_p = Eigen::Vector2d::Zero();
        for (std::size_t c = 0; c < combos; ++c) {
          std::size_t rest = c;
          std::vector<Eigen::Vector2d> ps;
          for (std::size_t m : nb) {
            const auto& cs = cand[m][u];
            ps.push_back(pos_b[m] + cs[rest % cs.size()].r);
            rest /= cs.size();
          }
          Eigen::Vector2d mean = Eigen::Vector2d::Zero();
          for (const auto& p : ps) mean += p;
          mean /= static_cast<double>(ps.size());
          double spread = 0.0;
          for (const auto& p : ps) spread = std::max(spread, (p - mean).norm());
          if (spread < best) {
            best = spread;
            best_p = mean;
          }
        }
        if (best <= cfg_.max_closure_m) add.emplace_back(u, best_p);
      }
      for (const auto& [u, p] : add) {
        placed[u] = 1;
        pos_b[u] = p;
        grew = true;
      }
    }
  }
  for (std::size_t u = 0; u < n; ++u) {
    if (!placed[u] || localized_[u]) continue;
    localized_[u] = 1;
    for (std::size_t q = base_; q <= k; ++q) positions_[q][u] = pos_b[u] + move(u, rounds_[b].tau_s, rounds_[q].tau_s);
  }
}

void Formation::adjust(std::size_t k) {
  const std::size_t n = users_.size();
  const std::size_t window = static_cast<std::size_t>(std::max(1, cfg_.window_rounds));
  const std::size_t w0 = std::max(base_, k + 1 > window ? k + 1 - window : 0);
  const std::size_t nr = k - w0 + 1;
  // Unknowns: positions (round, user), then per user δ (not the origin's) and k.
  std::vector<int> user_col(n, -1);
  int nl = 0;
  for (std::size_t u = 0; u < n; ++u)
    if (localized_[u]) user_col[u] = nl++;
  if (nl == 0) return;
  const int npos = 2 * nl * static_cast<int>(nr);
  const int pcol_psi = npos + 2 * nl;  // the frame's rotation from the world-aligned frame, ψ
  const int nvar = pcol_psi + 1;
  auto pcol = [&](std::size_t q, std::size_t u) { return 2 * (static_cast<int>(q - w0) * nl + user_col[u]); };
  auto dcol = [&](std::size_t u) { return npos + 2 * user_col[u]; };
  auto kcol = [&](std::size_t u) { return npos + 2 * user_col[u] + 1; };
  const bool gauge_fixed = w0 == base_;  // the origin's first position is the frame's origin

  Eigen::MatrixXd H(nvar, nvar);
  Eigen::VectorXd g(nvar);
  for (int it = 0; it < cfg_.iterations; ++it) {
    H.setZero();
    g.setZero();
    // Ranges.
    for (std::size_t q = w0; q <= k; ++q) {
      const RoundData& rd = rounds_[q];
      for (std::size_t m = 0; m < rd.ranges.size(); ++m) {
        const RangeObs& ro = rd.ranges[m];
        if (rd.dropped[m] || !localized_[ro.i] || !localized_[ro.j]) continue;
        const Eigen::Vector2d dv = positions_[q][ro.j] - positions_[q][ro.i];
        const double len = std::max(dv.norm(), 1e-6);
        const double sig = range_sigma(ro);
        const double e = (len - ro.distance_m) / sig;
        const double w = std::abs(e) <= cfg_.huber_k ? 1.0 : cfg_.huber_k / std::abs(e);
        const Eigen::Vector2d uvec = dv / len / sig;
        const int ci = pcol(q, ro.i), cj = pcol(q, ro.j);
        // J: d e/d p_j = u, d e/d p_i = −u
        H.block<2, 2>(cj, cj) += w * uvec * uvec.transpose();
        H.block<2, 2>(ci, ci) += w * uvec * uvec.transpose();
        H.block<2, 2>(ci, cj) -= w * uvec * uvec.transpose();
        H.block<2, 2>(cj, ci) -= w * uvec * uvec.transpose();
        g.segment<2>(cj) += w * uvec * e;
        g.segment<2>(ci) -= w * uvec * e;
      }
    }
    // Movement between consecutive rounds.
    for (std::size_t q = std::max<std::size_t>(w0, base_ + 1); q <= k; ++q)
      for (std::size_t u = 0; u < n; ++u) {
        if (!localized_[u]) continue;
        double steps = 0.0;
        const Eigen::Vector2d raw = raw_move(u, rounds_[q - 1].tau_s, rounds_[q].tau_s, &steps);
        const double sig = std::sqrt(cfg_.step_std_m * cfg_.step_std_m * steps +
                                     std::pow(cfg_.drift_std_m_per_m * scale_[u] * raw.norm(), 2) + 0.02 * 0.02);
        const Eigen::Matrix2d R = rot(delta_[u]);
        const Eigen::Vector2d pred = scale_[u] * (R * raw);
        const Eigen::Vector2d e = (positions_[q][u] - positions_[q - 1][u] - pred) / sig;
        // Jacobian blocks (2 x each var group).
        std::vector<std::pair<int, Eigen::MatrixXd>> J;
        J.emplace_back(pcol(q, u), Eigen::Matrix2d::Identity() / sig);
        if (q - 1 >= w0) J.emplace_back(pcol(q - 1, u), -Eigen::Matrix2d::Identity() / sig);
        Eigen::MatrixXd jk = -(R * raw) / sig;
        J.emplace_back(kcol(u), jk);
        if (origin_ && u != *origin_) {
          Eigen::MatrixXd jd = -(scale_[u] * (drot(delta_[u]) * raw)) / sig;
          J.emplace_back(dcol(u), jd);
        }
        for (const auto& [ca, Ja] : J) {
          g.segment(ca, Ja.cols()) += Ja.transpose() * e;
          for (const auto& [cb, Jb] : J) H.block(ca, cb, Ja.cols(), Jb.cols()) += Ja.transpose() * Jb;
        }
      }
    // Priors: δ around the acceleration estimate, k around 1; the origin's δ fixed.
    for (std::size_t u = 0; u < n; ++u) {
      if (!localized_[u]) continue;
      const int cd = dcol(u), ck = kcol(u);
      const bool fixed = origin_ && u == *origin_;
      if (fixed) H(cd, cd) += 1.0;  // no unknown: keep the system regular
      // The offset prior is in the world-aligned frame, δ in the positions' frame: δ_u − ψ ~ prior_u.
      // Every user's prior, the origin's too, shares the one ψ, so one device's prior error rotates
      // no other user's δ (before, the origin's δ was fixed at its own prior and that prior's error
      // pulled every other δ by the same angle).
      if (const std::optional<double> prior = prior_offset(u, rounds_[k].tau_s)) {
        const double w = 1.0 / (cfg_.offset_prior_std_rad * cfg_.offset_prior_std_rad);
        const double ed = std::remainder(delta_[u] - psi_ - *prior, 2.0 * std::numbers::pi);
        if (!fixed) {
          H(cd, cd) += w;
          g(cd) += w * ed;
        }
        if (cfg_.shared_frame_rotation) {  // else ψ stays 0: the origin's prior is taken as exact
          if (!fixed) {
            H(cd, pcol_psi) -= w;
            H(pcol_psi, cd) -= w;
          }
          H(pcol_psi, pcol_psi) += w;
          g(pcol_psi) -= w * ed;
        }
      } else if (!fixed) {
        H(cd, cd) += 1.0 / (std::numbers::pi * std::numbers::pi);
      }
      H(ck, ck) += 1.0 / (cfg_.scale_prior_std * cfg_.scale_prior_std);
      g(ck) += (scale_[u] - 1.0) / (cfg_.scale_prior_std * cfg_.scale_prior_std);
    }
    H(pcol_psi, pcol_psi) += 1e-6;  // ψ without any prior: not observable, stays
    // Gauge: the origin's position at the base round.
    if (gauge_fixed && origin_) {
      const int c = pcol(base_, *origin_);
      H.block<2, 2>(c, c) += 1e6 * Eigen::Matrix2d::Identity();
      g.segment<2>(c) += 1e6 * positions_[base_][*origin_];
    }
    // Users seen by no range in the window still have their movement chain; regularise lightly.
    for (int c = 0; c < nvar; ++c) H(c, c) += 1e-9;
    Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
    Eigen::VectorXd dx = -ldlt.solve(g);
    if (!dx.allFinite()) break;
    // Trust region: a Gauss-Newton step on a weakly constrained user (one range, a heading offset the
    // ranges barely see) can be metres; take at most 1 m per position and 0.2 rad / 0.1 per δ / k.
    double shrink = 1.0;
    for (int c = 0; c < npos; ++c) shrink = std::min(shrink, 1.0 / std::max(1e-12, std::abs(dx(c))));
    for (int c = npos; c < pcol_psi; ++c) shrink = std::min(shrink, ((c - npos) % 2 == 0 ? 0.2 : 0.1) / std::max(1e-12, std::abs(dx(c))));
    dx *= shrink;
    for (std::size_t q = w0; q <= k; ++q)
      for (std::size_t u = 0; u < n; ++u)
        if (localized_[u]) positions_[q][u] += dx.segment<2>(pcol(q, u));
    for (std::size_t u = 0; u < n; ++u) {
      if (!localized_[u]) continue;
      if (!(origin_ && u == *origin_)) delta_[u] += dx(dcol(u));
      scale_[u] = std::clamp(scale_[u] + dx(kcol(u)), 0.3, 3.0);
    }
    psi_ += std::clamp(dx(pcol_psi), -0.2, 0.2);
    if (dx.norm() < 1e-4) break;
  }
  // A posteriori variance factor: when the ranges and movements fit worse than their stds say
  // (reduced chi-square > 1: a wrong formation, a range or a step model that does not hold), the
  // covariance is widened by it; never narrowed (a fit cleaner than the stds is not evidence enough).
  double var_factor = 1.0;
  if (cfg_.chi2_std_inflation) {
    double chi2 = 0.0;
    int nobs = 0;
    for (std::size_t q = w0; q <= k; ++q) {
      const RoundData& rd = rounds_[q];
      for (std::size_t m = 0; m < rd.ranges.size(); ++m) {
        const RangeObs& ro = rd.ranges[m];
        if (rd.dropped[m] || !localized_[ro.i] || !localized_[ro.j]) continue;
        const double e = ((positions_[q][ro.j] - positions_[q][ro.i]).norm() - ro.distance_m) / range_sigma(ro);
        chi2 += e * e;
        ++nobs;
      }
    }
    for (std::size_t q = std::max<std::size_t>(w0, base_ + 1); q <= k; ++q)
      for (std::size_t u = 0; u < n; ++u) {
        if (!localized_[u] || q - 1 < w0) continue;
        double steps = 0.0;
        const Eigen::Vector2d raw = raw_move(u, rounds_[q - 1].tau_s, rounds_[q].tau_s, &steps);
        const double sig = std::sqrt(cfg_.step_std_m * cfg_.step_std_m * steps +
                                     std::pow(cfg_.drift_std_m_per_m * scale_[u] * raw.norm(), 2) + 0.02 * 0.02);
        const Eigen::Vector2d e = (positions_[q][u] - positions_[q - 1][u] - scale_[u] * (rot(delta_[u]) * raw)) / sig;
        chi2 += e.squaredNorm();
        nobs += 2;
      }
    // Unknowns: the positions (the δ and k are matched by their priors); the gauge fixes two.
    const int dof = nobs - npos + (gauge_fixed && origin_ ? 2 : 0);
    if (dof >= 3) var_factor = std::max(1.0, chi2 / dof);
  }
  // Covariance of the positions at round k (H at the last linearisation).
  Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
  for (std::size_t u = 0; u < n; ++u) {
    if (!localized_[u]) continue;
    const int c = pcol(k, u);
    Eigen::MatrixXd e = Eigen::MatrixXd::Zero(nvar, 2);
    e(c, 0) = 1.0;
    e(c + 1, 1) = 1.0;
    const Eigen::MatrixXd cov = ldlt.solve(e).block(c, 0, 2, 2);
    stds_[k][u] = std::sqrt(std::max(0.0, 0.5 * cov.trace()) * var_factor);
  }
  // Outliers: ranges far from the adjusted formation are dropped for good.
  for (std::size_t q = w0; q <= k; ++q) {
    RoundData& rd = rounds_[q];
    for (std::size_t m = 0; m < rd.ranges.size(); ++m) {
      const RangeObs& ro = rd.ranges[m];
      if (rd.dropped[m] || !localized_[ro.i] || !localized_[ro.j]) continue;
      const double len = (positions_[q][ro.j] - positions_[q][ro.i]).norm();
      if (std::abs(len - ro.distance_m) > cfg_.outlier_sigma * range_sigma(ro) + 0.1 * len) {
        rd.dropped[m] = 1;
        ++dropped_;
      }
    }
  }
}

std::vector<UserFix> Formation::solve(std::size_t k) {
  std::vector<UserFix> out(users_.size());
  if (k >= rounds_.size()) return out;
  for (std::size_t r = solved_; r <= k; ++r) {
    // Users not localized yet take their device's latest offset estimate (the origin keeps its own).
    for (std::size_t u = 0; u < users_.size(); ++u)
      if (!localized_[u])
        if (const auto p = prior_offset(u, rounds_[r].tau_s)) delta_[u] = *p;
    if (origin_ && r > base_)
      for (std::size_t u = 0; u < users_.size(); ++u)
        if (localized_[u]) positions_[r][u] = positions_[r - 1][u] + move(u, rounds_[r - 1].tau_s, rounds_[r].tau_s);
    if (std::count(localized_.begin(), localized_.end(), 1) < static_cast<std::ptrdiff_t>(users_.size())) try_localize(r);
    if (origin_) adjust(r);
    solved_ = r + 1;
  }
  for (std::size_t u = 0; u < users_.size(); ++u) {
    if (!localized_[u] || k < base_) continue;
    out[u].localized = true;
    out[u].position_m = positions_[k][u];
    out[u].std_m = stds_[k][u];
  }
  return out;
}

}  // namespace locus::plugins::montage
