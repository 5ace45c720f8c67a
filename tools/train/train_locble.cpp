// `locus train locble`: the EnvAware classifier (paper 003 Sec. 4) from labelled scenes.
//
// Labels per BLE reading: `truth_ble_env.csv` (t_true, tag, env every 0.1 s: `locus simulate
// locble`; the label of a reading is the row nearest its true time) or the foreign generator's
// `truth-extra.yaml` `ble_rows` (one row per ble.csv row, same order, with its env). A scene with
// neither is refused (it cannot teach anything). Each tag's readings are cut into windows of
// window_s; a window with at least 4 readings gives the 9 features (plugins/locble/envaware.hpp) and
// the majority label. Features are standardised over the training windows; classes are balanced by
// repeating the rarer ones; the linear SVM (one-vs-rest) is trained by Pegasos (locus/dsp/svm.hpp).
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "locble/envaware.hpp"
#include "locble/messages.hpp"
#include "locus/dsp/svm.hpp"
#include "locus/scene/ble_csv.hpp"
#include "locus/scene/csv.hpp"
#include "locus/scene/scene.hpp"
#include "train/train.hpp"
#include "app.hpp"

namespace locus::app {

namespace lb = locus::plugins::locble;

namespace {

struct Window {
  std::array<double, lb::kEnvFeatures> f{};
  int label = 0;
};

struct Reading {
  double t_local = 0.0;
  std::string address;
  double rssi = 0.0;
  int label = -1;
};

std::vector<Window> scene_windows(const std::string& dir, double window_s) {
  const scene::Scene sc = scene::load_scene(dir);
  std::map<std::string, std::string> tag_of;  // address -> emitter/device id
  for (const auto& e : sc.emitters)
    for (const auto& s : e.emits)
      if (s.type == "ble") tag_of[lb::format_address(*lb::parse_address(s.address))] = e.id;
  std::vector<Window> out;
  for (const auto& d : sc.devices) {
    if (d.ble.empty()) continue;
    std::vector<Reading> rs;
    scene::BleCsvReader reader(sc.path(d.ble), DeviceId(d.id));
    BleAdvertisement a;
    while (reader.next(a)) rs.push_back({a.t_s, lb::format_address(a.address), a.rssi_dbm, -1});
    const std::string sim_labels = dir + "/truth_ble_env.csv", extra = dir + "/truth-extra.yaml";
    if (std::ifstream(sim_labels).good()) {
      scene::ClockTruth clk;
      if (sc.truth && sc.truth->clocks.count(d.id)) clk = sc.truth->clocks.at(d.id);
      std::map<std::string, std::vector<std::pair<double, int>>> table;  // tag -> (t_true, class)
      std::ifstream f(sim_labels);
      std::string line;
      int ln = 0;
      while (std::getline(f, line)) {
        ++ln;
        if (ln == 1) {
          if (line != "t_true,tag,env") throw std::runtime_error(sim_labels + ":1: expected the header t_true,tag,env");
          continue;
        }
        std::istringstream ls(line);
        std::string t, tag, env;
        if (!std::getline(ls, t, ',') || !std::getline(ls, tag, ',') || !std::getline(ls, env))
          throw std::runtime_error(sim_labels + ":" + std::to_string(ln) + ": expected t_true,tag,env");
        const auto c = lb::envaware_class(env);
        if (!c) throw std::runtime_error(sim_labels + ":" + std::to_string(ln) + ": env '" + env + "' is not LOS, pLOS or NLOS");
        table[tag].emplace_back(std::stod(t), *c);
      }
      for (Reading& r : rs) {
        const auto it = tag_of.find(r.address);
        if (it == tag_of.end() || !table.count(it->second)) continue;
        const auto& v = table.at(it->second);
        const double tt = clk.true_from_local(r.t_local);
        const auto p = std::lower_bound(v.begin(), v.end(), tt, [](const auto& e, double x) { return e.first < x; });
        const auto& near = (p == v.end()) ? v.back() : (p != v.begin() && tt - (p - 1)->first < p->first - tt ? *(p - 1) : *p);
        r.label = near.second;
      }
    } else if (std::ifstream(extra).good()) {
      const YAML::Node y = YAML::LoadFile(extra);
      const YAML::Node rows = y["ble_rows"]["rows"];
      if (!rows || !rows.IsSequence() || rows.size() != rs.size())
        throw std::runtime_error(extra + ": ble_rows.rows must have one row per " + d.ble + " row (" + std::to_string(rs.size()) + ")");
      for (std::size_t i = 0; i < rs.size(); ++i) {
        const auto c = lb::envaware_class(rows[i][3].as<std::string>(""));
        if (!c) throw std::runtime_error(extra + ": ble_rows.rows[" + std::to_string(i) + "][3] is not LOS, pLOS or NLOS");
        rs[i].label = *c;
      }
    } else {
      throw std::runtime_error(dir + ": no labels (truth_ble_env.csv or truth-extra.yaml with ble_rows)");
    }
    std::map<std::string, std::vector<const Reading*>> by_tag;
    for (const Reading& r : rs)
      if (r.label >= 0) by_tag[r.address].push_back(&r);
    for (const auto& [addr, v] : by_tag) {
      std::size_t i = 0;
      while (i < v.size()) {
        const double t0 = v[i]->t_local;
        std::vector<double> x;
        int votes[3] = {0, 0, 0};
        std::size_t j = i;
        for (; j < v.size() && v[j]->t_local < t0 + window_s; ++j) {
          x.push_back(v[j]->rssi);
          ++votes[v[j]->label];
        }
        if (x.size() >= 4) {
          Window w;
          w.f = lb::envaware_features(x);
          w.label = static_cast<int>(std::max_element(votes, votes + 3) - votes);
          out.push_back(w);
        }
        i = j;
      }
    }
  }
  return out;
}

std::string report(const lb::EnvAwareModel& m, const std::vector<Window>& ws) {
  int conf[3][3] = {};
  for (const Window& w : ws) ++conf[w.label][m.predict(w.f)];
  std::ostringstream os;
  os << std::fixed << std::setprecision(1);
  int right = 0;
  for (int c = 0; c < 3; ++c) {
    int truth = 0, pred = 0;
    for (int k = 0; k < 3; ++k) {
      truth += conf[c][k];
      pred += conf[k][c];
    }
    right += conf[c][c];
    os << "  " << lb::kEnvClasses[static_cast<std::size_t>(c)] << ": windows " << truth << ", recall "
       << (truth ? 100.0 * conf[c][c] / truth : NAN) << " %, precision " << (pred ? 100.0 * conf[c][c] / pred : NAN) << " %\n";
  }
  os << "  accuracy " << (ws.empty() ? NAN : 100.0 * right / static_cast<double>(ws.size())) << " % over " << ws.size()
     << " windows\n";
  return os.str();
}

}  // namespace

int train_locble(const LocBleTrainOptions& opt) {
  try {
    if (!(opt.window_s > 0.0)) throw std::runtime_error("--window-s must be > 0");
    std::vector<Window> train;
    for (const auto& s : opt.scenes) {
      auto w = scene_windows(s, opt.window_s);
      train.insert(train.end(), w.begin(), w.end());
    }
    int count[3] = {0, 0, 0};
    for (const Window& w : train) ++count[w.label];
    if (train.empty() || *std::min_element(count, count + 3) == 0)
      throw std::runtime_error("training windows per class LOS/pLOS/NLOS: " + std::to_string(count[0]) + "/" +
                               std::to_string(count[1]) + "/" + std::to_string(count[2]) + " (every class needs some)");
    lb::EnvAwareModel m;
    m.window_s = opt.window_s;
    const auto n = static_cast<Eigen::Index>(train.size());
    Eigen::MatrixXd x(n, lb::kEnvFeatures);
    for (Eigen::Index i = 0; i < n; ++i)
      for (int k = 0; k < lb::kEnvFeatures; ++k) x(i, k) = train[static_cast<std::size_t>(i)].f[static_cast<std::size_t>(k)];
    m.mean = x.colwise().mean().transpose();
    m.scale = ((x.rowwise() - m.mean.transpose()).array().square().colwise().mean().sqrt()).transpose();
    for (int k = 0; k < lb::kEnvFeatures; ++k)
      if (!(m.scale[k] > 1e-9)) m.scale[k] = 1.0;
    // Balanced: every class repeated up to the largest class's count.
    const int most = *std::max_element(count, count + 3);
    std::vector<Eigen::Index> rows;
    for (int c = 0; c < 3; ++c) {
      std::vector<Eigen::Index> of;
      for (Eigen::Index i = 0; i < n; ++i)
        if (train[static_cast<std::size_t>(i)].label == c) of.push_back(i);
      for (int k = 0; k < most; ++k) rows.push_back(of[static_cast<std::size_t>(k) % of.size()]);
    }
    Eigen::MatrixXd xs(static_cast<Eigen::Index>(rows.size()), lb::kEnvFeatures);
    Eigen::VectorXi ys(static_cast<Eigen::Index>(rows.size()));
    for (std::size_t r = 0; r < rows.size(); ++r) {
      xs.row(static_cast<Eigen::Index>(r)) = ((x.row(rows[r]).transpose() - m.mean).array() / m.scale.array()).transpose();
      ys[static_cast<Eigen::Index>(r)] = train[static_cast<std::size_t>(rows[r])].label;
    }
    dsp::PegasosOptions po;
    po.epochs = opt.epochs;
    po.lambda = opt.lambda;
    po.seed = opt.seed;
    m.svm = dsp::train_linear_svm(xs, ys, 3, po);
    m.svm.set_standardization(m.mean, m.scale);
    std::ostringstream comment;
    comment << "EnvAware (paper 003 Sec. 4): linear SVM LOS/pLOS/NLOS, written by `locus train locble`\n"
            << "from " << opt.scenes.size() << " scenes, " << train.size() << " windows of " << opt.window_s
            << " s (LOS/pLOS/NLOS " << count[0] << "/" << count[1] << "/" << count[2] << ")";
    std::ofstream f(opt.output);
    if (!f) throw std::runtime_error("cannot write " + opt.output);
    f << lb::envaware_model_yaml(m, comment.str());
    if (!f) throw std::runtime_error("cannot write " + opt.output);
    std::cout << "training (" << opt.scenes.size() << " scenes):\n" << report(m, train);
    if (!opt.test_scenes.empty()) {
      std::vector<Window> test;
      for (const auto& s : opt.test_scenes) {
        auto w = scene_windows(s, opt.window_s);
        test.insert(test.end(), w.begin(), w.end());
      }
      std::cout << "held out (" << opt.test_scenes.size() << " scenes):\n" << report(m, test);
    }
    std::cout << "wrote " << opt.output << "\n";
    return kExitOk;
  } catch (const std::exception& e) {
    std::cerr << "locus train locble: " << e.what() << "\n";
    return kExitBadConfig;
  }
}

}  // namespace locus::app
