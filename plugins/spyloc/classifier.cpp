// SpyLoc LoS/NLoS naive Bayes with per-feature 1-D GMMs: EM, model file I/O. See classifier.hpp.
#include "classifier.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <sstream>
#include <cstring>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace locus::plugins::spyloc {

namespace {
constexpr double kSdFloor_s = 0.0015;  // 1.5 ms: below the detector's envelope smoothing resolution
double log_sum_exp(double a, double b) {
  if (a == -std::numeric_limits<double>::infinity()) return b;
  if (b == -std::numeric_limits<double>::infinity()) return a;
  const double m = std::max(a, b);
  return m + std::log(std::exp(a - m) + std::exp(b - m));
}
}  // namespace

double Mixture1d::log_pdf(double x) const noexcept {
  double acc = -std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < w.size(); ++k) {
    const double z = (x - mu[k]) / sd[k];
    acc = log_sum_exp(acc, std::log(w[k]) - 0.5 * z * z - std::log(sd[k] * std::sqrt(2.0 * std::numbers::pi)));
  }
  return acc;
}

Mixture1d fit_mixture_1d(const std::vector<double>& x, int components, double sd_floor) {
  if (components < 1) throw std::invalid_argument("fit_mixture_1d: components must be >= 1");
  if (x.size() < static_cast<std::size_t>(2 * components))
    throw std::invalid_argument("fit_mixture_1d: " + std::to_string(x.size()) + " samples for " +
                                std::to_string(components) + " components (need at least twice as many)");
  std::vector<double> s = x;
  std::sort(s.begin(), s.end());
  const std::size_t n = s.size();
  const auto K = static_cast<std::size_t>(components);
  Mixture1d m;
  double var_all = 0.0, mean_all = 0.0;
  for (double v : s) mean_all += v;
  mean_all /= static_cast<double>(n);
  for (double v : s) var_all += (v - mean_all) * (v - mean_all);
  var_all /= static_cast<double>(n);
  for (std::size_t k = 0; k < K; ++k) {  // initial means at the quantiles (k + 0.5) / K
    m.w.push_back(1.0 / static_cast<double>(K));
    m.mu.push_back(s[std::min(n - 1, static_cast<std::size_t>((static_cast<double>(k) + 0.5) / static_cast<double>(K) * static_cast<double>(n)))]);
    m.sd.push_back(std::max(sd_floor, std::sqrt(var_all) / static_cast<double>(K)));
  }
  std::vector<double> r(n * K);
  double prev = -std::numeric_limits<double>::infinity();
  for (int it = 0; it < 300; ++it) {
    double ll = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      double tot = -std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < K; ++k) {
        const double z = (x[i] - m.mu[k]) / m.sd[k];
        r[i * K + k] = std::log(m.w[k]) - 0.5 * z * z - std::log(m.sd[k]);
        tot = log_sum_exp(tot, r[i * K + k]);
      }
      for (std::size_t k = 0; k < K; ++k) r[i * K + k] = std::exp(r[i * K + k] - tot);
      ll += tot;
    }
    for (std::size_t k = 0; k < K; ++k) {
      double nk = 0.0, sx = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        nk += r[i * K + k];
        sx += r[i * K + k] * x[i];
      }
      if (nk < 1e-9) {  // an empty component: park it on the data mean with the full spread
        m.w[k] = 1e-6;
        m.mu[k] = mean_all;
        m.sd[k] = std::max(sd_floor, std::sqrt(var_all));
        continue;
      }
      const double mu = sx / nk;
      double sv = 0.0;
      for (std::size_t i = 0; i < n; ++i) sv += r[i * K + k] * (x[i] - mu) * (x[i] - mu);
      m.w[k] = nk / static_cast<double>(n);
      m.mu[k] = mu;
      m.sd[k] = std::max(sd_floor, std::sqrt(sv / nk));
    }
    double ws = 0.0;
    for (double w : m.w) ws += w;
    for (double& w : m.w) w /= ws;
    if (ll - prev < 1e-9 * static_cast<double>(n)) break;
    prev = ll;
  }
  return m;
}

double LosClassifier::censor(float v) const noexcept {
  return std::isfinite(v) ? std::min(static_cast<double>(v), censor_s_) : censor_s_;
}

void LosClassifier::train(const std::vector<DecayVector>& los, const std::vector<DecayVector>& nlos, int components,
                          double censor_s) {
  for (int cls = 0; cls < 2; ++cls) {  // checked first: a refused training leaves the model as it was
    const auto& data = cls == 0 ? los : nlos;
    if (data.size() < static_cast<std::size_t>(2 * components))
      throw std::invalid_argument(std::string("spyloc classifier: ") + (cls == 0 ? "LoS" : "NLoS") + " class has " +
                                  std::to_string(data.size()) + " labelled beeps; at least " +
                                  std::to_string(2 * components) + " are needed");
  }
  censor_s_ = censor_s;
  los_.clear();
  nlos_.clear();
  for (int cls = 0; cls < 2; ++cls) {
    const auto& data = cls == 0 ? los : nlos;
    if (data.size() < static_cast<std::size_t>(2 * components))
      throw std::invalid_argument(std::string("spyloc classifier: ") + (cls == 0 ? "LoS" : "NLoS") + " class has " +
                                  std::to_string(data.size()) + " labelled beeps; at least " +
                                  std::to_string(2 * components) + " are needed");
    for (std::size_t f = 0; f < kDecayFeatures; ++f) {
      std::vector<double> x;
      for (const DecayVector& v : data) x.push_back(censor(v[f]));
      (cls == 0 ? los_ : nlos_).push_back(fit_mixture_1d(x, components, kSdFloor_s));
    }
  }
  n_los_ = los.size();
  n_nlos_ = nlos.size();
  prior_los_ = static_cast<double>(n_los_) / static_cast<double>(n_los_ + n_nlos_);
}

double fuse_los(double p_los_decay, double innovation_m, double innovation_std_m, double nlos_excess_max_m) noexcept {
  const double p = std::clamp(p_los_decay, 1e-9, 1.0 - 1e-9);
  if (!(nlos_excess_max_m > 0.0) || !(innovation_std_m > 0.0) || !std::isfinite(innovation_m) ||
      !std::isfinite(p_los_decay))
    return p_los_decay;
  const double z = innovation_m / innovation_std_m;
  const double l_los = std::exp(-0.5 * z * z) / (innovation_std_m * std::sqrt(2.0 * std::numbers::pi));
  // ∫ U(e; 0, E) N(ν − e; 0, σ²) de = (Φ(ν/σ) − Φ((ν − E)/σ)) / E
  auto Phi = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
  const double l_nlos = (Phi(z) - Phi((innovation_m - nlos_excess_max_m) / innovation_std_m)) / nlos_excess_max_m;
  const double num = p * l_los, den = num + (1.0 - p) * l_nlos;
  if (!(den > 0.0) || !std::isfinite(den)) return p_los_decay;
  return num / den;
}

double temper_los(double p, double scale) noexcept {
  if (scale == 1.0 || !std::isfinite(p)) return p;
  const double q = std::clamp(p, 1e-300, 1.0 - 1e-16);
  const double log_odds = scale * std::log(q / (1.0 - q));
  return 1.0 / (1.0 + std::exp(-std::clamp(log_odds, -700.0, 700.0)));
}

double LosClassifier::p_los(const DecayVector& f) const noexcept {
  if (!ready()) return 0.5;
  double a = std::log(prior_los_), b = std::log(1.0 - prior_los_);
  for (std::size_t i = 0; i < kDecayFeatures; ++i) {
    const double x = censor(f[i]);
    a += los_[i].log_pdf(x);
    b += nlos_[i].log_pdf(x);
  }
  const double d = std::clamp(b - a, -700.0, 700.0);
  return 1.0 / (1.0 + std::exp(d));
}

void LosClassifier::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("spyloc: los_model '" + path + "': cannot read (" + std::strerror(errno) + ")");
  std::stringstream text;
  text << in.rdbuf();
  load_text(text.str(), path);
}

void LosClassifier::load_text(const std::string& text, const std::string& path) {
  const LosClassifier before = *this;  // a refused file leaves the model as it was
  try {
    parse(text, path);
  } catch (...) {
    *this = before;
    throw;
  }
}

void LosClassifier::parse(const std::string& text, const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const std::exception& e) {
    throw std::runtime_error("spyloc: los_model '" + path + "': not YAML (" + e.what() + ")");
  }
  auto fail = [&](const std::string& field, const std::string& what) {
    throw std::runtime_error("spyloc: los_model '" + path + "': field '" + field + "': " + what);
  };
  if (!root.IsMap()) fail("(top)", "expected a mapping");
  if (!root["format"] || root["format"].as<std::string>("") != "locus-spyloc-los/1")
    fail("format", "expected 'locus-spyloc-los/1'");
  try {
    censor_s_ = root["censor_s"].as<double>();
  } catch (...) {
    fail("censor_s", "expected a number of seconds");
  }
  if (!(censor_s_ > 0.0)) fail("censor_s", "must be > 0");
  try {
    prior_los_ = root["prior_los"].as<double>();
  } catch (...) {
    fail("prior_los", "expected a number");
  }
  if (!(prior_los_ > 0.0 && prior_los_ < 1.0)) fail("prior_los", "must be in (0, 1)");
  for (int cls = 0; cls < 2; ++cls) {
    const std::string key = cls == 0 ? "los" : "nlos";
    const YAML::Node list = root[key];
    if (!list || !list.IsSequence() || list.size() != kDecayFeatures)
      fail(key, "expected a list of " + std::to_string(kDecayFeatures) + " mixtures (T5..T30)");
    std::vector<Mixture1d> out;
    for (std::size_t f = 0; f < kDecayFeatures; ++f) {
      const std::string fk = key + "[" + std::to_string(f) + "]";
      Mixture1d m;
      try {
        m.w = list[f]["w"].as<std::vector<double>>();
        m.mu = list[f]["mu"].as<std::vector<double>>();
        m.sd = list[f]["sd"].as<std::vector<double>>();
      } catch (...) {
        fail(fk, "expected {w: [...], mu: [...], sd: [...]} lists of numbers");
      }
      if (m.w.empty() || m.w.size() != m.mu.size() || m.w.size() != m.sd.size()) fail(fk, "w, mu and sd must have the same non-zero length");
      double ws = 0.0;
      for (std::size_t k = 0; k < m.w.size(); ++k) {
        if (!(m.w[k] > 0.0) || !(m.sd[k] > 0.0) || !std::isfinite(m.mu[k])) fail(fk, "weights and sd must be > 0, means finite");
        ws += m.w[k];
      }
      if (std::fabs(ws - 1.0) > 1e-3) fail(fk + ".w", "weights must sum to 1 (got " + std::to_string(ws) + ")");
      out.push_back(std::move(m));
    }
    (cls == 0 ? los_ : nlos_) = std::move(out);
  }
  if (const YAML::Node t = root["trained_on"]) {
    if (!t.IsMap()) fail("trained_on", "expected a mapping {los: N, nlos: N, note: ...}");
    n_los_ = t["los"].as<std::size_t>(0);
    n_nlos_ = t["nlos"].as<std::size_t>(0);
  }
}

void LosClassifier::save(const std::string& path, const std::string& note) const {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("spyloc: cannot write '" + path + "'");
  f.precision(9);
  f << "# SpyLoc LoS/NLoS model: naive Bayes, per feature (T5..T30) a 1-D GMM per class (plugins/spyloc/classifier.hpp)\n";
  f << "format: locus-spyloc-los/1\ncensor_s: " << censor_s_ << "\nprior_los: " << prior_los_ << "\n";
  f << "trained_on: {los: " << n_los_ << ", nlos: " << n_nlos_ << ", note: \"" << note << "\"}\n";
  for (int cls = 0; cls < 2; ++cls) {
    f << (cls == 0 ? "los:\n" : "nlos:\n");
    for (const Mixture1d& m : cls == 0 ? los_ : nlos_) {
      auto list = [&](const std::vector<double>& v) {
        f << "[";
        for (std::size_t i = 0; i < v.size(); ++i) f << (i ? ", " : "") << v[i];
        f << "]";
      };
      f << "  - {w: ";
      list(m.w);
      f << ", mu: ";
      list(m.mu);
      f << ", sd: ";
      list(m.sd);
      f << "}\n";
    }
  }
  if (!f) throw std::runtime_error("spyloc: error writing '" + path + "'");
}

// Generated from config/spyloc-los.yaml (plugins/CMakeLists.txt, locus_embed_text).
const std::string& builtin_los_model_yaml();

const std::string& LosClassifier::builtin_text() { return builtin_los_model_yaml(); }

}  // namespace locus::plugins::spyloc
