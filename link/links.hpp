// Registers the built-in links between nodes and the network event outputs (MQTT).
#pragma once
#include "locus/registry.hpp"
namespace locus::links {
/// Adds link "mqtt" and output "mqtt" (link/mqtt). The in-process link needs no registration: it is
/// what a node uses when its config has no `link:` section. Without MQTT support (LOCUS_WITH_MQTT),
/// registers "mqtt" as not built in (Registry::add_not_built) instead.
void register_builtin_links(Registry& registry);
}  // namespace locus::links
