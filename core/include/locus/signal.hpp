// One signal description for the whole system: what a device or emitter plays (a scene's `emits`
// entry, docs/scene-format.md "Signals"), as typed data.
//
// Why one type: the scene reader, the plugins (a detector's template, a localizer's beep), the emitter
// and the simulator all talk about the same signals. They exchange a SignalSpec, never text, so there
// is exactly one parser (parse_signal: YAML or JSON text, e.g. a scene's entry or a link message) and
// one writer (signal_to_json), both driven by one table of the fields of each type, and one set of
// value rules (check_signal) that the parser and the emitter share. Every error names the field
// ("emits[1].duration: value 0 out of range (expected > 0 s)") and, for text, its line and column.
//
// Part of the plugin API (liblocus): DeviceGeometry and Emitter::schedule carry SignalSpec, and an
// out-of-tree plugin may parse or write signals it exchanges over the link. The generators (render
// the samples of a signal) are in locus/dsp/signals.hpp (host side).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace locus {

/// One `emits` entry. Fields that do not belong to `type` are left at their defaults.
struct SignalSpec {
  std::string type;               ///< "lfm", "gold", "multitone", "ble", or a project-specific type
  double amplitude = 1.0;         ///< 0..1 (lfm, multitone, gold)
  // lfm / multitone
  double f0_hz = 0.0;             ///< lfm start frequency
  double f1_hz = 0.0;             ///< lfm end frequency
  double duration_s = 0.0;        ///< lfm, multitone
  double fade_s = 0.0;            ///< raised-cosine fade in and out (lfm, multitone); 0 = none
  std::vector<double> tones_hz;   ///< multitone
  // gold
  int degree = 0;                 ///< r: code length 2^r − 1
  int index = 0;                  ///< which code of the family
  double carrier_hz = 0.0;
  int chip_samples = 0;           ///< samples per chip at the scene's sample rate
  std::string chips;              ///< optional '0'/'1' string; authoritative when not empty
  // ble
  std::string address;            ///< "AA:BB:CC:DD:EE:FF"
  double tx_power_dbm = 0.0;      ///< RSSI at 1 m
  double interval_s = 0.0;        ///< advertising interval
  // any acoustic entry
  std::optional<double> sync_delay_s;  ///< delay from the emitter's radio sync message to the sound

  bool acoustic() const noexcept { return type == "lfm" || type == "gold" || type == "multitone"; }
};

/// A signal with who emits it: one entry of the scene's signals (DeviceGeometry::scene_emits).
struct SceneSignal {
  std::string id;      ///< the emitting device's or emitter's id
  SignalSpec signal;
  bool has_anchor = false;            ///< the emitter's position is known (an anchored beacon, SpyLoc)
  std::array<double, 3> anchor_m{};   ///< its anchor in the world frame (metres) when has_anchor
};

/// One problem with a signal: the field it concerns, and where in the text it was (0 = unknown).
struct SignalIssue {
  std::string field;    ///< "emits[1].duration" ("" = the signal as a whole)
  int line = 0;         ///< 1-based line of the text; 0 for typed data
  int column = 0;       ///< 1-based column; 0 for typed data
  std::string message;  ///< what was wrong and what was expected
  /// "source:line:column: field: message" (the position and field parts when known).
  std::string format(std::string_view source) const;
};

/// A signal is malformed. what() lists every issue, one per line, each formatted with the source.
class SignalError : public std::runtime_error {
 public:
  SignalError(std::string source, std::vector<SignalIssue> issues);
  const std::string& source() const noexcept { return source_; }
  const std::vector<SignalIssue>& issues() const noexcept { return issues_; }

 private:
  std::string source_;
  std::vector<SignalIssue> issues_;
};

/// [main] Parses one signal object from YAML or JSON text (JSON is YAML), e.g. a link message's
/// {"type":"lfm","f0":18000,"f1":22000,"duration":0.05,"fade":0.005}. Field names and rules are those
/// of scene-format.md; unknown keys are ignored, an unknown `type` is kept as is (see
/// is_known_signal_type). `source` names the text in messages (a file, "link message on <topic>").
/// Throws SignalError listing every issue (field, line, column).
SignalSpec parse_signal(std::string_view text, std::string_view source = "signal");

/// [main] The value rules of scene-format.md applied to typed data (ranges, required lists, Gold
/// degrees, BLE address): every violation, each naming its field (prefixed with `field_prefix` and a
/// dot when given). Empty = valid. Unknown types have no rules here (see is_known_signal_type).
std::vector<SignalIssue> check_signal(const SignalSpec& spec, std::string_view field_prefix = "");

/// [main] `spec` as one JSON object with the field names of scene-format.md, every field of its type
/// in the format's order (the inverse of parse_signal: parse_signal(signal_to_json(s)) == s).
std::string signal_to_json(const SignalSpec& spec);

/// Signal types this build knows ("lfm", "gold", "multitone", "ble").
bool is_known_signal_type(std::string_view type) noexcept;
/// The known types for messages: "lfm, gold, multitone, ble".
inline constexpr const char* kKnownSignalTypes = "lfm, gold, multitone, ble";

/// Parses "AA:BB:CC:DD:EE:FF" (hex, either case; a ble signal's address, ble.csv). False when malformed.
bool parse_ble_address(std::string_view s, std::array<std::uint8_t, 6>& out) noexcept;
/// "AA:BB:CC:DD:EE:FF" (upper case).
std::string format_ble_address(const std::array<std::uint8_t, 6>& a);

}  // namespace locus
