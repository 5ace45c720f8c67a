// list_jack_ports (see jack_devices.hpp).
#include "jack/jack_devices.hpp"

#include <jack/jack.h>

#include "jack/jack_client.hpp"

namespace locus::hal {

std::vector<DeviceInfo> list_jack_ports(const std::string& server) {
  const std::string resolved = jack::resolve_server_name(server);
  std::vector<DeviceInfo> out;
  jack_client_t* jc = nullptr;
  jack_status_t status{};
  {
    jack::QuietJack quiet;
    int options = JackNoStartServer;
    if (!server.empty()) options |= JackServerName;
    jc = jack_client_open("locus_devices", static_cast<jack_options_t>(options), &status, server.c_str());
  }
  if (jc == nullptr) {
    out.push_back(DeviceInfo{"jack", "unavailable", resolved,
                             jack::describe_open_status(static_cast<unsigned>(status), resolved, "locus_devices")});
    return out;
  }
  const std::string rate = std::to_string(jack_get_sample_rate(jc)) + " Hz, " +
                           std::to_string(jack_get_buffer_size(jc)) + "-frame periods";
  const char** ports = jack_get_ports(jc, nullptr, JACK_DEFAULT_AUDIO_TYPE, 0);
  const std::string own = std::string(jack_get_client_name(jc)) + ":";
  for (const char** p = ports; p != nullptr && *p != nullptr; ++p) {
    if (std::string(*p).rfind(own, 0) == 0) continue;
    jack_port_t* port = jack_port_by_name(jc, *p);
    if (port == nullptr) continue;  // went away meanwhile
    const int flags = jack_port_flags(port);
    std::string d = (flags & JackPortIsOutput) ? "output (a jack source captures from it)"
                                               : "input (a jack sink plays into it)";
    if (flags & JackPortIsPhysical) d += ", physical";
    if (flags & JackPortIsTerminal) d += ", terminal";
    d += ", " + rate;
    const char** conns = jack_port_get_all_connections(jc, port);
    if (conns != nullptr) {
      d += ", connected to";
      for (const char** c = conns; *c != nullptr; ++c) d += std::string(c == conns ? " " : ", ") + *c;
      jack_free(conns);
    }
    out.push_back(DeviceInfo{"jack", "port", *p, d});
  }
  if (ports != nullptr) jack_free(ports);
  {
    jack::QuietJack quiet;
    jack_client_close(jc);
  }
  if (out.empty()) out.push_back(DeviceInfo{"jack", "unavailable", resolved, "JACK server '" + resolved + "' has no audio ports"});
  return out;
}

}  // namespace locus::hal
