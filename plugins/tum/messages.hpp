// TUM link messages (docs/tum.md, "Messages").
//
// One message per device and tone exchange: what that device heard, on its own clock, plus what the
// solver needs to place it (its mic/speaker geometry and its attitude at the exchange). JSON, like
// AMIL's, because it crosses MQTT between boards and people read it; every field is checked on decode.
//
// Topic (prefix = the plugin's `topic` parameter, default "tum"):
//   <prefix>/obs/<device>  {"type":"tum_obs","device":"B","seq":4,
//                           "mics":[[x,y,z],...],"speaker":[x,y,z] | null,
//                           "q_wxyz":[w,x,y,z] | null, "moving":false, "w_radps":[x,y,z],
//                           "t1":[t_mic0, t_mic1, ...], "t2":[...]}
// t1 / t2: local arrival time (s, the device's audio clock) of working device 1's / device 2's tone at
// each microphone, null = not detected. q_wxyz: the `attitude` detector's body -> reference rotation
// (null = no IMU) and w_radps the gyro's body-frame rate (optional: absent or null = no gyro), both at
// the device's reference instant of the exchange: its hearing of device 1's tone (the mean of t1),
// else its first arrival. Times are never converted: relating clocks is the solver's job (docs/tum.md).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locus::plugins::tum {

using Vec3a = std::array<double, 3>;

struct ObsMessage {
  std::string device;
  std::uint64_t seq = 0;                        ///< 0, 1, ... per device
  std::vector<Vec3a> mics_m;                    ///< body frame, channel order (>= 2)
  std::optional<Vec3a> speaker_m;               ///< body frame; absent = cannot emit
  std::optional<std::array<double, 4>> q_wxyz;  ///< attitude at the exchange; absent = unknown
  bool moving = false;                          ///< the IMU saw motion since the previous exchange
  std::optional<Vec3a> gyro_radps;              ///< body-frame angular rate at the exchange; absent = no gyro
  std::vector<double> t1_s;                     ///< per mic; NaN = not heard
  std::vector<double> t2_s;                     ///< per mic; NaN = not heard
};

std::string topic_obs(std::string_view prefix, std::string_view device);
/// The subscription filter for every TUM message under `prefix` ("<prefix>/#").
std::string topic_filter(std::string_view prefix);

std::string encode(const ObsMessage& m);

struct Decoded {
  std::optional<ObsMessage> obs;
  std::string error;  ///< why the message was refused (empty when obs is set)
};
/// Decodes a message from its topic and payload; the device of the topic must equal the payload's.
Decoded decode(std::string_view prefix, std::string_view topic, std::string_view payload);

}  // namespace locus::plugins::tum
