// The built-in plugins, by name. Each plugin folder exposes its descriptor; adding a plugin means
// adding one line here.
#include "../hal/builtin.hpp"
#include "locus/registry.hpp"
#include "onset/onset.hpp"

namespace locus {

void register_builtins(Registry& registry) {
  hal::register_builtin_sources(registry);
  registry.add_plugin(onset_descriptor());
}

}  // namespace locus
