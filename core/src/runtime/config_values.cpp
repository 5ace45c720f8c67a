#include "config_values.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <cctype>
#include <system_error>

namespace locus::config_detail {

namespace {

constexpr std::size_t kMaxShownChars = 40;

std::string shorten(std::string_view s) {
  if (s.size() <= kMaxShownChars) return std::string(s);
  return std::string(s.substr(0, kMaxShownChars)) + "...";
}

bool is_digit(char c) { return c >= '0' && c <= '9'; }

/// YAML 1.2 core schema integer: [-+]?[0-9]+ | 0o[0-7]+ | 0x[0-9a-fA-F]+.
bool parse_int(std::string_view t, std::int64_t& out, bool& overflow) {
  overflow = false;
  int base = 10;
  bool negative = false;
  std::string_view digits = t;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'o')) {
    base = t[1] == 'x' ? 16 : 8;
    digits = t.substr(2);
  } else {
    if (!digits.empty() && (digits[0] == '+' || digits[0] == '-')) {
      negative = digits[0] == '-';
      digits.remove_prefix(1);
    }
    if (digits.empty() || !std::all_of(digits.begin(), digits.end(), is_digit)) return false;
  }
  std::uint64_t magnitude = 0;
  const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), magnitude, base);
  if (r.ptr != digits.data() + digits.size()) {
    if (r.ec == std::errc::result_out_of_range) {
      overflow = true;
      return true;
    }
    return false;
  }
  constexpr auto kMax = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  if (negative) {
    if (magnitude > kMax + 1) {
      overflow = true;
      return true;
    }
    out = magnitude == kMax + 1 ? std::numeric_limits<std::int64_t>::min() : -static_cast<std::int64_t>(magnitude);
  } else {
    if (magnitude > kMax) {
      overflow = true;
      return true;
    }
    out = static_cast<std::int64_t>(magnitude);
  }
  return true;
}

/// YAML 1.2 core schema number (integer or float). `finite` is false for .inf/.nan and overflow.
bool parse_float(std::string_view t, double& out, bool& finite) {
  finite = true;
  std::string lower(t);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == ".nan" || lower == ".inf" || lower == "+.inf" || lower == "-.inf") {
    finite = false;
    return true;
  }
  std::int64_t i = 0;
  bool overflow = false;
  if (t.size() > 2 && t[0] == '0' && (t[1] == 'x' || t[1] == 'o')) {
    if (!parse_int(t, i, overflow)) return false;
    out = static_cast<double>(i);
    finite = !overflow;
    return true;
  }
  // [-+]? ( \. [0-9]+ | [0-9]+ ( \. [0-9]* )? ) ( [eE] [-+]? [0-9]+ )?
  std::size_t p = 0;
  if (p < t.size() && (t[p] == '+' || t[p] == '-')) ++p;
  std::size_t mantissa_digits = 0;
  while (p < t.size() && is_digit(t[p])) ++p, ++mantissa_digits;
  if (p < t.size() && t[p] == '.') {
    ++p;
    while (p < t.size() && is_digit(t[p])) ++p, ++mantissa_digits;
  }
  if (mantissa_digits == 0) return false;
  if (p < t.size() && (t[p] == 'e' || t[p] == 'E')) {
    ++p;
    if (p < t.size() && (t[p] == '+' || t[p] == '-')) ++p;
    std::size_t exp_digits = 0;
    while (p < t.size() && is_digit(t[p])) ++p, ++exp_digits;
    if (exp_digits == 0) return false;
  }
  if (p != t.size()) return false;
  // from_chars takes no leading '+'.
  const char* first = t.data() + (t[0] == '+' ? 1 : 0);
  double v = 0.0;
  const auto r = std::from_chars(first, t.data() + t.size(), v);
  if (r.ec == std::errc::result_out_of_range) {
    // Underflow (1e-999) is a harmless zero; overflow (1e999) is not a finite number.
    const auto e = t.find_first_of("eE");
    finite = e != std::string_view::npos && t.find('-', e) != std::string_view::npos;
    out = 0.0;
    return true;
  }
  if (r.ec != std::errc() || r.ptr != t.data() + t.size()) return false;
  out = v;
  finite = std::isfinite(v);
  return true;
}

std::string range_text(const ParamSpec& spec, bool min_exclusive) {
  if (spec.min && spec.max) {
    return std::string(min_exclusive ? " in (" : " in [") + format_number(*spec.min) + ", " +
           format_number(*spec.max) + "]";
  }
  if (spec.min) return std::string(min_exclusive ? " > " : " >= ") + format_number(*spec.min);
  if (spec.max) return " <= " + format_number(*spec.max);
  return {};
}

std::string unit_text(const ParamSpec& spec) { return spec.unit.empty() ? std::string() : " (unit: " + spec.unit + ")"; }

std::string items_text(const ParamSpec& spec) {
  const auto& lo = spec.min_items;
  const auto& hi = spec.max_items;
  if (lo && hi && *lo == *hi) return std::to_string(*lo) + " ";
  if (lo && hi) return std::to_string(*lo) + " to " + std::to_string(*hi) + " ";
  if (lo) return "at least " + std::to_string(*lo) + " ";
  if (hi) return "at most " + std::to_string(*hi) + " ";
  return {};
}

bool in_range(const ParamSpec& spec, double x, bool min_exclusive) {
  if (spec.min && (min_exclusive ? x <= *spec.min : x < *spec.min)) return false;
  if (spec.max && x > *spec.max) return false;
  return true;
}

}  // namespace

std::string format_number(double x) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, x);
  return std::string(buf, r.ptr);
}

std::string expected_text(const ParamSpec& spec, bool min_exclusive) {
  switch (spec.type) {
    case ParamType::Bool: return "a bool (true or false)";
    case ParamType::Int: return "an integer" + range_text(spec, min_exclusive) + unit_text(spec);
    case ParamType::Float: return "a float" + range_text(spec, min_exclusive) + unit_text(spec);
    case ParamType::String: return "a string";
    case ParamType::Enum: return "one of " + join_quoted(spec.choices);
    case ParamType::FloatList:
      return "a list of " + items_text(spec) + "floats" + range_text(spec, false) + unit_text(spec);
  }
  return "a value";
}

std::string element_expected_text(const ParamSpec& spec) {
  return "a float" + range_text(spec, false) + unit_text(spec);
}

std::string got_text(const ScalarText& s) {
  if (s.plain) return "'" + shorten(s.text) + "'";
  return "the quoted string \"" + shorten(s.text) + "\"";
}

std::optional<ParamValue> check_scalar(const ParamSpec& spec, const ScalarText& s, std::string& error,
                                       bool min_exclusive) {
  const auto fail = [&](std::string_view extra = {}) -> std::optional<ParamValue> {
    error = "expected " + expected_text(spec, min_exclusive) + ", got " + got_text(s) + std::string(extra);
    return std::nullopt;
  };
  switch (spec.type) {
    case ParamType::Bool: {
      if (!s.plain) return fail();
      if (s.text == "true" || s.text == "True" || s.text == "TRUE") return ParamValue(true);
      if (s.text == "false" || s.text == "False" || s.text == "FALSE") return ParamValue(false);
      return fail();
    }
    case ParamType::Int: {
      std::int64_t v = 0;
      bool overflow = false;
      if (!s.plain || !parse_int(s.text, v, overflow)) return fail();
      if (overflow) return fail(" (too large)");
      if (!in_range(spec, static_cast<double>(v), min_exclusive)) return fail();
      return ParamValue(v);
    }
    case ParamType::Float: {
      double v = 0.0;
      bool finite = true;
      if (!s.plain || !parse_float(s.text, v, finite)) return fail();
      if (!finite) return fail(" (not a finite number)");
      if (!in_range(spec, v, min_exclusive)) return fail();
      return ParamValue(v);
    }
    case ParamType::String: return ParamValue(s.text);
    case ParamType::Enum: {
      if (std::find(spec.choices.begin(), spec.choices.end(), s.text) != spec.choices.end()) {
        return ParamValue(s.text);
      }
      const std::string guess = closest(s.text, spec.choices);
      return fail(guess.empty() ? std::string() : "; did you mean '" + guess + "'?");
    }
    case ParamType::FloatList: return fail();
  }
  return fail();
}

std::optional<double> check_list_element(const ParamSpec& spec, const ScalarText& s, std::string& error) {
  double v = 0.0;
  bool finite = true;
  const auto fail = [&](std::string_view extra = {}) -> std::optional<double> {
    error = "expected " + element_expected_text(spec) + ", got " + got_text(s) + std::string(extra);
    return std::nullopt;
  };
  if (!s.plain || !parse_float(s.text, v, finite)) return fail();
  if (!finite) return fail(" (not a finite number)");
  if (!in_range(spec, v, false)) return fail();
  return v;
}

std::string check_list_length(const ParamSpec& spec, std::size_t n) {
  if ((spec.min_items && n < *spec.min_items) || (spec.max_items && n > *spec.max_items)) {
    return "expected " + expected_text(spec) + ", got " + std::to_string(n) + (n == 1 ? " item" : " items");
  }
  return {};
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  // Optimal string alignment: insertions, deletions, substitutions and adjacent transpositions.
  // Three rolling rows (one allocation): a row needs the two before it for transpositions.
  const std::size_t n = a.size(), m = b.size();
  std::vector<std::size_t> rows(3 * (m + 1));
  std::size_t* before = rows.data();
  std::size_t* prev = before + (m + 1);
  std::size_t* cur = prev + (m + 1);
  for (std::size_t j = 0; j <= m; ++j) prev[j] = j;
  for (std::size_t i = 1; i <= n; ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= m; ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) cur[j] = std::min(cur[j], before[j - 2] + 1);
    }
    std::size_t* const recycled = before;
    before = prev;
    prev = cur;
    cur = recycled;
  }
  return prev[m];
}

std::string closest(std::string_view name, const std::vector<std::string>& candidates) {
  // A typo: at most a third of the longer word's letters wrong (at least one edit allowed, at most 3).
  // The distance is at least the difference in length, so most candidates (and any absurdly long
  // key a broken file may hold) are ruled out without computing it.
  std::string best;
  std::size_t best_d = std::numeric_limits<std::size_t>::max();
  for (const std::string& c : candidates) {
    const std::size_t limit = std::clamp<std::size_t>(std::max(name.size(), c.size()) / 3, 1, 3);
    const std::size_t length_gap = name.size() > c.size() ? name.size() - c.size() : c.size() - name.size();
    if (length_gap > limit) continue;
    const std::size_t d = edit_distance(name, c);
    if (d <= limit && d < best_d) {
      best = c;
      best_d = d;
    }
  }
  return best;
}

std::string join(const std::vector<std::string>& items, std::string_view sep) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i != 0) out += sep;
    out += items[i];
  }
  return out;
}

std::string join_quoted(const std::vector<std::string>& items) {
  std::string out;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i != 0) out += ", ";
    out += "'" + items[i] + "'";
  }
  return out;
}

std::string unknown_key_message(std::string_view key, const std::vector<std::string>& known) {
  std::string m = "unknown key '" + shorten(key) + "'";
  const std::string guess = closest(key, known);
  if (!guess.empty()) m += "; did you mean '" + guess + "'?";
  m += known.empty() ? std::string(" (no keys are allowed here)") : " (known keys: " + join(known) + ")";
  return m;
}

}  // namespace locus::config_detail
