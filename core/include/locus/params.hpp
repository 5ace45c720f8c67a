// Parameter schemas that every plugin and backend declares, and the validated values it receives.
//
// The host validates a whole config against these schemas before anything runs (see config.hpp), so
// a plugin's configure() only ever sees values of the declared type, inside the declared range, with
// defaults filled in.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace locus {

enum class ParamType : std::uint8_t { Bool, Int, Float, String, Enum, FloatList };

/// A value of one of the ParamType kinds; std::monostate means "no value" (a required parameter).
using ParamValue = std::variant<std::monostate, bool, std::int64_t, double, std::string, std::vector<double>>;

/// One declared parameter.
struct ParamSpec {
  std::string key;                    ///< YAML key, snake_case, SI unit suffix where ambiguous
  ParamType type = ParamType::Float;
  ParamValue default_value;           ///< monostate = required
  std::optional<double> min;          ///< inclusive bounds for Int/Float (and each FloatList element)
  std::optional<double> max;
  std::string unit;                   ///< SI unit ("Hz", "s", "m", "dB", "" for none)
  std::string doc;                    ///< one sentence for `locus plugins` and docs
  std::vector<std::string> choices;   ///< allowed values for Enum
  std::optional<std::size_t> min_items;  ///< FloatList length bounds
  std::optional<std::size_t> max_items;

  bool required() const noexcept { return std::holds_alternative<std::monostate>(default_value); }
};

using ParamSchema = std::vector<ParamSpec>;

// Schema builders: one line per parameter in a plugin's schema, e.g.
//   ParamSchema s{float_param("threshold_db", 12.0, 1.0, 80.0, "dB", "Trigger level above the floor."),
//                 enum_param("mode", "spyloc", {"spyloc", "montage"}, "Step detector form.")};
// A std::monostate default (see required()) makes the parameter required.
inline ParamSpec float_param(std::string key, ParamValue def, double min, double max, std::string unit, std::string doc) {
  ParamSpec s;
  s.key = std::move(key);
  s.type = ParamType::Float;
  s.default_value = std::move(def);
  s.min = min;
  s.max = max;
  s.unit = std::move(unit);
  s.doc = std::move(doc);
  return s;
}
inline ParamSpec int_param(std::string key, ParamValue def, double min, double max, std::string unit, std::string doc) {
  ParamSpec s = float_param(std::move(key), std::move(def), min, max, std::move(unit), std::move(doc));
  s.type = ParamType::Int;
  return s;
}
inline ParamSpec bool_param(std::string key, bool def, std::string doc) {
  ParamSpec s;
  s.key = std::move(key);
  s.type = ParamType::Bool;
  s.default_value = def;
  s.doc = std::move(doc);
  return s;
}
inline ParamSpec string_param(std::string key, ParamValue def, std::string doc) {
  ParamSpec s;
  s.key = std::move(key);
  s.type = ParamType::String;
  s.default_value = std::move(def);
  s.doc = std::move(doc);
  return s;
}
inline ParamSpec enum_param(std::string key, ParamValue def, std::vector<std::string> choices, std::string doc) {
  ParamSpec s = string_param(std::move(key), std::move(def), std::move(doc));
  s.type = ParamType::Enum;
  s.choices = std::move(choices);
  return s;
}
inline ParamSpec float_list_param(std::string key, ParamValue def, double min, double max, std::string unit,
                                  std::string doc, std::size_t min_items = 0,
                                  std::optional<std::size_t> max_items = std::nullopt) {
  ParamSpec s = float_param(std::move(key), std::move(def), min, max, std::move(unit), std::move(doc));
  s.type = ParamType::FloatList;
  if (min_items > 0) s.min_items = min_items;
  s.max_items = max_items;
  return s;
}

/// Human-readable name of a type ("float", "list of floats", ...), used in error messages.
std::string_view param_type_name(ParamType t) noexcept;

/// Validated parameter values (every declared key present, of its declared type).
class Params {
 public:
  Params() = default;

  /// [main] Typed getters; throw std::out_of_range naming the key if it is absent or of another type
  /// (never the case for values produced by the validator from the same schema).
  bool get_bool(std::string_view key) const;
  std::int64_t get_int(std::string_view key) const;
  double get_float(std::string_view key) const;  ///< also accepts an Int value
  const std::string& get_string(std::string_view key) const;  ///< String or Enum
  const std::vector<double>& get_floats(std::string_view key) const;

  bool has(std::string_view key) const { return values_.find(key) != values_.end(); }
  void set(std::string key, ParamValue v) { values_[std::move(key)] = std::move(v); }
  const std::map<std::string, ParamValue, std::less<>>& values() const noexcept { return values_; }

  /// Params holding every schema default (required keys left absent).
  static Params defaults(const ParamSchema& schema);

 private:
  const ParamValue& at(std::string_view key) const;
  std::map<std::string, ParamValue, std::less<>> values_;
};

}  // namespace locus
