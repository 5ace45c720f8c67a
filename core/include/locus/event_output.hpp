// Event outputs: where a node's events go besides its JSON-lines file (`outputs:` in the config),
// e.g. estimates published to an MQTT broker for Home Assistant. Host-side, built in.
#pragma once

#include "locus/events.hpp"

namespace locus {

class EventOutput {
 public:
  virtual ~EventOutput() = default;
  /// [main] One event of a type the output's config entry selected (dispatcher thread). Must not
  /// block for long: queue and send asynchronously; count what could not be sent.
  virtual void write(const Event& event) = 0;
  /// [main] Everything written so far has been handed on (or reported lost). Called once at shutdown.
  virtual void flush() {}
};

}  // namespace locus
