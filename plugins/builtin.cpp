// The built-ins the host registers: HAL sources, links and the plugins. The plugin list is
// LOCUS_BUILTIN_PLUGINS in plugins/CMakeLists.txt (one line per plugin folder), from which CMake
// generates builtin_plugin_descriptors() (builtin_plugins.cpp in the build tree); adding a plugin never
// touches this file.
#include <vector>

#include "../hal/builtin.hpp"
#include "links.hpp"
#include "locus/registry.hpp"

namespace locus {

/// Every plugin of LOCUS_BUILTIN_PLUGINS, in its order (generated).
const std::vector<const locus_plugin_descriptor*>& builtin_plugin_descriptors();

void register_builtins(Registry& registry) {
  hal::register_builtin_sources(registry);
  links::register_builtin_links(registry);
  for (const locus_plugin_descriptor* d : builtin_plugin_descriptors()) registry.add_plugin(d);
}

}  // namespace locus
