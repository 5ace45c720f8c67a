#include "builtin.hpp"

#include <memory>

#include "scene/scene_sources.hpp"
#include "synth/synth_source.hpp"

namespace locus::hal {

void register_builtin_sources(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "synth",
      "deterministic signal generator (lfm/tone emissions, per-channel delays, clock skew, noise)",
      synth::synth_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<synth::SynthSource>()); },
  });
  scene_replay::register_scene_sources(registry);  // scene_audio, scene_imu, scene_ble, scene_sync
}

}  // namespace locus::hal
