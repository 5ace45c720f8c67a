// `locus devices` for JACK: the audio ports a `jack` source or sink can connect to, on one server.
//
// Why it opens its own short-lived client: listing must work with no locus node running and must not
// disturb one (a unique, non-exact client name, closed right away). With no server it never fails:
// one entry of kind "unavailable" says why (see hal/devices.hpp).
#pragma once

#include <string>
#include <vector>

#include "devices.hpp"

namespace locus::hal {

/// Every audio port of JACK server `server` ("" = $JACK_DEFAULT_SERVER, else "default"): kind "port",
/// id the full port name, description its direction (output = a source connects from it, input = a
/// sink connects to it), flags and connections. One "unavailable" entry when no server answers.
std::vector<DeviceInfo> list_jack_ports(const std::string& server);

}  // namespace locus::hal
