// Registers the built-in HAL backends. alsa, jack and bluez are optional (LOCUS_WITH_ALSA/JACK/BLUEZ):
// one that was not built is registered as "not built in" with the reason from the generated
// locus/build_options.hpp, so configs and `locus plugins` say why it is missing.
#include "builtin.hpp"

#include <memory>

#include "iio/iio_source.hpp"
#include "locus/build_options.hpp"
#include "radio/link_sync.hpp"
#include "scene/scene_sources.hpp"
#include "synth/synth_source.hpp"
#if LOCUS_HAVE_ALSA
#include "alsa/alsa_register.hpp"
#endif
#if LOCUS_HAVE_BLUEZ
#include "bluez/bluez_scanner.hpp"
#endif
#if LOCUS_HAVE_JACK
#include "jack/jack_backend.hpp"
#endif

namespace locus::hal {

namespace {

/// Registers an optional backend that this build lacks under its config name (e.g. "jack").
[[maybe_unused]] void add_not_built(Registry& registry, std::string_view name) {
  const build::OptionalBackend* b = build::find_optional_backend(name);
  registry.add_not_built(NotBuiltBackend{std::string(name), build::not_built_reason(*b)});
}

}  // namespace

void register_builtin_sources(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "synth",
      "deterministic signal generator (lfm/tone emissions, per-channel delays, clock skew, noise)",
      synth::synth_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<synth::SynthSource>()); },
  });
#if LOCUS_HAVE_ALSA
  alsa::register_alsa_backends(registry);           // alsa (source: capture PCM; sink: playback PCM)
#else
  add_not_built(registry, "alsa");
#endif
  scene_replay::register_scene_sources(registry);  // scene_audio, scene_imu, scene_ble, scene_sync
#if LOCUS_HAVE_JACK
  jack::register_jack_backends(registry);           // jack (source: input ports; sink: output ports)
#else
  add_not_built(registry, "jack");
#endif
  radio::register_link_sync_source(registry);       // link (radio sync over the node's link; add_sensor_source kind Sync)
  iio::register_iio_source(registry);               // iio (IMU from Linux IIO sysfs + /dev/iio:deviceN)
#if LOCUS_HAVE_BLUEZ
  bluez::register_bluez_source(registry);           // bluez (BLE adverts through BlueZ D-Bus; add_sensor_source kind Ble)
#else
  add_not_built(registry, "bluez");
#endif
}

}  // namespace locus::hal
