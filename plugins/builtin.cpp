// The built-in plugins, by name. Each plugin folder exposes its descriptor; adding a plugin means
// adding one line here.
#include "../hal/builtin.hpp"
#include "locus/registry.hpp"
#include "chirp/chirp.hpp"
#include "goldcode/goldcode.hpp"
#include "multitone/multitone.hpp"
#include "onset/onset.hpp"
#include "attitude/attitude.hpp"
#include "steps/steps.hpp"
#include "turns/turns.hpp"
#include "ble_rss/ble_rss.hpp"

namespace locus {

void register_builtins(Registry& registry) {
  hal::register_builtin_sources(registry);
  registry.add_plugin(onset_descriptor());
  registry.add_plugin(chirp_descriptor());
  registry.add_plugin(goldcode_descriptor());
  registry.add_plugin(multitone_descriptor());
  registry.add_plugin(attitude_descriptor());
  registry.add_plugin(steps_descriptor());
  registry.add_plugin(turns_descriptor());
  registry.add_plugin(ble_rss_descriptor());
}

}  // namespace locus
