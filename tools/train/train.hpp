// `locus train SYSTEM`: training a localizer's models from labelled scenes.
//   spyloc  the LoS/NLoS classifier (run_train_spyloc, train.cpp);
//   locble  the EnvAware LOS/pLOS/NLOS linear SVM (train_locble, train_locble.cpp; docs/locble.md).
//
// SpyLoc: // Why through the replay pipeline: the classifier must learn the features exactly as the detector
// produces them at run time (same detector, same parameters: the multitone detector with
// `from_scene: true` plus any --detector-params), so each scene is replayed with a detector-only
// config into a temporary JSON-lines file of audio_detection + decay_features events.
// Labels, per detected beep (its identity names the beacon):
//   * truth-extra.yaml `beeps` (the independent reference generator): the beep of that beacon whose
//     first arrival (arrival_first_local_sample, on the walker's audio) is within 30 ms; label LOS/NLOS;
//   * truth_los.csv (locus simulate spyloc): the emission of that beacon whose true start lies in the
//     0-120 ms before the detection's true time (scene truth clocks); los 1/0.
// Beeps with no label (false detections, wrong identity) are left out and counted.
#pragma once

#include <string>
#include <vector>

namespace locus::app {

struct SpyLocTrainOptions {
  std::vector<std::string> scenes;
  std::vector<std::string> test_scenes;  ///< held out: accuracy per class printed on stdout after training
  std::string output;
  int components = 4;
  std::string detector_params;  ///< extra multitone params, YAML flow mapping text ("" = none)
};

/// Exit status: 0 written; 2 bad input (message on stderr); 1 failure.
int run_train_spyloc(const SpyLocTrainOptions& options);

struct LocBleTrainOptions {
  std::vector<std::string> scenes, test_scenes;
  std::string output;
  double window_s = 2.0;
  int epochs = 200;
  double lambda = 1e-3;
  unsigned long long seed = 1;
};

/// locble: EnvAware from scenes with per-reading labels (truth_ble_env.csv of `locus simulate locble`,
/// or truth-extra.yaml ble_rows of the foreign generator). Returns the exit status.
int train_locble(const LocBleTrainOptions& opt);

}  // namespace locus::app
