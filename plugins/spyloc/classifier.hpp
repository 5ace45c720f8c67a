// SpyLoc LoS/NLoS classifier (paper 001, §V-B): naive Bayes over the reverberation-decay features
// T5..T30 (`decay_features` events of the multitone detector), each feature's class-conditional
// density a 1-D Gaussian mixture of m components fitted by EM (paper: m = 4).
//
// Why naive Bayes with 1-D mixtures: the paper's choice; the features are strongly correlated, but
// each one's class-conditional shape is far from Gaussian (an LoS beep's T10 is a few ms, an NLoS
// beep's tens of ms, with a mass at "not reached"), which a per-feature mixture captures with few
// parameters from a few hundred labelled beeps.
// A feature that was not reached inside the detector's window (NaN) is censored to `censor_s`
// (the value is "at least the window"): the mixtures learn that mass like any other value.
// Model file (YAML, `locus train spyloc ... -o FILE`):
//   format: locus-spyloc-los/1
//   censor_s: 0.2
//   prior_los: 0.78            # class prior from the training labels
//   trained_on: {los: N, nlos: M, scenes: [...]}
//   los:  [{w: [...], mu: [...], sd: [...]}, ... one per feature T5..T30]
//   nlos: [...]
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace locus::plugins::spyloc {

inline constexpr std::size_t kDecayFeatures = 6;  // T5, T10, ..., T30
using DecayVector = std::array<float, kDecayFeatures>;

/// One 1-D Gaussian mixture.
struct Mixture1d {
  std::vector<double> w, mu, sd;
  double log_pdf(double x) const noexcept;  ///< [RT-safe: no allocation]
};

class LosClassifier {
 public:
  /// [main] Fits both classes from labelled feature vectors (EM, `components` per feature, fixed
  /// seedless initialisation at quantiles: deterministic). Throws std::invalid_argument when a class
  /// has fewer than 2·components samples.
  void train(const std::vector<DecayVector>& los, const std::vector<DecayVector>& nlos, int components = 4,
             double censor_s = 0.2);
  /// [main] Reads a model file; throws std::runtime_error naming the file and field on any problem.
  void load(const std::string& path);
  /// [main] The same from the file's text; `name` names it in errors. A refused file leaves the
  /// model as it was (as does a refused train()).
  void load_text(const std::string& text, const std::string& name);
  /// [main] The shipped model (config/spyloc-los.yaml as built): what `los_model: builtin` loads.
  static const std::string& builtin_text();
  /// [main] Writes the model (YAML); `note` goes into trained_on.
  void save(const std::string& path, const std::string& note) const;
  bool ready() const noexcept { return !los_.empty(); }
  /// Posterior probability of LoS for one beep's features. [main]
  double p_los(const DecayVector& f) const noexcept;
  double censor_s() const noexcept { return censor_s_; }
  std::size_t trained_los() const noexcept { return n_los_; }
  std::size_t trained_nlos() const noexcept { return n_nlos_; }

 private:
  void parse(const std::string& text, const std::string& name);
  double censor(float v) const noexcept;
  std::vector<Mixture1d> los_, nlos_;
  double prior_los_ = 0.5;
  double censor_s_ = 0.2;
  std::size_t n_los_ = 0, n_nlos_ = 0;
};

/// P(LoS) of a ranged beep from its decay verdict and from what a track predicts for its range (the
/// localizer's verdict, docs/spyloc.md "LoS/NLoS verdict"): the classifier's P(LoS) as the prior, times
/// the likelihood of the range's innovation ν = measured − predicted under each class. LoS: ν ~ N(0, σ²).
/// NLoS: the detector times a diffracted or reflected path, never shorter than the direct one, so
/// ν = e + N(0, σ²) with the excess path e ~ U(0, nlos_excess_max_m). σ = the innovation's std (track
/// and range). A range far SHORTER than predicted is unlikely under both (the track is what is wrong):
/// where both likelihoods vanish the classifier's P(LoS) is returned unchanged, as it is for
/// nlos_excess_max_m <= 0 or a non-finite input. [RT-safe: no allocation]
double fuse_los(double p_los_decay, double innovation_m, double innovation_std_m, double nlos_excess_max_m) noexcept;

/// P(LoS) with its log-odds scaled by `scale` (0 < scale <= 1): the classifier multiplies six
/// correlated decay times as if independent, so its odds are overstated (a burst over a beep's tail
/// drives a LoS beep's to 1e-4 and below, beyond what a range's innovation can answer). scale 1
/// returns p.
/// [RT-safe]
double temper_los(double p, double scale) noexcept;

/// [main] EM for a 1-D mixture (exposed for the tests).
Mixture1d fit_mixture_1d(const std::vector<double>& x, int components, double sd_floor);

}  // namespace locus::plugins::spyloc
