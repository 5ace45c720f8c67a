// See alsa_devices.hpp.
#include "alsa/alsa_devices.hpp"

#include <alsa/asoundlib.h>

#include <cstdlib>
#include <string>

#include "alsa/alsa_pcm.hpp"

namespace locus::hal::alsa {

namespace {

/// Hint strings are malloc'ed by libasound; multi-line descriptions become one line.
std::string take_hint(void* hint, const char* field) {
  char* s = snd_device_name_get_hint(hint, field);
  if (s == nullptr) return {};
  std::string out(s);
  std::free(s);
  for (char& c : out)
    if (c == '\n') c = ' ';
  return out;
}

std::string directions(snd_ctl_t* ctl, int device) {
  std::string out;
  snd_pcm_info_t* info = nullptr;
  snd_pcm_info_malloc(&info);
  for (snd_pcm_stream_t stream : {SND_PCM_STREAM_CAPTURE, SND_PCM_STREAM_PLAYBACK}) {
    snd_pcm_info_set_device(info, static_cast<unsigned int>(device));
    snd_pcm_info_set_subdevice(info, 0);
    snd_pcm_info_set_stream(info, stream);
    if (snd_ctl_pcm_info(ctl, info) == 0)
      out += (out.empty() ? "" : "+") + std::string(stream == SND_PCM_STREAM_CAPTURE ? "capture" : "playback");
  }
  snd_pcm_info_free(info);
  return out;
}

}  // namespace

std::vector<DeviceInfo> list_alsa_devices() {
  install_error_capture();  // keep libasound's own complaints off stderr
  std::vector<DeviceInfo> out;
  // ---- cards and their PCM devices
  int card = -1;
  while (snd_card_next(&card) == 0 && card >= 0) {
    const std::string hw = "hw:" + std::to_string(card);
    snd_ctl_t* ctl = nullptr;
    if (snd_ctl_open(&ctl, hw.c_str(), 0) < 0) {
      out.push_back(DeviceInfo{"alsa", "card", hw, "(cannot open its control device)"});
      continue;
    }
    snd_ctl_card_info_t* info = nullptr;
    snd_ctl_card_info_malloc(&info);
    std::string name = "?";
    if (snd_ctl_card_info(ctl, info) == 0)
      name = std::string(snd_ctl_card_info_get_id(info)) + ": " + snd_ctl_card_info_get_name(info);
    snd_ctl_card_info_free(info);
    out.push_back(DeviceInfo{"alsa", "card", hw, name});
    int device = -1;
    while (snd_ctl_pcm_next_device(ctl, &device) == 0 && device >= 0) {
      const std::string id = hw + "," + std::to_string(device);
      out.push_back(DeviceInfo{"alsa", "pcm", id, name + " device " + std::to_string(device) + " [" +
                                                      directions(ctl, device) + "] (plug" + id + " converts/resamples)"});
    }
    snd_ctl_close(ctl);
  }
  // ---- PCMs of the configuration
  void** hints = nullptr;
  const int err = snd_device_name_hint(-1, "pcm", &hints);
  if (err < 0 || hints == nullptr) {
    out.push_back(DeviceInfo{"alsa", "unavailable", "",
                             "cannot list the configured ALSA PCMs: " + alsa_error_text(err)});
    return out;
  }
  for (void** h = hints; *h != nullptr; ++h) {
    const std::string name = take_hint(*h, "NAME");
    if (name.empty()) continue;
    const std::string desc = take_hint(*h, "DESC");
    const std::string ioid = take_hint(*h, "IOID");
    const std::string dir = ioid.empty() ? "capture+playback" : ioid == "Input" ? "capture" : "playback";
    out.push_back(DeviceInfo{"alsa", "pcm", name, (desc.empty() ? name : desc) + " [" + dir + "]"});
  }
  snd_device_name_free_hint(hints);
  take_alsa_message();
  return out;
}

}  // namespace locus::hal::alsa
