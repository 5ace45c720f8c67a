// The rules of a plugin descriptor (see descriptor_rules.hpp).
#include "descriptor_rules.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <variant>

#include "locus/events.hpp"

namespace locus {

namespace {

/// Instance names default to the plugin name and are carried in NameTag (31 characters).
constexpr std::size_t kMaxPluginNameLength = NameTag::max_size();

bool valid_plugin_name(std::string_view name) noexcept {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

bool default_matches(const ParamSpec& spec) {
  const ParamValue& v = spec.default_value;
  switch (spec.type) {
    case ParamType::Bool: return std::holds_alternative<bool>(v);
    case ParamType::Int: return std::holds_alternative<std::int64_t>(v);
    case ParamType::Float: return std::holds_alternative<double>(v) || std::holds_alternative<std::int64_t>(v);
    case ParamType::String:
    case ParamType::Enum: return std::holds_alternative<std::string>(v);
    case ParamType::FloatList: return std::holds_alternative<std::vector<double>>(v);
  }
  return false;
}

bool in_range(const ParamSpec& spec, double x) {
  if (std::isnan(x)) return true;  // NaN defaults mean "automatic" for some plugins
  return !(spec.min && x < *spec.min) && !(spec.max && x > *spec.max);
}

/// The kind, its factory and (detectors) its inputs.
std::optional<DescriptorFault> kind_fault(const locus_plugin_descriptor& d) {
  const auto fault = [](DescriptorRule rule, std::string reason) {
    return std::optional<DescriptorFault>(DescriptorFault{rule, std::move(reason)});
  };
  switch (d.kind) {
    case LOCUS_PLUGIN_DETECTOR:
      if (d.create_detector == nullptr) return fault(DescriptorRule::Factory, "a detector without a create_detector factory");
      if (d.create_localizer != nullptr) return fault(DescriptorRule::Factory, "a detector that also sets create_localizer");
      if (d.inputs == 0) return fault(DescriptorRule::Inputs, "a detector that declares no inputs");
      if ((d.inputs & ~std::uint32_t{kInputAudio | kInputImu | kInputBle}) != 0) {
        return fault(DescriptorRule::Inputs, "unknown input bits " + std::to_string(d.inputs));
      }
      return std::nullopt;
    case LOCUS_PLUGIN_LOCALIZER:
      if (d.create_localizer == nullptr) return fault(DescriptorRule::Factory, "a localizer without a create_localizer factory");
      if (d.create_detector != nullptr) return fault(DescriptorRule::Factory, "a localizer that also sets create_detector");
      return std::nullopt;
    default:
      return fault(DescriptorRule::Kind, "unknown kind " + std::to_string(d.kind) + " (1 = detector, 2 = localizer)");
  }
}

}  // namespace

std::string schema_problem(const ParamSchema& schema) {
  for (std::size_t i = 0; i < schema.size(); ++i) {
    const ParamSpec& spec = schema[i];
    if (spec.key.empty()) return "parameter #" + std::to_string(i) + " has an empty key";
    const std::string where = "parameter '" + spec.key + "'";
    for (std::size_t j = 0; j < i; ++j) {
      if (schema[j].key == spec.key) return where + " is declared twice";
    }
    if (spec.min && spec.max && *spec.min > *spec.max) return where + " has min > max";
    if (spec.type == ParamType::Enum && spec.choices.empty()) return where + " is an enum without choices";
    if (spec.min_items && spec.max_items && *spec.min_items > *spec.max_items) {
      return where + " has min_items > max_items";
    }
    if (spec.required()) continue;
    if (!default_matches(spec)) {
      return where + " has a default that does not match its type (" + std::string(param_type_name(spec.type)) + ")";
    }
    bool ok = true;
    if (const auto* d = std::get_if<double>(&spec.default_value)) ok = in_range(spec, *d);
    if (const auto* n = std::get_if<std::int64_t>(&spec.default_value)) ok = in_range(spec, static_cast<double>(*n));
    if (const auto* l = std::get_if<std::vector<double>>(&spec.default_value)) {
      ok = std::all_of(l->begin(), l->end(), [&](double x) { return in_range(spec, x); });
    }
    if (!ok) return where + " has a default outside [min, max]";
    if (spec.type == ParamType::Enum) {
      const auto& s = std::get<std::string>(spec.default_value);
      if (std::find(spec.choices.begin(), spec.choices.end(), s) == spec.choices.end()) {
        return where + " has a default '" + s + "' that is not one of its choices";
      }
    }
  }
  return {};
}

std::optional<DescriptorFault> descriptor_fault(const locus_plugin_descriptor* d) {
  const auto fault = [](DescriptorRule rule, std::string reason) {
    return std::optional<DescriptorFault>(DescriptorFault{rule, std::move(reason)});
  };
  if (d == nullptr) return fault(DescriptorRule::NotNull, "null descriptor");
  if (d->abi_version != LOCUS_PLUGIN_ABI_VERSION) {
    return fault(DescriptorRule::AbiVersion, "built for plugin ABI version " + std::to_string(d->abi_version) +
                                                 ", this host uses version " + std::to_string(LOCUS_PLUGIN_ABI_VERSION) +
                                                 "; rebuild the plugin against this Locus");
  }
  if (d->name == nullptr) return fault(DescriptorRule::NameNotNull, "the descriptor has no name");
  const std::string_view name(d->name);
  if (!valid_plugin_name(name)) return fault(DescriptorRule::NameCharacters, "invalid name (a plugin name is [a-z0-9_]+)");
  if (name.size() > kMaxPluginNameLength) {
    return fault(DescriptorRule::NameLength, "name longer than " + std::to_string(kMaxPluginNameLength) + " characters");
  }
  if (d->version == nullptr) return fault(DescriptorRule::Version, "no version");
  if (d->description == nullptr) return fault(DescriptorRule::Description, "no description");
  if (auto f = kind_fault(*d)) return f;
  if (d->schema == nullptr) return fault(DescriptorRule::SchemaFunction, "no schema function");
  const ParamSchema* schema = nullptr;
  try {
    schema = d->schema();
  } catch (...) {
    return fault(DescriptorRule::SchemaFunction, "schema() threw an exception");
  }
  if (schema == nullptr) return fault(DescriptorRule::SchemaFunction, "schema() returned nullptr");
  if (const std::string problem = schema_problem(*schema); !problem.empty()) {
    return fault(DescriptorRule::Schema, "bad schema: " + problem);
  }
  return std::nullopt;
}

}  // namespace locus
