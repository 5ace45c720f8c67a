// `locble`: find BLE tags by walking an L (paper 003, LocBLE). The observer's phone hears the tags'
// advertisements while its owner walks a few steps, turns, and walks on; from the RSS along the
// dead-reckoned path (steps + heading from the motion detectors) each tag is placed in the observer's
// start frame, with a calibrated std, a confidence and guidance (bearing and distance from where the
// observer is now). Maths in solver.hpp, link message (moving targets) in messages.hpp, docs/locble.md.
#pragma once

#include "locus/params.hpp"
#include "locus/plugin.hpp"

namespace locus::plugins::locble {

/// The plugin's descriptor; plugins/CMakeLists.txt (LOCUS_BUILTIN_PLUGINS) registers it.
const locus_plugin_descriptor* descriptor();
/// Its parameters: key, type, default, range, unit, doc (`locus plugins` prints them).
const ParamSchema& schema();

}  // namespace locus::plugins::locble
