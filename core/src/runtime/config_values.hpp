// Private helpers of config.cpp: checking one parameter value against its ParamSpec, independent of
// YAML (so key=value strings from a command line get the same rules and messages), and "did you
// mean" suggestions.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "locus/params.hpp"

namespace locus::config_detail {

/// A scalar as written: its text, and whether it was plain (unquoted) YAML. Quoted scalars are
/// strings, never numbers or bools.
struct ScalarText {
  std::string text;
  bool plain = true;
};

/// Shortest round-trip text of a number ("0.5", "44100", "1e-06").
std::string format_number(double x);

/// What a value of `spec` must look like: "a float in [0, 1] (unit: s)", "one of 'a', 'b'", ...
/// `min_exclusive` makes the lower bound exclusive ("(0, 384000]").
std::string expected_text(const ParamSpec& spec, bool min_exclusive = false);
/// For one element of a FloatList: "a float in [0, 1] (unit: Hz)".
std::string element_expected_text(const ParamSpec& spec);

/// How a scalar is shown after "got": 'abc' when plain, the quoted string "abc" otherwise (shortened).
std::string got_text(const ScalarText& s);

/// Checks a scalar against a non-list spec. Returns the value, or nullopt and sets `error` to the full
/// message ("expected ..., got ...").
std::optional<ParamValue> check_scalar(const ParamSpec& spec, const ScalarText& s, std::string& error,
                                       bool min_exclusive = false);
/// Checks one FloatList element (number within min/max).
std::optional<double> check_list_element(const ParamSpec& spec, const ScalarText& s, std::string& error);
/// Checks the length of a FloatList; "" when fine, else the message.
std::string check_list_length(const ParamSpec& spec, std::size_t n);

/// Edit distance (Levenshtein with adjacent transpositions).
std::size_t edit_distance(std::string_view a, std::string_view b);
/// The candidate closest to `name` when it is plausibly a typo of it, else "".
std::string closest(std::string_view name, const std::vector<std::string>& candidates);
/// "a, b, c"
std::string join(const std::vector<std::string>& items, std::string_view sep = ", ");
/// "'a', 'b', 'c'"
std::string join_quoted(const std::vector<std::string>& items);

/// "unknown key 'x'; did you mean 'y'? (known keys: ...)"
std::string unknown_key_message(std::string_view key, const std::vector<std::string>& known);

}  // namespace locus::config_detail
