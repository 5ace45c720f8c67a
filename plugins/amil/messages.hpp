// AMIL link messages (docs/amil.md, "Messages") and the pairing of a listener's arrivals with the
// player's beeps.
//
// Why JSON: the messages cross MQTT between boards built at different times and are read by people
// debugging a demo; a beep arrival is a few dozen bytes a second. Every field is checked on decode; a
// malformed message gives a reason (the plugin logs it with the topic and counts it), never a crash.
//
// Topics (prefix = the plugin's `topic` parameter, default "amil"):
//   <prefix>/hello/<listener>     {"type":"amil_hello","listener":"L1","channel":0,"mic_offset_m":0.072}
//   <prefix>/arrivals/<listener>  {"type":"amil_arrival","listener":"L1","seq":0,"frame":123456.789,
//                                  "sample_rate_hz":44100.0,"t_s":2.79947,"channel":0,"snr_db":31.5,
//                                  "confidence":0.98,"envelope_frame":123456.1,"carrier_period":2.205}
// `mic_offset_m`, `confidence`, `envelope_frame` and `carrier_period` are optional (older listeners):
// absent = unknown (0), 1, and no carrier timing (the player then cannot align carrier cycles).
//   <prefix>/done/<listener>      {"type":"amil_done","listener":"L1","arrivals":5}
// Times are the listener's own clock (frame counter of its audio stream), never converted: relating the
// clocks is the solver's job (offset and skew).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locus::plugins::amil {

struct ArrivalMessage {
  std::string listener;
  std::uint64_t seq = 0;          ///< 0, 1, ... per listener (gaps reveal lost messages)
  double frame = 0.0;             ///< fractional frame of the beep's start on the listener's stream
  double sample_rate_hz = 0.0;    ///< nominal rate of that stream
  std::uint32_t channel = 0;
  double snr_db = 0.0;
  double confidence = 1.0;        ///< the detector's confidence, 0..1 (< 1: the carrier cycle is uncertain)
  double envelope_frame = 0.0;    ///< the arrival by the envelope alone (AudioDetection::envelope_frame)
  double carrier_period = 0.0;    ///< samples; 0 = not carrier-timed
  double t_s() const { return frame / sample_rate_hz; }
  /// frame - envelope_frame in seconds (0 when not carrier-timed)
  double cycle_offset_s() const { return carrier_period > 0.0 ? (frame - envelope_frame) / sample_rate_hz : 0.0; }
  double carrier_period_s() const { return carrier_period / sample_rate_hz; }
};

struct DoneMessage {
  std::string listener;
  std::uint64_t arrivals = 0;     ///< arrivals the listener published in all
};

struct HelloMessage {
  std::string listener;
  std::uint32_t channel = 0;
  double mic_offset_m = 0.0;      ///< horizontal distance of the listening mic from the device origin (0 = unknown)
};

std::string topic_hello(std::string_view prefix, std::string_view listener);
std::string topic_arrival(std::string_view prefix, std::string_view listener);
std::string topic_done(std::string_view prefix, std::string_view listener);
/// The subscription filter for every AMIL message under `prefix` ("<prefix>/#").
std::string topic_filter(std::string_view prefix);

std::string encode(const ArrivalMessage& m);
std::string encode(const DoneMessage& m);
std::string encode(const HelloMessage& m);

/// One decoded message: exactly one of the three is set, or `error` says what was wrong.
struct Decoded {
  std::optional<ArrivalMessage> arrival;
  std::optional<DoneMessage> done;
  std::optional<HelloMessage> hello;
  std::string error;
};
/// Decodes a message from its topic and payload. The listener id of the topic must equal the
/// payload's; a topic under the prefix with an unknown kind is an error too.
Decoded decode(std::string_view prefix, std::string_view topic, std::string_view payload);

/// Pairs a listener's arrivals (its clock) with the player's beeps (player clock): the clock offset is
/// the one that pairs the most beeps within `tolerance_s` (ties: the smaller RMS spread), each beep
/// taking its nearest unused arrival. Returns one arrival per beep (NaN = not heard). Assumes the
/// beeps are further apart than 2·tolerance_s (AMIL pauses: ~1 s) and that the listener's clock rate
/// differs by less than tolerance_s over the beeps' span.
std::vector<double> match_arrivals(const std::vector<double>& beeps_s, const std::vector<double>& arrivals_s,
                                   double tolerance_s, int* matched = nullptr);


}  // namespace locus::plugins::amil
