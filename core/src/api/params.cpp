// Params: typed access to validated parameter values; ParamType names for messages.
#include "locus/params.hpp"

#include <stdexcept>
#include <string>
#include <type_traits>

namespace locus {

std::string_view param_type_name(ParamType t) noexcept {
  switch (t) {
    case ParamType::Bool: return "bool";
    case ParamType::Int: return "integer";
    case ParamType::Float: return "float";
    case ParamType::String: return "string";
    case ParamType::Enum: return "enum";
    case ParamType::FloatList: return "list of floats";
  }
  return "unknown";
}

namespace {

std::string_view held_type_name(const ParamValue& v) noexcept {
  return std::visit(
      [](const auto& x) -> std::string_view {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, std::monostate>) return "unset";
        else if constexpr (std::is_same_v<T, bool>) return "bool";
        else if constexpr (std::is_same_v<T, std::int64_t>) return "integer";
        else if constexpr (std::is_same_v<T, double>) return "float";
        else if constexpr (std::is_same_v<T, std::string>) return "string";
        else return "list of floats";
      },
      v);
}

std::string with_article(std::string_view noun) {
  const bool vowel = !noun.empty() && std::string_view("aeiou").find(noun[0]) != std::string_view::npos;
  return (vowel ? "an " : "a ") + std::string(noun);
}

[[noreturn]] void wrong_type(std::string_view key, std::string_view wanted, const ParamValue& v) {
  throw std::out_of_range("parameter '" + std::string(key) + "' is " + with_article(held_type_name(v)) +
                          ", not " + with_article(wanted));
}

}  // namespace

const ParamValue& Params::at(std::string_view key) const {
  const auto it = values_.find(key);
  if (it == values_.end() || std::holds_alternative<std::monostate>(it->second)) {
    throw std::out_of_range("parameter '" + std::string(key) + "' is not set");
  }
  return it->second;
}

bool Params::get_bool(std::string_view key) const {
  const ParamValue& v = at(key);
  if (const auto* b = std::get_if<bool>(&v)) return *b;
  wrong_type(key, "bool", v);
}

std::int64_t Params::get_int(std::string_view key) const {
  const ParamValue& v = at(key);
  if (const auto* i = std::get_if<std::int64_t>(&v)) return *i;
  wrong_type(key, "integer", v);
}

double Params::get_float(std::string_view key) const {
  const ParamValue& v = at(key);
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  wrong_type(key, "float", v);
}

const std::string& Params::get_string(std::string_view key) const {
  const ParamValue& v = at(key);
  if (const auto* s = std::get_if<std::string>(&v)) return *s;
  wrong_type(key, "string", v);
}

const std::vector<double>& Params::get_floats(std::string_view key) const {
  const ParamValue& v = at(key);
  if (const auto* l = std::get_if<std::vector<double>>(&v)) return *l;
  wrong_type(key, "list of floats", v);
}

Params Params::defaults(const ParamSchema& schema) {
  Params p;
  for (const ParamSpec& spec : schema) {
    if (spec.required()) continue;
    ParamValue v = spec.default_value;
    // An integer literal written as the default of a Float parameter is stored as a float, like a
    // value read from a config.
    if (spec.type == ParamType::Float) {
      if (const auto* i = std::get_if<std::int64_t>(&v)) v = static_cast<double>(*i);
    }
    p.set(spec.key, std::move(v));
  }
  return p;
}

}  // namespace locus
