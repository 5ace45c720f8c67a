// Registration of the ALSA backend (see alsa_source.hpp and alsa_sink.hpp for what they do).
#include "alsa/alsa_register.hpp"

#include <memory>

#include "alsa/alsa_sink.hpp"
#include "alsa/alsa_source.hpp"

namespace locus::hal::alsa {

void register_alsa_backends(Registry& registry) {
  registry.add_source(SourceDescriptor{
      "alsa",
      "capture from an ALSA PCM (hw:, plughw:, default, or a PCM of an extra config file); xruns recovered "
      "and reported as lost frames, device loss retried with backoff",
      alsa_source_schema(),
      [] { return std::unique_ptr<AudioSource>(std::make_unique<AlsaSource>()); },
  });
  registry.add_sink(SinkDescriptor{
      "alsa",
      "play the device's scheduled emissions through an ALSA PCM; underruns skipped on the playback clock",
      alsa_sink_schema(),
      [] { return std::unique_ptr<AudioSink>(std::make_unique<AlsaSink>()); },
  });
}

}  // namespace locus::hal::alsa
