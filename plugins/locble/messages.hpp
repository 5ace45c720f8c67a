// The link message of `locble`: the moving-target mode (paper 003, Sec. 5: "the target will send
// measurement data to the observer"). A target that moves (a phone advertising BLE) publishes its own
// dead-reckoned displacement on <topic>/motion/<address> as the text
//   "<address> <t_s> <east_m> <north_m>"
// t_s on the target's clock as synchronised to the observer's (the observer reads it as its own),
// the displacement since the target's start in a north-referenced frame (x east, y north: the only
// axes two phones share without seeing each other). The observer rotates it into its start frame
// with its own north heading and subtracts it from its path (the model's p_i = b_i − a_i).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace locus::plugins::locble {

struct TargetMotion {
  std::array<std::uint8_t, 6> address{};  ///< the target's BLE address
  double t_s = 0.0;
  double east_m = 0.0, north_m = 0.0;
};

/// "AA:BB:CC:DD:EE:FF" (upper case).
std::string format_address(const std::array<std::uint8_t, 6>& address);
/// Parses "aa:bb:cc:dd:ee:ff" (any case); nullopt unless exactly six two-digit hex groups.
std::optional<std::array<std::uint8_t, 6>> parse_address(std::string_view text);

std::string encode(const TargetMotion& m);
/// nullopt unless `payload` is exactly one message with finite numbers; `why` (optional) says what
/// was wrong.
std::optional<TargetMotion> decode(std::string_view payload, std::string* why = nullptr);

}  // namespace locus::plugins::locble
