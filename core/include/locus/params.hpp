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
