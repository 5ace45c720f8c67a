// The built-in plugins, by name. Each plugin folder exposes its descriptor; adding a plugin means
// adding one line here.
#include "../hal/builtin.hpp"
#include "links.hpp"
#include "locus/registry.hpp"
#include "chirp/chirp.hpp"
#include "goldcode/goldcode.hpp"
#include "multitone/multitone.hpp"
#include "onset/onset.hpp"
#include "attitude/attitude.hpp"
#include "steps/steps.hpp"
#include "turns/turns.hpp"
#include "ble_rss/ble_rss.hpp"
#include "amil/amil.hpp"

namespace locus {

void register_builtins(Registry& registry) {
  hal::register_builtin_sources(registry);
  links::register_builtin_links(registry);
  registry.add_plugin(onset_descriptor());
  registry.add_plugin(chirp_descriptor());
  registry.add_plugin(goldcode_descriptor());
  registry.add_plugin(multitone_descriptor());
  registry.add_plugin(attitude_descriptor());
  registry.add_plugin(steps_descriptor());
  registry.add_plugin(turns_descriptor());
  registry.add_plugin(ble_rss_descriptor());
  registry.add_plugin(amil_descriptor());
}

}  // namespace locus
