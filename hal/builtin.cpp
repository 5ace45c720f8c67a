#include "builtin.hpp"

#include <memory>

#include "alsa/alsa_register.hpp"
#include "bluez/bluez_scanner.hpp"
#include "iio/iio_source.hpp"
#include "jack/jack_backend.hpp"
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
  alsa::register_alsa_backends(registry);           // alsa (source: capture PCM; sink: playback PCM)
  scene_replay::register_scene_sources(registry);  // scene_audio, scene_imu, scene_ble, scene_sync
  jack::register_jack_backends(registry);           // jack (source: input ports; sink: output ports)
  iio::register_iio_source(registry);               // iio (IMU from Linux IIO sysfs + /dev/iio:deviceN)
  bluez::register_bluez_source(registry);           // bluez (BLE adverts through BlueZ D-Bus; add_sensor_source kind Ble)
}

}  // namespace locus::hal
