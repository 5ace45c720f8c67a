// Registers the built-in links and network event outputs: link "mqtt" and output "mqtt" (link/mqtt),
// or, in a build without MQTT (LOCUS_WITH_MQTT=OFF or libmosquitto not found), "mqtt" as not built in.
#include "links.hpp"

#include <memory>

#include "locus/build_options.hpp"
#if LOCUS_HAVE_MQTT
#include "mqtt/mqtt_link.hpp"
#include "mqtt/mqtt_output.hpp"
#endif

namespace locus::links {

void register_builtin_links(Registry& registry) {
#if LOCUS_HAVE_MQTT
  registry.add_link(LinkDescriptor{
      "mqtt",
      "MQTT broker between boards (libmosquitto): reconnects, re-subscribes, queues while offline; "
      "optional username/password, TLS and signed messages (docs/mqtt.md)",
      mqtt::mqtt_link_schema(),
      [](const Params& params, Logger& log) -> std::unique_ptr<Link> {
        mqtt::MqttOptions options = mqtt::mqtt_options_from_params(params, "mqtt link");
        auto auth = mqtt::mqtt_link_authenticator(params, options);
        return std::make_unique<mqtt::MqttLink>(std::move(options), params.get_string("topic_prefix"), log,
                                                std::move(auth));
      },
  });
  registry.add_output(OutputDescriptor{
      "mqtt",
      "events as JSON on MQTT topics, with Home Assistant discovery for estimates (docs/mqtt.md)",
      mqtt::mqtt_output_schema(),
      [](const Params& params, Logger& log) -> std::unique_ptr<EventOutput> {
        mqtt::MqttOptions options = mqtt::mqtt_options_from_params(params, "mqtt output");
        return std::make_unique<mqtt::MqttEventOutput>(std::move(options), mqtt::mqtt_output_options_from_params(params),
                                                       log);
      },
  });
#else
  registry.add_not_built(
      NotBuiltBackend{"mqtt", build::not_built_reason(*build::find_optional_backend("mqtt"))});
#endif
}

}  // namespace locus::links
