// EnvAware features and model I/O (see envaware.hpp).
#include "envaware.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

namespace locus::plugins::locble {

namespace {

double quantile(std::vector<double>& v, double q) {  // v sorted; numpy's linear interpolation
  const double k = q * static_cast<double>(v.size() - 1);
  const auto f = static_cast<std::size_t>(std::floor(k));
  const std::size_t c = std::min(f + 1, v.size() - 1);
  return v[f] + (v[c] - v[f]) * (k - static_cast<double>(f));
}

}  // namespace

std::array<double, kEnvFeatures> envaware_features(std::span<const double> rss) {
  if (rss.size() < 2) throw std::invalid_argument("envaware_features: need at least 2 readings in a window");
  const double n = static_cast<double>(rss.size());
  double mean = 0.0;
  for (double r : rss) mean += r;
  mean /= n;
  double m2 = 0.0, m3 = 0.0, m4 = 0.0;
  for (double r : rss) {
    const double d = r - mean;
    m2 += d * d;
    m3 += d * d * d;
    m4 += d * d * d * d;
  }
  m2 /= n;
  m3 /= n;
  m4 /= n;
  const double skew = m2 > 1e-12 ? m3 / std::pow(m2, 1.5) : 0.0;
  const double kurt = m2 > 1e-12 ? m4 / (m2 * m2) - 3.0 : 0.0;
  std::vector<double> v(rss.begin(), rss.end());
  std::sort(v.begin(), v.end());
  return {mean, m2, skew, kurt, v.front(), quantile(v, 0.25), quantile(v, 0.5), quantile(v, 0.75), v.back()};
}

std::optional<int> envaware_class(const std::string& label) {
  std::string l;
  for (char c : label) l.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  if (l == "los") return 0;
  if (l == "plos" || l == "partial" || l == "p-los") return 1;
  if (l == "nlos") return 2;
  return std::nullopt;
}

int EnvAwareModel::predict(const std::array<double, kEnvFeatures>& f) const {
  Eigen::VectorXd x(kEnvFeatures);
  for (int i = 0; i < kEnvFeatures; ++i) x[i] = f[static_cast<std::size_t>(i)];
  return svm.predict(x);
}

EnvAwareModel load_envaware_model(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot read the EnvAware model (no such file?)");
  std::stringstream ss;
  ss << f.rdbuf();
  return parse_envaware_model(ss.str(), path);
}

EnvAwareModel parse_envaware_model(const std::string& text, const std::string& path) {
  YAML::Node y;
  try {
    y = YAML::Load(text);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": cannot read the EnvAware model: " + e.what());
  }
  auto vec = [&](const char* key, std::size_t n) {
    const YAML::Node v = y[key];
    if (!v || !v.IsSequence() || v.size() != n)
      throw std::runtime_error(path + ": '" + key + "' must be a list of " + std::to_string(n) + " numbers");
    Eigen::VectorXd out(static_cast<Eigen::Index>(n));
    for (std::size_t i = 0; i < n; ++i) {
      try {
        out[static_cast<Eigen::Index>(i)] = v[i].as<double>();
      } catch (const std::exception&) {
        throw std::runtime_error(path + ": '" + key + "' item " + std::to_string(i) + " is not a number");
      }
      if (!std::isfinite(out[static_cast<Eigen::Index>(i)]))
        throw std::runtime_error(path + ": '" + key + "' item " + std::to_string(i) + " is not finite");
    }
    return out;
  };
  if (!y["format"] || y["format"].as<std::string>("") != "locble-envaware/1")
    throw std::runtime_error(path + ": 'format' must be locble-envaware/1");
  const YAML::Node classes = y["classes"];
  if (!classes || !classes.IsSequence() || classes.size() != 3)
    throw std::runtime_error(path + ": 'classes' must be [LOS, pLOS, NLOS]");
  for (std::size_t i = 0; i < 3; ++i)
    if (classes[i].as<std::string>("") != kEnvClasses[i])
      throw std::runtime_error(path + ": 'classes' must be [LOS, pLOS, NLOS]");
  EnvAwareModel m;
  m.mean = vec("mean", kEnvFeatures);
  m.scale = vec("scale", kEnvFeatures);
  for (int i = 0; i < kEnvFeatures; ++i)
    if (!(m.scale[i] > 0.0)) throw std::runtime_error(path + ": 'scale' must be > 0 everywhere");
  const YAML::Node w = y["weights"];
  if (!w || !w.IsSequence() || w.size() != 3) throw std::runtime_error(path + ": 'weights' must be 3 lists of 9 numbers");
  Eigen::MatrixXd wm(3, kEnvFeatures);
  for (std::size_t c = 0; c < 3; ++c) {
    if (!w[c].IsSequence() || w[c].size() != kEnvFeatures)
      throw std::runtime_error(path + ": 'weights' row " + std::to_string(c) + " must be a list of 9 numbers");
    for (std::size_t i = 0; i < kEnvFeatures; ++i) {
      try {
        wm(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(i)) = w[c][i].as<double>();
      } catch (const std::exception&) {
        throw std::runtime_error(path + ": 'weights' row " + std::to_string(c) + " item " + std::to_string(i) + " is not a number");
      }
    }
  }
  const Eigen::VectorXd b = vec("bias", 3);
  if (y["window_s"]) {
    m.window_s = y["window_s"].as<double>(0.0);
    if (!(m.window_s > 0.0)) throw std::runtime_error(path + ": 'window_s' must be > 0");
  }
  try {
    m.svm = dsp::LinearSvm(wm, b);
    m.svm.set_standardization(m.mean, m.scale);
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
  return m;
}

std::string envaware_model_yaml(const EnvAwareModel& m, const std::string& comment) {
  std::ostringstream os;
  os << std::setprecision(10);
  std::istringstream cs(comment);
  for (std::string line; std::getline(cs, line);) os << "# " << line << "\n";
  os << "format: locble-envaware/1\nclasses: [LOS, pLOS, NLOS]\n";
  os << "features: [mean, variance, skewness, kurtosis, min, q1, median, q3, max]\n";
  os << "window_s: " << m.window_s << "\n";
  auto row = [&](const Eigen::VectorXd& v) {
    os << "[";
    for (Eigen::Index i = 0; i < v.size(); ++i) os << (i ? ", " : "") << v[i];
    os << "]";
  };
  os << "mean: ";
  row(m.mean);
  os << "\nscale: ";
  row(m.scale);
  os << "\nweights:\n";
  for (Eigen::Index c = 0; c < m.svm.weights().rows(); ++c) {
    os << "  - ";
    row(m.svm.weights().row(c).transpose());
    os << "\n";
  }
  os << "bias: ";
  row(m.svm.bias());
  os << "\n";
  return os.str();
}

}  // namespace locus::plugins::locble
