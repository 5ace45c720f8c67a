#include "builtin.hpp"

namespace locus::hal {

void register_builtin_sources(Registry& /*registry*/) {}

}  // namespace locus::hal
