// `locus train spyloc`: replay each scene's walker through the multitone detector, label every beep
// from the scene truth, fit the classifier. See train.hpp.
#include "train.hpp"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "app.hpp"
#include "locus/scene/csv.hpp"
#include "locus/scene/scene.hpp"
#include "replay/replay.hpp"
#include "spyloc/classifier.hpp"

namespace locus::app {

namespace {

namespace fs = std::filesystem;
using plugins::spyloc::DecayVector;

const std::vector<double> kGrid = {18000, 18250, 18500, 18750, 19000, 19250, 19500, 19750, 20000, 20250};

struct Beep {
  double frame = 0.0;
  double t_s = 0.0;
  int mask = 0;
  DecayVector decay{};
};

struct Truth {
  std::string beacon;
  double key = 0.0;  ///< local sample (extra) or true start (truth_los)
  bool los = true;
};

std::map<int, std::string> beacon_masks(const scene::Scene& sc) {
  std::map<int, std::string> out;
  for (const scene::EmitterSpec& e : sc.emitters)
    for (const auto& s : e.emits) {
      if (s.type != "multitone") continue;
      int m = 0;
      for (double f : s.tones_hz)
        for (std::size_t k = 0; k < kGrid.size(); ++k)
          if (std::fabs(kGrid[k] - f) < 0.5) m |= 1 << k;
      out[m] = e.id;
    }
  return out;
}

}  // namespace

int run_train_spyloc(const SpyLocTrainOptions& o) {
  std::size_t unlabelled = 0;
  // Replays one scene through the detector and appends its labelled beeps' features; 0 or the exit status.
  auto collect = [&](const std::string& dir, std::vector<DecayVector>& los, std::vector<DecayVector>& nlos) -> int {
    scene::Scene sc;
    try {
      sc = scene::load_scene(dir);
    } catch (const std::exception& e) {
      std::cerr << "locus train spyloc: " << e.what() << "\n";
      return kExitBadConfig;
    }
    const std::map<int, std::string> masks = beacon_masks(sc);
    if (masks.empty()) {
      std::cerr << "locus train spyloc: " << dir << "/scene.yaml: no multitone emitters (not a SpyLoc scene)\n";
      return kExitBadConfig;
    }
    // Labels.
    std::vector<Truth> truth;
    bool from_extra = false;
    const fs::path extra = fs::path(dir) / "truth-extra.yaml";
    const fs::path los_csv = fs::path(dir) / "truth_los.csv";
    if (fs::exists(extra)) {
      YAML::Node root = YAML::LoadFile(extra.string());
      if (root["beeps"] && root["beeps"].IsSequence()) {
        for (const auto& b : root["beeps"]) {
          Truth t;
          try {
            t.beacon = b["beacon"].as<std::string>();
            t.key = b["arrival_first_local_sample"].as<double>();
            t.los = b["label"].as<std::string>() == "LOS";
          } catch (const std::exception&) {
            std::cerr << "locus train spyloc: " << extra.string()
                      << ": beeps[]: expected beacon, arrival_first_local_sample and label (LOS/NLOS)\n";
            return kExitBadConfig;
          }
          truth.push_back(t);
        }
        from_extra = true;
      }
    }
    if (!from_extra) {
      if (!fs::exists(los_csv)) {
        std::cerr << "locus train spyloc: " << dir << ": no labels (truth-extra.yaml with `beeps`, or truth_los.csv)\n";
        return kExitBadConfig;
      }
      std::ifstream f(los_csv);
      std::string line;
      std::getline(f, line);
      if (line.rfind("t_true,beacon,los", 0) != 0) {
        std::cerr << "locus train spyloc: " << los_csv.string() << ":1: expected the header t_true,beacon,los\n";
        return kExitBadConfig;
      }
      int ln = 1;
      while (std::getline(f, line)) {
        ++ln;
        if (line.empty()) continue;
        std::stringstream ss(line);
        std::string a, b, c;
        std::getline(ss, a, ',');
        std::getline(ss, b, ',');
        std::getline(ss, c, ',');
        try {
          truth.push_back(Truth{b, std::stod(a), std::stoi(c) == 1});
        } catch (const std::exception&) {
          std::cerr << "locus train spyloc: " << los_csv.string() << ":" << ln << ": expected t_true,beacon,los (0/1)\n";
          return kExitBadConfig;
        }
      }
    }
    // Walker: the first device with audio.
    const scene::DeviceSpec* walker = nullptr;
    for (const auto& d : sc.devices)
      if (!d.audio.empty()) {
        walker = &d;
        break;
      }
    if (walker == nullptr) {
      std::cerr << "locus train spyloc: " << dir << "/scene.yaml: no device with audio\n";
      return kExitBadConfig;
    }
    scene::ClockTruth clock;
    if (sc.truth && sc.truth->clocks.count(walker->id)) clock = sc.truth->clocks.at(walker->id);

    // Detector-only replay into a temporary file.
    const fs::path tmp = fs::temp_directory_path() / ("locus-train-spyloc-" + std::to_string(::getpid()));
    fs::create_directories(tmp);
    const fs::path cfg = tmp / "detector.yaml";
    const fs::path out = tmp / "events.jsonl";
    {
      std::ofstream c(cfg);
      c << "log_level: warn\noutput: {path: \"-\", events: [audio_detection, decay_features]}\n"
        << "devices:\n  - id: \"" << walker->id << "\"\n    detectors:\n      - plugin: multitone\n"
        << "        params: " << (o.detector_params.empty() ? std::string("{from_scene: true}") : o.detector_params) << "\n";
    }
    if (!o.detector_params.empty() && o.detector_params.find("from_scene") == std::string::npos)
      std::cerr << "locus train spyloc: note: --detector-params given without from_scene\n";
    ReplayOptions ro;
    ro.scene_dir = dir;
    ro.config_path = cfg.string();
    ro.output = out.string();
    ro.events = "audio_detection,decay_features";
    ro.log_level = "warn";
    const int rc = run_replay(ro);
    if (rc != 0) {
      std::cerr << "locus train spyloc: replay of " << dir << " failed (status " << rc << ")\n";
      fs::remove_all(tmp);
      return rc;
    }
    std::vector<Beep> beeps;
    {
      std::ifstream f(out);
      std::string line;
      std::map<double, std::size_t> by_frame;
      while (std::getline(f, line)) {
        if (line.empty()) continue;
        const auto j = nlohmann::json::parse(line, nullptr, false);
        if (j.is_discarded() || !j.contains("type")) continue;
        if (j["type"] == "audio_detection") {
          Beep b;
          b.frame = j["frame"].get<double>();
          b.t_s = j["t_s"].get<double>();
          b.mask = j["template"].get<int>();
          by_frame[b.frame] = beeps.size();
          beeps.push_back(b);
        } else if (j["type"] == "decay_features") {
          auto it = by_frame.find(j["frame"].get<double>());
          if (it == by_frame.end()) continue;
          for (std::size_t k = 0; k < 6; ++k)
            beeps[it->second].decay[k] = j["decay_s"][k].is_null() ? NAN : j["decay_s"][k].get<float>();
        }
      }
    }
    fs::remove_all(tmp);
    std::size_t n_los = 0, n_nlos = 0;
    const double fs_hz = sc.sample_rate_hz;
    for (const Beep& b : beeps) {
      auto m = masks.find(b.mask);
      if (m == masks.end()) {
        ++unlabelled;
        continue;
      }
      const Truth* best = nullptr;
      for (const Truth& t : truth) {
        if (t.beacon != m->second) continue;
        bool match;
        if (from_extra) {
          match = std::fabs(t.key - b.frame) < 0.03 * fs_hz;
        } else {
          const double t_true = (b.t_s - clock.offset_s) / (1.0 + clock.skew_ppm * 1e-6);
          match = t_true - t.key > -0.002 && t_true - t.key < 0.12;
        }
        if (match) best = &t;
      }
      if (best == nullptr) {
        ++unlabelled;
        continue;
      }
      (best->los ? los : nlos).push_back(b.decay);
      ++(best->los ? n_los : n_nlos);
    }
    std::cerr << "locus train spyloc: " << dir << ": " << beeps.size() << " beeps, " << n_los << " LoS, " << n_nlos
              << " NLoS\n";
    return 0;
  };
  std::vector<DecayVector> los, nlos;
  std::string note;
  for (const std::string& dir : o.scenes) {
    if (const int rc = collect(dir, los, nlos); rc != 0) return rc;
    note += (note.empty() ? "" : " ") + fs::path(dir).filename().string();
  }
  // Held-out scenes are read before anything is written: a bad one refuses the run, model untouched.
  struct TestSet {
    std::string dir;
    std::vector<DecayVector> los, nlos;
  };
  std::vector<TestSet> tests;
  for (const std::string& dir : o.test_scenes) {
    TestSet t{dir, {}, {}};
    if (const int rc = collect(dir, t.los, t.nlos); rc != 0) return rc;
    tests.push_back(std::move(t));
  }
  plugins::spyloc::LosClassifier c;
  try {
    c.train(los, nlos, o.components);
    c.save(o.output, note);
  } catch (const std::exception& e) {
    std::cerr << "locus train spyloc: " << e.what() << "\n";
    return kExitBadConfig;
  }
  // Training accuracy (resubstitution; test on other scenes for the real figure, docs/spyloc.md).
  std::size_t ok = 0;
  for (const auto& v : los) ok += c.p_los(v) >= 0.5;
  for (const auto& v : nlos) ok += c.p_los(v) < 0.5;
  std::cerr << "locus train spyloc: " << los.size() << " LoS + " << nlos.size() << " NLoS beeps (" << unlabelled
            << " unlabelled left out); training accuracy " << (100.0 * ok / std::max<std::size_t>(1, los.size() + nlos.size()))
            << " %; wrote " << o.output << "\n";
  // Held-out scenes: accuracy per class, per scene and pooled (docs/spyloc.md "LoS/NLoS").
  std::size_t t_los = 0, t_los_ok = 0, t_nlos = 0, t_nlos_ok = 0;
  for (const TestSet& t : tests) {
    const auto& tl = t.los;
    const auto& tn = t.nlos;
    std::size_t lo = 0, no = 0;
    for (const auto& v : tl) lo += c.p_los(v) >= 0.5;
    for (const auto& v : tn) no += c.p_los(v) < 0.5;
    std::printf("test %s: LoS %zu/%zu NLoS %zu/%zu accuracy %.1f %%\n", t.dir.c_str(), lo, tl.size(), no, tn.size(),
                100.0 * static_cast<double>(lo + no) / static_cast<double>(std::max<std::size_t>(1, tl.size() + tn.size())));
    t_los += tl.size(), t_los_ok += lo, t_nlos += tn.size(), t_nlos_ok += no;
  }
  if (!o.test_scenes.empty())
    std::printf("test pooled: LoS %zu/%zu (%.1f %%) NLoS %zu/%zu (%.1f %%) accuracy %.1f %%\n", t_los_ok, t_los,
                100.0 * static_cast<double>(t_los_ok) / static_cast<double>(std::max<std::size_t>(1, t_los)), t_nlos_ok, t_nlos,
                100.0 * static_cast<double>(t_nlos_ok) / static_cast<double>(std::max<std::size_t>(1, t_nlos)),
                100.0 * static_cast<double>(t_los_ok + t_nlos_ok) / static_cast<double>(std::max<std::size_t>(1, t_los + t_nlos)));
  return 0;
}

}  // namespace locus::app
