// locus_amil_solve: runs the AMIL solver (plugins/amil/solver.hpp) with every method on positioning
// problems given as JSON, for the accuracy campaign (tools/scripts/amil_campaign.py) — it lets the
// campaign compare the methods on the *same* beeps and arrivals, isolated from the plugin's IMU tracking.
//
//   locus_amil_solve < problems.jsonl > solutions.jsonl
//
// One problem per input line:
//   {"name": "...", "c": 343.2, "timing_std_s": 1.5e-6, "position_std_m": 0.003,
//    "beeps": [{"p": [x, y], "e": t_player_s}, ...],          (e null = beep not found by the player)
//    "listeners": [{"id": "L1", "a": [t_s | null, ...], "known_skew": s (optional)}, ...]}
// One output line per (listener, method):
//   {"name", "id", "method", "status", "x", "y", "direction_rad", "distance_m", "std_m", "skew", "note"}
// The methods: paper (skew = known_skew when given, else 0), paper_joint_skew, joint, robust, and
// network (solve_network over all listeners of the problem).
#include <cmath>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "amil/solver.hpp"

namespace amil = locus::plugins::amil;
using nlohmann::json;

namespace {
double num_or_nan(const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); }
json finite_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }
}  // namespace

int main() {
  std::string line;
  int lineno = 0;
  while (std::getline(std::cin, line)) {
    ++lineno;
    if (line.empty()) continue;
    try {
      const json pj = json::parse(line);
      amil::SolverConfig base;
      base.speed_of_sound_mps = pj.value("c", 343.2);
      base.timing_std_s = pj.value("timing_std_s", base.timing_std_s);
      base.position_std_m = pj.value("position_std_m", base.position_std_m);
      std::vector<amil::Beep> beeps;
      for (const auto& b : pj.at("beeps")) {
        amil::Beep beep;
        beep.position_m = {b.at("p").at(0).get<double>(), b.at("p").at(1).get<double>()};
        beep.player_time_s = num_or_nan(b.at("e"));
        beeps.push_back(beep);
      }
      auto emit = [&](const std::string& id, amil::Method m, const amil::Solution& s) {
        json out{{"name", pj.value("name", "")},
                 {"id", id},
                 {"method", amil::to_string(m)},
                 {"status", amil::to_string(s.status)},
                 {"x", finite_or_null(s.position_m.x())},
                 {"y", finite_or_null(s.position_m.y())},
                 {"direction_rad", finite_or_null(s.direction_rad)},
                 {"distance_m", finite_or_null(s.distance_m)},
                 {"std_m", finite_or_null(s.std_m)},
                 {"distance_std_m", finite_or_null(s.distance_std_m)},
                 {"skew", finite_or_null(s.skew)},
                 {"confidence", s.confidence},
                 {"beeps_used", s.beeps_used},
                 {"note", s.note}};
        std::cout << out.dump() << '\n';
      };
      std::vector<amil::ListenerArrivals> all;
      std::vector<std::string> ids;
      for (const auto& l : pj.at("listeners")) {
        amil::ListenerArrivals arr;
        for (const auto& a : l.at("a")) arr.arrival_s.push_back(num_or_nan(a));
        const double known = l.contains("known_skew") ? num_or_nan(l.at("known_skew")) : std::nan("");
        for (auto m : {amil::Method::Paper, amil::Method::PaperJointSkew, amil::Method::Joint, amil::Method::Robust}) {
          amil::SolverConfig cfg = base;
          cfg.method = m;
          amil::ListenerArrivals la = arr;
          la.known_skew = m == amil::Method::Paper ? known : std::nan("");
          emit(l.at("id").get<std::string>(), m, amil::solve(beeps, la, cfg));
        }
        all.push_back(arr);
        ids.push_back(l.at("id").get<std::string>());
      }
      amil::SolverConfig cfg = base;
      cfg.method = amil::Method::Network;
      const auto net = amil::solve_network(beeps, all, cfg);
      for (std::size_t i = 0; i < ids.size(); ++i) emit(ids[i], amil::Method::Network, net.listeners[i]);
    } catch (const std::exception& e) {
      std::cerr << "locus_amil_solve: stdin:" << lineno << ": " << e.what() << '\n';
      return 2;
    }
  }
  return 0;
}
