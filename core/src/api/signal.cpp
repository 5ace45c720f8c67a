// The one signal parser and writer (locus/signal.hpp, locus/signal_yaml.hpp).
//
// Every signal type is a row of kTypes: its fields in the format's order, each with its kind (number,
// integer, text, list of numbers), whether it is required, and its value rule. The YAML/JSON parser,
// the typed checker, the JSON writer and the YAML writer all walk these rows, so a field is added or
// a rule changed in one place. The parser reads a field, then applies the same value rule as
// check_signal to what it read, reporting at the field's own line and column; a field that could not
// be read is not checked again (one issue per field).
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "locus/signal.hpp"
#include "locus/signal_yaml.hpp"

namespace locus {

namespace {

enum class Kind : std::uint8_t { Number, OptionalNumber, Integer, Text, NumberList };

/// What a field's value must satisfy (beyond its kind).
enum class Rule : std::uint8_t {
  Range,       ///< lo <= v <= hi (numbers, integers), `range` in messages
  Finite,      ///< any finite number
  Tones,       ///< a non-empty list of frequencies > 0 Hz
  Chips,       ///< a string of '0' and '1'
  GoldDegree,  ///< a degree with a preferred pair (5, 6, 7, 9, 10, 11), any of 1..30 with explicit chips
  GoldIndex,   ///< 0..2^degree
  BleAddress,  ///< AA:BB:CC:DD:EE:FF
};

struct Field {
  const char* key;
  Kind kind;
  bool required;
  Rule rule;
  double lo = 0.0, hi = 0.0;
  const char* range = "";        ///< Rule::Range: the expectation in messages
  const char* missing = nullptr; ///< expectation when required and absent; nullptr = "'<key>' for type <type>"
  double SignalSpec::*number = nullptr;                 // Number
  std::optional<double> SignalSpec::*optional = nullptr;  // OptionalNumber
  int SignalSpec::*integer = nullptr;                   // Integer
  std::string SignalSpec::*text = nullptr;              // Text
  bool parse_first = false;      ///< read before the others (gold: the degree rule depends on chips)
};

constexpr double kInf = 1e300;

Field number(const char* key, double SignalSpec::*m, bool required, double lo, double hi, const char* range) {
  Field f{key, Kind::Number, required, Rule::Range};
  f.lo = lo;
  f.hi = hi;
  f.range = range;
  f.number = m;
  return f;
}

Field integer(const char* key, int SignalSpec::*m, Rule rule, double lo = 0, double hi = 0, const char* range = "") {
  Field f{key, Kind::Integer, true, rule};
  f.lo = lo;
  f.hi = hi;
  f.range = range;
  f.integer = m;
  return f;
}

Field sync_delay() {
  Field f{"sync_delay_s", Kind::OptionalNumber, false, Rule::Finite};
  f.optional = &SignalSpec::sync_delay_s;
  return f;
}

struct TypeFields {
  const char* type;
  std::vector<Field> fields;  ///< in the format's order (what the writers write)
};

const std::vector<TypeFields>& types() {
  static const std::vector<TypeFields> kTypes = [] {
    const Field duration = number("duration", &SignalSpec::duration_s, true, 1e-12, kInf, "> 0 s");
    const Field fade = number("fade", &SignalSpec::fade_s, false, 0.0, kInf, ">= 0 s");
    const Field amplitude = number("amplitude", &SignalSpec::amplitude, false, 0.0, 1.0, "0..1");

    Field tones{"tones_hz", Kind::NumberList, true, Rule::Tones};
    tones.missing = "a list of frequencies in Hz";
    Field chips{"chips", Kind::Text, false, Rule::Chips};
    chips.text = &SignalSpec::chips;
    chips.parse_first = true;
    Field address{"address", Kind::Text, true, Rule::BleAddress};
    address.text = &SignalSpec::address;
    address.missing = "a BLE address AA:BB:CC:DD:EE:FF";

    return std::vector<TypeFields>{
        {"lfm",
         {number("f0", &SignalSpec::f0_hz, true, 0.0, kInf, ">= 0 Hz"),
          number("f1", &SignalSpec::f1_hz, true, 0.0, kInf, ">= 0 Hz"), duration, fade, amplitude, sync_delay()}},
        {"multitone", {tones, duration, fade, amplitude, sync_delay()}},
        {"gold",
         {integer("degree", &SignalSpec::degree, Rule::GoldDegree),
          integer("index", &SignalSpec::index, Rule::GoldIndex),
          number("carrier", &SignalSpec::carrier_hz, true, 0.0, kInf, ">= 0 Hz"),
          integer("chip_samples", &SignalSpec::chip_samples, Rule::Range, 1, 1 << 20, "1..1048576"), amplitude,
          chips, sync_delay()}},
        {"ble",
         {address, number("tx_power_dbm", &SignalSpec::tx_power_dbm, true, -200.0, 100.0, "-200..100 dBm"),
          number("interval_s", &SignalSpec::interval_s, true, 1e-12, kInf, "> 0 s")}},
    };
  }();
  return kTypes;
}

const TypeFields* fields_of(std::string_view type) {
  for (const TypeFields& t : types())
    if (type == t.type) return &t;
  return nullptr;
}

constexpr int kGoldDegrees[] = {5, 6, 7, 9, 10, 11};

std::string shortest(double v) {
  char b[64];
  const auto r = std::to_chars(b, b + sizeof b, v);
  return std::string(b, r.ptr);
}

std::string join(std::string_view where, std::string_view key) {
  if (where.empty()) return std::string(key);
  std::string s(where);
  s += '.';
  s += key;
  return s;
}

std::string out_of_range(double v, const char* range) {
  return "value " + shortest(v) + " out of range (expected " + range + ")";
}

/// The value rule of field `f` of `s` (its value already in `s`); "" when fine. `chips_given`: the
/// signal has explicit chips (the Gold degree rule). Rule::Tones checks the list, not its elements
/// (tone_issue).
/// `raw`: an integer field's value as read (it may not fit the field; default: the field's value).
std::string value_issue(const SignalSpec& s, const Field& f, bool chips_given, std::optional<long long> raw = {}) {
  const long long iv = f.kind == Kind::Integer ? raw.value_or(s.*f.integer) : 0;
  switch (f.rule) {
    case Rule::Range: {
      if (f.kind == Kind::Integer) {
        if (iv < static_cast<long long>(f.lo) || iv > static_cast<long long>(f.hi))
          return "value " + std::to_string(iv) + " out of range (expected " + f.range + ")";
        return "";
      }
      const double v = s.*f.number;
      if (!(v >= f.lo && v <= f.hi)) return out_of_range(v, f.range);
      return "";
    }
    case Rule::Finite:
      if (f.kind == Kind::OptionalNumber && (s.*f.optional) && !std::isfinite(*(s.*f.optional)))
        return "expected a finite number, got " + shortest(*(s.*f.optional));
      return "";
    case Rule::Tones:
      return s.tones_hz.empty() ? "expected a non-empty list of frequencies in Hz, got an empty list" : "";
    case Rule::Chips: {
      const std::string& c = s.*f.text;
      const auto bad = c.find_first_not_of("01");
      if (bad != std::string::npos)
        return "expected only '0' and '1', got '" + std::string(1, c[bad]) + "' at position " + std::to_string(bad);
      return "";
    }
    case Rule::GoldDegree: {
      const long long d = iv;
      bool listed = false;
      for (int g : kGoldDegrees) listed = listed || g == d;
      if (!listed && !chips_given)
        return "degree " + std::to_string(d) + " has no preferred pair (expected 5, 6, 7, 9, 10 or 11, or give 'chips')";
      if (d < 1 || d > 30) return "degree " + std::to_string(d) + " out of range (expected 1..30)";
      return "";
    }
    case Rule::GoldIndex: {
      const long long max_index = s.degree > 0 && s.degree <= 30 ? (1LL << s.degree) : (1LL << 30);
      const long long v = iv;
      if (v < 0 || v > max_index)
        return "value " + std::to_string(v) + " out of range (expected 0.." + std::to_string(max_index) + ")";
      return "";
    }
    case Rule::BleAddress: {
      std::array<std::uint8_t, 6> bytes{};
      if (!parse_ble_address(s.*f.text, bytes))
        return "expected a BLE address AA:BB:CC:DD:EE:FF (hex), got '" + s.*f.text + "'";
      return "";
    }
  }
  return "";
}

std::string tone_issue(double v) { return v > 0.0 && std::isfinite(v) ? "" : out_of_range(v, "> 0 Hz"); }

// ------------------------------------------------------------------------------------------ YAML nodes

std::string shown(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

void add(std::vector<SignalIssue>& issues, const YAML::Node& at, std::string field, std::string message) {
  SignalIssue is;
  is.field = std::move(field);
  const YAML::Mark m = at.IsDefined() ? at.Mark() : YAML::Mark::null_mark();
  if (!m.is_null()) {
    is.line = m.line + 1;
    is.column = m.column + 1;
  }
  is.message = std::move(message);
  issues.push_back(std::move(is));
}

std::optional<double> read_number(const YAML::Node& n, const std::string& field, std::vector<SignalIssue>& issues) {
  double v = 0.0;
  if (!n.IsScalar() || !YAML::convert<double>::decode(n, v) || !std::isfinite(v)) {
    add(issues, n, field, "expected a number, got " + shown(n));
    return std::nullopt;
  }
  return v;
}

/// Reads field `f` of the mapping `e` into `s`; true when a value was read (then its rule applies).
/// An integer is also returned in `raw` as written (it may not fit an int: its rule reports it).
bool read_field(const YAML::Node& e, const Field& f, const std::string& where, SignalSpec& s,
                std::vector<SignalIssue>& issues, std::optional<long long>& raw) {
  const YAML::Node n = e[f.key];
  const std::string field = join(where, f.key);
  if (!n.IsDefined() || n.IsNull()) {
    if (f.required) {
      const std::string expect = f.missing != nullptr ? std::string(f.missing) : "'" + std::string(f.key) + "' for type " + s.type;
      add(issues, e, where, std::string("missing required key '") + f.key + "' (expected " + expect + ")");
    }
    return false;
  }
  switch (f.kind) {
    case Kind::Number:
    case Kind::OptionalNumber: {
      const auto v = read_number(n, field, issues);
      if (!v) return false;
      if (f.kind == Kind::Number) s.*f.number = *v;
      else s.*f.optional = *v;
      return true;
    }
    case Kind::Integer: {
      long long v = 0;
      if (!n.IsScalar() || !YAML::convert<long long>::decode(n, v)) {
        add(issues, n, field, "expected an integer, got " + shown(n));
        return false;
      }
      raw = v;
      if (v >= -(1LL << 31) && v < (1LL << 31)) s.*f.integer = static_cast<int>(v);  // else: out of every range
      return true;
    }
    case Kind::Text:
      if (!n.IsScalar()) {
        add(issues, n, field, "expected a string, got " + shown(n));
        return false;
      }
      if (f.rule == Rule::Chips && n.Scalar().empty()) {  // typed data cannot tell "" from absent
        add(issues, n, field, "expected a string of 0 and 1, got an empty string");
        return false;
      }
      s.*f.text = n.Scalar();
      return true;
    case Kind::NumberList:
      if (!n.IsSequence() || n.size() == 0) {
        add(issues, n, field, "expected a non-empty list of frequencies in Hz, got " + shown(n));
        return false;
      }
      for (std::size_t i = 0; i < n.size(); ++i) {
        const std::string element = field + "[" + std::to_string(i) + "]";
        const auto v = read_number(n[i], element, issues);
        if (!v) continue;
        if (std::string msg = tone_issue(*v); !msg.empty()) add(issues, n[i], element, std::move(msg));
        else s.tones_hz.push_back(*v);
      }
      return false;  // elements checked above
  }
  return false;
}

}  // namespace

// ---------------------------------------------------------------------------------------------- parse

SignalSpec parse_signal_node(const YAML::Node& e, const std::string& where, std::vector<SignalIssue>& issues) {
  SignalSpec s;
  if (!e.IsMap()) {
    add(issues, e, where, "expected a mapping {type: ..., ...}, got " + shown(e));
    return s;
  }
  const YAML::Node tn = e["type"];
  if (!tn.IsDefined() || tn.IsNull()) {
    add(issues, e, where, "missing required key 'type' (expected lfm, gold, multitone, ble or a project type)");
    return s;
  }
  if (!tn.IsScalar()) add(issues, tn, join(where, "type"), "expected a string, got " + shown(tn));
  else s.type = tn.Scalar();
  const TypeFields* t = fields_of(s.type);
  if (t == nullptr) return s;  // a project-specific type, kept as is (is_known_signal_type tells consumers)
  const YAML::Node chips = e["chips"];
  const bool chips_given = chips.IsDefined() && !chips.IsNull();
  for (const bool first : {true, false}) {
    for (const Field& f : t->fields) {
      if (f.parse_first != first) continue;
      std::optional<long long> raw;
      if (!read_field(e, f, where, s, issues, raw)) continue;
      if (std::string msg = value_issue(s, f, chips_given, raw); !msg.empty()) {
        add(issues, e[f.key], join(where, f.key), std::move(msg));
        // the field keeps its default, as if it had not been given
        if (f.kind == Kind::Number) s.*f.number = SignalSpec{}.*f.number;
        else if (f.kind == Kind::Integer) s.*f.integer = SignalSpec{}.*f.integer;
        else if (f.kind == Kind::Text) s.*f.text = std::string();
        else if (f.kind == Kind::OptionalNumber) s.*f.optional = std::nullopt;
      }
    }
  }
  return s;
}

SignalSpec parse_signal(std::string_view text, std::string_view source) {
  YAML::Node n;
  try {
    n = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    SignalIssue is;
    if (!e.mark.is_null()) {
      is.line = e.mark.line + 1;
      is.column = e.mark.column + 1;
    }
    is.message = "not valid YAML/JSON: " + e.msg;
    throw SignalError(std::string(source), {is});
  }
  std::vector<SignalIssue> issues;
  if (!n.IsMap()) {
    add(issues, n, "", "expected one signal object ({\"type\": ..., ...}), got " + shown(n));
    throw SignalError(std::string(source), std::move(issues));
  }
  SignalSpec spec = parse_signal_node(n, "", issues);
  if (!issues.empty()) throw SignalError(std::string(source), std::move(issues));
  return spec;
}

std::vector<SignalIssue> check_signal(const SignalSpec& s, std::string_view field_prefix) {
  std::vector<SignalIssue> issues;
  auto add_typed = [&](std::string field, std::string message) {
    SignalIssue is;
    is.field = std::move(field);
    is.message = std::move(message);
    issues.push_back(std::move(is));
  };
  if (s.type.empty()) {
    add_typed(join(field_prefix, "type"), "expected lfm, gold, multitone, ble or a project type, got an empty string");
    return issues;
  }
  const TypeFields* t = fields_of(s.type);
  if (t == nullptr) return issues;
  const bool chips_given = !s.chips.empty();
  for (const Field& f : t->fields) {
    if (f.kind == Kind::Text && !f.required && (s.*f.text).empty()) continue;  // absent optional text
    const std::string field = join(field_prefix, f.key);
    if (std::string msg = value_issue(s, f, chips_given); !msg.empty()) add_typed(field, std::move(msg));
    if (f.kind == Kind::NumberList) {
      for (std::size_t i = 0; i < s.tones_hz.size(); ++i)
        if (std::string msg = tone_issue(s.tones_hz[i]); !msg.empty())
          add_typed(field + "[" + std::to_string(i) + "]", std::move(msg));
    }
  }
  return issues;
}

// ---------------------------------------------------------------------------------------------- write

std::string signal_to_json(const SignalSpec& s) {
  nlohmann::ordered_json j{{"type", s.type}};
  if (const TypeFields* t = fields_of(s.type)) {
    for (const Field& f : t->fields) {
      switch (f.kind) {
        case Kind::Number: j[f.key] = s.*f.number; break;
        case Kind::OptionalNumber:
          if (s.*f.optional) j[f.key] = *(s.*f.optional);
          break;
        case Kind::Integer: j[f.key] = s.*f.integer; break;
        case Kind::Text:
          if (f.required || !(s.*f.text).empty()) j[f.key] = s.*f.text;
          break;
        case Kind::NumberList: j[f.key] = s.tones_hz; break;
      }
    }
  }
  return j.dump();
}

void emit_signal_yaml(YAML::Emitter& out, const SignalSpec& s) {
  out << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << s.type;
  if (const TypeFields* t = fields_of(s.type)) {
    for (const Field& f : t->fields) {
      switch (f.kind) {
        case Kind::Number: out << YAML::Key << f.key << YAML::Value << shortest(s.*f.number); break;
        case Kind::OptionalNumber:
          if (s.*f.optional) out << YAML::Key << f.key << YAML::Value << shortest(*(s.*f.optional));
          break;
        case Kind::Integer: out << YAML::Key << f.key << YAML::Value << s.*f.integer; break;
        case Kind::Text:
          if (f.required || !(s.*f.text).empty()) out << YAML::Key << f.key << YAML::Value << YAML::DoubleQuoted << s.*f.text;
          break;
        case Kind::NumberList:
          out << YAML::Key << f.key << YAML::Value << YAML::Flow << YAML::BeginSeq;
          for (double v : s.tones_hz) out << shortest(v);
          out << YAML::EndSeq;
          break;
      }
    }
  }
  out << YAML::EndMap;
}

// ---------------------------------------------------------------------------------------------- misc

std::string SignalIssue::format(std::string_view source) const {
  std::string s(source);
  if (line > 0) s += ":" + std::to_string(line) + ":" + std::to_string(column);
  s += ": ";
  if (!field.empty()) s += field + ": ";
  return s + message;
}

namespace {
std::string format_all(const std::string& source, const std::vector<SignalIssue>& issues) {
  std::string s;
  for (const SignalIssue& is : issues) {
    if (!s.empty()) s += '\n';
    s += is.format(source);
  }
  return s;
}
}  // namespace

SignalError::SignalError(std::string source, std::vector<SignalIssue> issues)
    : std::runtime_error(format_all(source, issues)), source_(std::move(source)), issues_(std::move(issues)) {}

bool is_known_signal_type(std::string_view type) noexcept {
  for (const TypeFields& t : types())
    if (type == t.type) return true;
  return false;
}

bool parse_ble_address(std::string_view s, std::array<std::uint8_t, 6>& out) noexcept {
  if (s.size() != 17) return false;
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (int i = 0; i < 6; ++i) {
    const int hi = hex(s[i * 3]), lo = hex(s[i * 3 + 1]);
    if (hi < 0 || lo < 0) return false;
    if (i < 5 && s[i * 3 + 2] != ':') return false;
    out[static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  return true;
}

std::string format_ble_address(const std::array<std::uint8_t, 6>& a) {
  char b[18];
  std::snprintf(b, sizeof b, "%02X:%02X:%02X:%02X:%02X:%02X", a[0], a[1], a[2], a[3], a[4], a[5]);
  return b;
}

}  // namespace locus
