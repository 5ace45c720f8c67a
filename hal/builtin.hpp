// Registers the built-in HAL audio sources.
#pragma once
#include "locus/registry.hpp"
namespace locus::hal {
void register_builtin_sources(Registry& registry);
}
