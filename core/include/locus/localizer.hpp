// Localizer plugins: subscribe to event types, talk to peers over the link, publish estimates.
//
// All methods run on the host's dispatcher thread ([main]): events, link messages and finish() are
// never delivered concurrently, so a localizer needs no locks of its own.
#pragma once

#include <vector>

#include "locus/events.hpp"
#include "locus/host.hpp"
#include "locus/params.hpp"

namespace locus {

class Localizer {
 public:
  virtual ~Localizer() = default;

  /// [main] Validated params; subscribe to link topics through ctx.link here. Throw
  /// std::runtime_error on a bad setup.
  virtual void configure(const Params& params, HostContext& ctx) = 0;

  /// [main] Event types this localizer wants (asked once, after configure()).
  virtual std::vector<EventType> subscriptions() const = 0;

  /// [main] One event of a subscribed type, from any device of this node.
  virtual void on_event(const Event& event, Publisher& out) = 0;

  /// [main] Every input of this node ended, and (replay) every other node's too: hand the peers what is
  /// still held back for them (link messages waiting for a window to close). Called on every node that
  /// shares the link before any node's finish(), with the link settled in between, so that a peer's
  /// finish() sees the last messages of every node whatever order the nodes finish in.
  virtual void inputs_ended(Publisher& /*out*/) {}

  /// [main] All inputs ended and the peers' last link messages delivered: publish final estimates.
  virtual void finish(Publisher& /*out*/) {}
};

}  // namespace locus
