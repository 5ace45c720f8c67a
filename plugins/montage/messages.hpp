// The link messages of `montage` (paper 002). Every device's instance publishes what it measured; the
// reporter's instance (docs/montage.md, "The localizer") assembles rounds, ranges and solves the
// formation. Topics `<topic>/<kind>/<device>` (the publishing device last: the site ACL lets a board
// write only its own), payloads text, times as seconds since the device's latest start signal
// ("tau": the radio start of the ranging protocol, received by every device at nearly the same true
// time, so tau is comparable between devices without clock sync):
//
//   round:    "<device> <tau_own_s> <self_m> <n> [<user> <dt_s>]*n"
//             the device's own emission at tau_own; its speaker-to-mic distance self_m; the arrival
//             of each other user's code, dt = arrival − own emission on the device's clock (ETOA uses
//             only such differences, paper Sec. 3).
//   step:     "<device> <tau_s> <t_s> <stride_m> <heading_rad> <offset_rad> <offset_valid>"
//             one step (heel strike at tau; t_s the same on the device's clock); stride from the bounce model (uncalibrated); heading =
//             the phone's heading (attitude, counter-clockwise from the reference x axis) averaged
//             over the step; offset = walking direction − phone heading estimated so far from the
//             horizontal acceleration (paper Sec. 4.3), offset_valid 0 while unknown.
//   progress: "<device> <tau_s>"  the device's stream has reached tau (lets the reporter know that
//             every step and round up to tau has been sent).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace locus::plugins::montage {

struct RoundMessage {
  std::string device;
  double tau_own_s = 0.0;
  double self_m = 0.0;
  std::vector<std::pair<std::string, double>> arrivals;  ///< (other user, dt_s)
};

struct StepMessage {
  std::string device;
  double tau_s = 0.0;
  double t_s = 0.0;  ///< the step on the device's own clock
  double stride_m = 0.0;
  double heading_rad = 0.0;
  double offset_rad = 0.0;
  bool offset_valid = false;
};

struct ProgressMessage {
  std::string device;
  double tau_s = 0.0;
};

std::string topic_round(std::string_view prefix, std::string_view device);
std::string topic_step(std::string_view prefix, std::string_view device);
std::string topic_progress(std::string_view prefix, std::string_view device);

std::string encode(const RoundMessage& m);
std::string encode(const StepMessage& m);
std::string encode(const ProgressMessage& m);

/// Each: nullopt unless `payload` is exactly one message of that kind with finite numbers in range
/// (|tau| and |dt| <= 1e6 s, self_m in [0, 10] m, stride in [0, 5] m, n <= 64 and matching the
/// pairs, offset_valid 0 or 1); `why` (optional) says what was wrong.
std::optional<RoundMessage> decode_round(std::string_view payload, std::string* why = nullptr);
std::optional<StepMessage> decode_step(std::string_view payload, std::string* why = nullptr);
std::optional<ProgressMessage> decode_progress(std::string_view payload, std::string* why = nullptr);

}  // namespace locus::plugins::montage
