// Link messages as they arrive from MQTT: the host's signature check (link/auth) and every built-in
// localizer's decoder. The first input byte picks the decoder, the next line is the topic, the rest
// the payload, so one corpus covers them all. Decoders report errors in their result; they never
// throw (an exception here is a finding).
#include <cstdint>
#include <string>

#include "amil/messages.hpp"
#include "auth/message_auth.hpp"
#include "fuzz_support.hpp"
#include "locble/messages.hpp"
#include "montage/messages.hpp"
#include "tum/messages.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view rest = locus::fuzz::as_text(data + 1, size - 1);
  const std::size_t eol = rest.find('\n');
  const std::string_view topic = eol == std::string_view::npos ? rest : rest.substr(0, eol);
  const std::string_view payload = eol == std::string_view::npos ? std::string_view() : rest.substr(eol + 1);
  std::string why;  // the decoders' reason for a refusal (filled, never read: only crashes matter)
  switch (data[0] % 7) {
    case 0: (void)locus::plugins::amil::decode("amil", topic, payload); break;
    case 1: (void)locus::plugins::tum::decode("tum", topic, payload); break;
    case 3: (void)locus::plugins::locble::decode(payload, &why); break;
    case 4: (void)locus::plugins::montage::decode_round(payload, &why); break;
    case 5: (void)locus::plugins::montage::decode_step(payload, &why); break;
    case 6: (void)locus::plugins::montage::decode_progress(payload, &why); break;
    default: {
      static locus::linkauth::MessageAuthenticator auth("fuzz-site-key-0123456789abcdef", "fuzz", 30.0);
      (void)auth.verify(topic, payload, 1.8e9);
      break;
    }
  }
  return 0;
}
