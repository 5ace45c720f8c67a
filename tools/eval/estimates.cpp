// JSON-lines reader for estimates and steps (docs/events.md), strict with file:line:column messages.
#include "locus/eval/estimates.hpp"

#include <cmath>
#include <fstream>
#include <iostream>
#include <limits>

#include <nlohmann/json.hpp>

#include "locus/eval/error.hpp"
#include "locus/numbers.hpp"

namespace locus::eval {

namespace {

constexpr std::size_t kMaxListed = 50;

using json = nlohmann::json;

/// A problem in one line; `key` locates the column when the key text is found in the line.
struct LineError {
  std::string key;
  std::string message;
};

const char* kind_of(const json& v) {
  switch (v.type()) {
    case json::value_t::null: return "null";
    case json::value_t::boolean: return "a boolean";
    case json::value_t::string: return "a string";
    case json::value_t::array: return "an array";
    case json::value_t::object: return "an object";
    case json::value_t::discarded: return "nothing";
    default: return "a number";
  }
}

std::string req_string(const json& j, const char* key, bool non_empty = false) {
  auto it = j.find(key);
  if (it == j.end()) throw LineError{"", std::string("missing key '") + key + "' (expected a string)"};
  if (!it->is_string()) throw LineError{key, std::string("key '") + key + "': expected a string, got " + kind_of(*it)};
  std::string s = it->get<std::string>();
  if (non_empty && s.empty()) throw LineError{key, std::string("key '") + key + "': expected a non-empty string"};
  return s;
}

std::string opt_string(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end() || it->is_null()) return {};
  if (!it->is_string()) throw LineError{key, std::string("key '") + key + "': expected a string or null, got " + kind_of(*it)};
  return it->get<std::string>();
}

double req_number(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end()) throw LineError{"", std::string("missing key '") + key + "' (expected a number)"};
  if (!it->is_number()) throw LineError{key, std::string("key '") + key + "': expected a number, got " + kind_of(*it)};
  const double v = it->get<double>();
  if (!std::isfinite(v)) throw LineError{key, std::string("key '") + key + "': expected a finite number"};
  return v;
}

/// Number or null (NaN); an absent key is NaN as well (consumers tolerate producers that omit).
double opt_number(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end() || it->is_null()) return kNaN;
  if (!it->is_number()) throw LineError{key, std::string("key '") + key + "': expected a number or null, got " + kind_of(*it)};
  return it->get<double>();
}

EstimateRecord parse_estimate(const json& j) {
  EstimateRecord e;
  e.plugin = req_string(j, "plugin", true);
  e.reference = req_string(j, "reference");
  e.frame = req_string(j, "frame", true);
  e.target = req_string(j, "target", true);
  e.t_s = req_number(j, "t_s");
  auto it = j.find("position_m");
  if (it == j.end()) throw LineError{"", "missing key 'position_m' (expected an array of 2 or 3 numbers)"};
  if (!it->is_array() || (it->size() != 2 && it->size() != 3))
    throw LineError{"position_m", std::string("key 'position_m': expected an array of 2 or 3 numbers (or nulls), got ") +
                                      (it->is_array() ? "an array of " + std::to_string(it->size()) : std::string(kind_of(*it)))};
  e.dims = static_cast<int>(it->size());
  e.position_m = {kNaN, kNaN, 0.0};
  for (std::size_t i = 0; i < it->size(); ++i) {
    const json& v = (*it)[i];
    if (v.is_null()) {
      e.position_m[i] = kNaN;
    } else if (v.is_number()) {
      e.position_m[i] = v.get<double>();
    } else {
      throw LineError{"position_m", "key 'position_m': element " + std::to_string(i) + " is " + kind_of(v) +
                                        ", expected a number or null"};
    }
  }
  e.direction_rad = opt_number(j, "direction_rad");
  e.distance_m = opt_number(j, "distance_m");
  e.std_m = opt_number(j, "std_m");
  e.confidence = opt_number(j, "confidence");
  e.direction_std_rad = opt_number(j, "direction_std_rad");
  e.distance_std_m = opt_number(j, "distance_std_m");
  if (auto fl = j.find("flags"); fl != j.end() && !fl->is_null()) {
    if (!fl->is_array()) throw LineError{"flags", std::string("key 'flags': expected a list of strings, got ") + kind_of(*fl)};
    for (const json& f : *fl) {
      if (!f.is_string()) throw LineError{"flags", std::string("key 'flags': element is ") + kind_of(f) + ", expected a string"};
      e.flags.push_back(f.get<std::string>());
    }
  }
  auto los = j.find("los");
  if (los != j.end() && !los->is_null()) {
    if (!los->is_boolean()) throw LineError{"los", std::string("key 'los': expected true, false or null, got ") + kind_of(*los)};
    e.los = los->get<bool>();
  }
  return e;
}

StepRecord parse_step(const json& j) {
  StepRecord s;
  s.device = req_string(j, "device", true);
  s.detector = opt_string(j, "detector");
  s.t_s = req_number(j, "t_s");
  s.stride_m = opt_number(j, "stride_m");
  return s;
}

/// "parse error at line 1, column 7: syntax error while parsing ..." → "syntax error while parsing ..."
std::string json_detail(const json::parse_error& e) {
  std::string w = e.what();
  const auto col = w.find("column ");
  if (col != std::string::npos) {
    const auto colon = w.find(": ", col);
    if (colon != std::string::npos) return w.substr(colon + 2);
  }
  const auto bracket = w.find("] ");
  return bracket == std::string::npos ? w : w.substr(bracket + 2);
}

}  // namespace

bool EstimateRecord::has_position() const noexcept {
  for (int i = 0; i < dims; ++i)
    if (!std::isfinite(position_m[static_cast<std::size_t>(i)])) return false;
  return true;
}

EstimatesFile parse_estimates(std::istream& in, const std::string& name) {
  EstimatesFile out;
  out.path = name;
  std::vector<std::string> errors;
  std::size_t error_count = 0;
  auto report = [&](int line, std::size_t column, const std::string& message) {
    ++error_count;
    if (errors.size() < kMaxListed)
      errors.push_back(name + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message);
  };

  std::string text;
  int line_no = 0;
  while (std::getline(in, text)) {
    ++line_no;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    if (text.find_first_not_of(" \t") == std::string::npos) continue;
    ++out.lines;
    json j;
    try {
      j = json::parse(text);
    } catch (const json::parse_error& e) {
      report(line_no, e.byte == 0 ? 1 : e.byte, "not valid JSON: " + json_detail(e));
      continue;
    } catch (const json::exception& e) {  // out_of_range: a number beyond double (1e400)
      const std::string w = e.what();
      const auto bracket = w.find("] ");
      report(line_no, 1, "not valid JSON: " + (bracket == std::string::npos ? w : w.substr(bracket + 2)));
      continue;
    }
    if (!j.is_object()) {
      report(line_no, 1, std::string("expected a JSON object (one event per line), got ") + kind_of(j));
      continue;
    }
    auto type = j.find("type");
    if (type == j.end() || !type->is_string()) {
      report(line_no, 1, "missing string key 'type' (every event has one, docs/events.md)");
      continue;
    }
    const std::string t = type->get<std::string>();
    try {
      if (t == "estimate") {
        EstimateRecord e = parse_estimate(j);
        e.line = line_no;
        out.estimates.push_back(std::move(e));
      } else if (t == "step") {
        StepRecord s = parse_step(j);
        s.line = line_no;
        out.steps.push_back(std::move(s));
      } else {
        ++out.other_events[t];
      }
    } catch (const LineError& e) {
      std::size_t column = 1;
      if (!e.key.empty()) {
        const auto pos = text.find("\"" + e.key + "\"");
        if (pos != std::string::npos) column = pos + 1;
      }
      report(line_no, column, t + " event: " + e.message);
    }
  }
  if (in.bad()) errors.push_back(name + ": read error after line " + std::to_string(line_no));
  if (error_count > kMaxListed)
    errors.push_back(name + ": ... and " + std::to_string(error_count - kMaxListed) + " more malformed lines");
  if (!errors.empty()) throw InputError(std::move(errors));
  return out;
}

EstimatesFile read_estimates(const std::string& path) {
  if (path == "-") return parse_estimates(std::cin, "<stdin>");
  std::ifstream f(path);
  if (!f) throw InputError(path + ": cannot open the estimates file");
  return parse_estimates(f, path);
}

}  // namespace locus::eval
