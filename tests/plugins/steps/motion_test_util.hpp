// Running the motion plugins on sample vectors (tests only).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus::test {

/// Creates and configures built-in detector `name` with its defaults overridden by `overrides`.
inline std::unique_ptr<Detector> make_detector(const std::string& name, TestHost& host, const Params& overrides = {}) {
  Registry reg;
  register_builtins(reg);
  const locus_plugin_descriptor* d = reg.find_plugin(name);
  if (!d) throw std::runtime_error("no plugin " + name);
  Params p = Params::defaults(*d->schema());
  for (const auto& [k, v] : overrides.values()) p.set(k, v);
  auto det = std::unique_ptr<Detector>(d->create_detector());
  StreamInfo info;
  info.device = "walker";
  HostContext ctx = host.context(name, "walker");
  det->configure(info, p, ctx);
  return det;
}

inline void feed_imu(Detector& d, const std::vector<ImuSample>& s, EventSink& sink, std::size_t chunk = 32) {
  for (std::size_t i = 0; i < s.size(); i += chunk) d.process_imu(s.data() + i, std::min(chunk, s.size() - i), sink);
}

template <typename T>
std::vector<T> events_of(const CollectingSink& sink) {
  std::vector<T> out;
  for (const Event& e : sink.events)
    if (const auto* x = std::get_if<T>(&e)) out.push_back(*x);
  return out;
}

/// Greedy one-to-one matching of detections to truth within `tol_s`; returns the matched pairs'
/// time offsets (detected - true).
inline std::vector<double> match_times(const std::vector<double>& truth, const std::vector<double>& det, double tol_s) {
  std::vector<bool> used(det.size(), false);
  std::vector<double> offsets;
  for (double t : truth) {
    int best = -1;
    for (std::size_t j = 0; j < det.size(); ++j)
      if (!used[j] && std::abs(det[j] - t) <= tol_s && (best < 0 || std::abs(det[j] - t) < std::abs(det[best] - t)))
        best = static_cast<int>(j);
    if (best >= 0) {
      used[static_cast<std::size_t>(best)] = true;
      offsets.push_back(det[static_cast<std::size_t>(best)] - t);
    }
  }
  return offsets;
}

}  // namespace locus::test
