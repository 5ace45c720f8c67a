// Host side of locus/signal.hpp: the signal parser and writer on yaml-cpp nodes, for readers and
// writers of larger YAML documents (scene.yaml) that hold signals. Implemented in liblocus next to
// parse_signal (one parser); NOT installed with the plugin API (it exposes yaml-cpp).
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "locus/signal.hpp"

namespace locus {

/// Parses the signal object at `node` (a mapping). Appends every issue to `issues`, each with its
/// field named `where`.<key> (`where` alone for the object) and the node's line and column; the
/// returned spec holds every field that was valid.
SignalSpec parse_signal_node(const YAML::Node& node, const std::string& where, std::vector<SignalIssue>& issues);

/// Writes `spec` as one flow mapping (every field of its type, numbers in their shortest round-trip
/// form): the YAML twin of signal_to_json, same keys, same order.
void emit_signal_yaml(YAML::Emitter& out, const SignalSpec& spec);

}  // namespace locus
