// EnvAware (paper 003, Sec. 4): the propagation class of a tag's link — LOS, partial LOS (people,
// glass, wood) or NLOS (walls) — from its RSS alone, so that the regression restarts when the class
// changes. Features over a 2 s window of raw RSS: mean, variance, skewness, kurtosis (the issue's
// ninth; the paper lists eight), minimum, first quartile, median, third quartile, maximum; standardised
// and classified by a linear SVM (one-vs-rest). The model is trained by `locus train locble` from
// labelled scenes and stored as YAML (config/locble-envaware.yaml).
//
// Why a file of its own: the features and the model format are shared by the plugin (inference) and
// the `train` tool (training, accuracy per class), and must not drift apart.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "locus/dsp/svm.hpp"

namespace locus::plugins::locble {

inline constexpr int kEnvFeatures = 9;
inline constexpr std::array<const char*, 3> kEnvClasses = {"LOS", "pLOS", "NLOS"};

/// [main] The 9 features of one window (at least 2 readings; std::invalid_argument otherwise).
std::array<double, kEnvFeatures> envaware_features(std::span<const double> rss_dbm);

/// Class index of a label ("LOS", "pLOS"/"partial"/"PLOS", "NLOS", any case); nullopt otherwise.
std::optional<int> envaware_class(const std::string& label);

struct EnvAwareModel {
  dsp::LinearSvm svm{Eigen::MatrixXd::Zero(3, kEnvFeatures), Eigen::VectorXd::Zero(3)};
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(kEnvFeatures), scale = Eigen::VectorXd::Ones(kEnvFeatures);
  double window_s = 2.0;
  int predict(const std::array<double, kEnvFeatures>& f) const;
};

/// [main] Reads a model file; throws std::runtime_error naming the file and the field that is missing
/// or malformed (and what was expected).
EnvAwareModel load_envaware_model(const std::string& path);
/// [main] The same from YAML text; `origin` names it in errors.
EnvAwareModel parse_envaware_model(const std::string& text, const std::string& origin);
/// The shipped model (config/locble-envaware.yaml, compiled in by plugins/CMakeLists.txt).
const std::string& builtin_envaware_yaml();
/// [main] The model as YAML text (what load_envaware_model reads).
std::string envaware_model_yaml(const EnvAwareModel& m, const std::string& comment);

}  // namespace locus::plugins::locble
