#include "builtin.hpp"

#include <memory>

#include "synth/synth_source.hpp"

namespace locus::hal {

void register_builtin_sources(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "synth",
      "deterministic signal generator (lfm/tone emissions, per-channel delays, clock skew, noise)",
      synth::synth_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<synth::SynthSource>()); },
  });
}

}  // namespace locus::hal
