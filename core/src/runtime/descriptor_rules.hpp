// The one set of rules a plugin descriptor must meet, built in (Registry::add_plugin) or loaded from
// a shared object (Registry::load_library): both ask descriptor_fault(), then word the answer for
// their reader (a library names the descriptor by index, add_plugin names the plugin and its origin).
//
// Why one function: the loader and the registry used to check overlapping but different lists, so a
// built-in descriptor could pass what a loaded one could not (a detector without inputs, a null
// version). Rules, in the order they are checked (the first broken one is reported):
//   abi_version first (the only field at a known position in a descriptor of another ABI), then
//   name (non-null, [a-z0-9_]+, at most 31 characters: instance names default to it and travel in
//   NameTag), version and description (non-null), kind (detector or localizer) with exactly its own
//   factory, a detector's inputs (some, and only kInputAudio | kInputImu | kInputBle), and the schema
//   (a function returning a sound ParamSchema: unique keys, min <= max, defaults of the declared type
//   inside the range, enum defaults among the choices).
#pragma once

#include <optional>
#include <string>

#include "locus/params.hpp"
#include "locus/plugin.hpp"

namespace locus {

/// Which rule a descriptor breaks.
enum class DescriptorRule {
  NotNull, AbiVersion, NameNotNull, NameCharacters, NameLength, Version, Description, Kind, Factory, Inputs,
  SchemaFunction, Schema,
};

/// The first rule a descriptor breaks and why, worded to follow "cannot add plugin 'x' (origin): ".
struct DescriptorFault {
  DescriptorRule rule;
  std::string reason;
};

/// [main] The first rule `d` breaks (nullopt when it meets them all). Calls d->schema() (a throwing
/// schema() is a fault). Never reads past abi_version when the ABI differs.
std::optional<DescriptorFault> descriptor_fault(const locus_plugin_descriptor* d);

/// [main] The first problem of a schema a plugin declares, or "" when it is sound.
std::string schema_problem(const ParamSchema& schema);

}  // namespace locus
