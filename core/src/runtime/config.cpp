// load_config: parse the node's YAML, load its plugin directories, validate every section against
// the registry's schemas, and report every problem at once (docs/config.md is the reference).
#include "locus/config.hpp"
#include "locus/ids.hpp"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <utility>

#include "config_values.hpp"

namespace locus {

// ------------------------------------------------------------------------------------ errors

std::string ConfigError::format() const {
  std::string out;
  if (!file.empty()) out += file;
  if (line > 0) {
    out += (out.empty() ? "" : ":") + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  }
  if (!out.empty()) out += ": ";
  if (!key.empty()) out += key + ": ";
  out += message;
  return out;
}

namespace {
std::string format_all(const std::vector<ConfigError>& errors) {
  std::string out;
  for (std::size_t i = 0; i < errors.size(); ++i) {
    if (i != 0) out += '\n';
    out += errors[i].format();
  }
  return out;
}
}  // namespace

ConfigErrors::ConfigErrors(std::vector<ConfigError> errors)
    : std::runtime_error(format_all(errors)), errors_(std::move(errors)) {}

// ------------------------------------------------------------------------------------ checker

namespace {

using namespace config_detail;
namespace fs = std::filesystem;

constexpr std::size_t kMaxNameLength = kMaxIdLength;  // ids.hpp: the one rule for ids and names

bool is_plain(const YAML::Node& n) { return n.Tag() == "?" || n.Tag().empty(); }

ScalarText scalar_text(const YAML::Node& n) { return ScalarText{n.Scalar(), is_plain(n)}; }

/// How a node is shown after "got".
std::string got(const YAML::Node& n) {
  if (!n.IsDefined() || n.IsNull()) return "nothing";
  if (n.IsMap()) return "a mapping";
  if (n.IsSequence()) return "a list";
  return got_text(scalar_text(n));
}

std::string id_expected() {
  return "letters, digits, '_' or '-' (at most " + std::to_string(kMaxNameLength) + " characters)";
}

/// "an imu", "a ble", "a sync".
std::string with_article(std::string_view word) {
  const bool vowel = !word.empty() && std::string_view("aeiou").find(word.front()) != std::string_view::npos;
  return (vowel ? "an " : "a ") + std::string(word);
}

std::string plugin_kind_name(std::uint32_t kind) {
  return kind == LOCUS_PLUGIN_DETECTOR ? "detector" : kind == LOCUS_PLUGIN_LOCALIZER ? "localizer" : "plugin";
}

/// A key of a mapping and its value.
struct Entry {
  YAML::Node key;
  YAML::Node value;
  /// Where an error about the value points: the value, or its key when the value is empty (yaml-cpp
  /// puts an empty value's mark at the start of the next line).
  YAML::Mark where() const { return value.IsNull() ? key.Mark() : value.Mark(); }
};

/// The known keys present in a mapping (first occurrence of each).
class Section {
 public:
  explicit Section(YAML::Mark mark) : mark_(mark) {}
  const Entry* find(std::string_view key) const {
    const auto it = entries_.find(key);
    return it == entries_.end() ? nullptr : &it->second;
  }
  /// Where "missing required key" points: the mapping itself.
  YAML::Mark mark() const { return mark_; }
  void add(std::string key, Entry e) { entries_.emplace(std::move(key), std::move(e)); }

 private:
  YAML::Mark mark_;
  std::map<std::string, Entry, std::less<>> entries_;
};

std::string child(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}
std::string index_path(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

class Checker {
 public:
  Checker(std::string file, std::vector<ConfigError>& errors) : file_(std::move(file)), errors_(errors) {}

  void error(const YAML::Mark& m, std::string path, std::string message) {
    ConfigError e;
    e.file = file_;
    // Null marks (-1) mean "unknown": 0.
    e.line = m.line >= 0 ? m.line + 1 : 0;
    e.column = m.column >= 0 ? m.column + 1 : 0;
    e.key = std::move(path);
    e.message = std::move(message);
    errors_.push_back(std::move(e));
  }

  /// Checks that `node` is a mapping (an empty value counts as an empty one) holding only `known` keys,
  /// each once. Returns nullopt (after reporting) when it is not a mapping.
  std::optional<Section> mapping(const YAML::Node& node, const YAML::Mark& where, const std::string& path,
                                 const std::vector<std::string>& known, const std::string& empty_note = {}) {
    if (!node.IsDefined() || node.IsNull()) return Section(where);
    if (!node.IsMap()) {
      error(where, path, "expected a mapping, got " + got(node));
      return std::nullopt;
    }
    Section section(node.Mark());
    std::map<std::string, int, std::less<>> first_line;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const YAML::Node k = it->first;
      if (!k.IsScalar()) {
        error(k.Mark(), path, "expected a key name, got " + got(k));
        continue;
      }
      const std::string& name = k.Scalar();
      const std::string key_path = child(path, name);
      if (const auto seen = first_line.find(name); seen != first_line.end()) {
        error(k.Mark(), key_path, "duplicate key '" + name + "' (first defined at line " +
                                      std::to_string(seen->second) + ")");
        continue;
      }
      first_line.emplace(name, k.Mark().line + 1);
      if (std::find(known.begin(), known.end(), name) == known.end()) {
        std::string m = unknown_key_message(name, known);
        if (known.empty() && !empty_note.empty()) m = "unknown key '" + name + "' (" + empty_note + ")";
        error(k.Mark(), key_path, std::move(m));
        continue;
      }
      section.add(name, Entry{k, it->second});
    }
    return section;
  }

  /// A list (an empty value counts as an empty one); nullopt after reporting when it is something else.
  std::optional<std::vector<YAML::Node>> list(const Entry& e, const std::string& path, std::string_view what) {
    if (e.value.IsNull()) return std::vector<YAML::Node>{};
    if (!e.value.IsSequence()) {
      error(e.where(), path, "expected a list of " + std::string(what) + ", got " + got(e.value));
      return std::nullopt;
    }
    std::vector<YAML::Node> out;
    for (const auto& n : e.value) out.push_back(n);
    return out;
  }

  /// A value of `spec` at `node`; nullopt after reporting.
  std::optional<ParamValue> value(const ParamSpec& spec, const YAML::Node& node, const YAML::Mark& where,
                                  const std::string& path, bool min_exclusive = false) {
    if (spec.type == ParamType::FloatList) {
      if (!node.IsSequence()) {
        error(where, path, "expected " + expected_text(spec) + ", got " + got(node));
        return std::nullopt;
      }
      std::vector<double> out;
      bool ok = true;
      if (std::string m = check_list_length(spec, node.size()); !m.empty()) {
        error(where, path, std::move(m));
        ok = false;
      }
      std::size_t i = 0;
      for (const auto& element : node) {
        const std::string element_path = index_path(path, i++);
        if (!element.IsScalar()) {
          error(element.IsNull() ? where : element.Mark(), element_path,
                "expected " + element_expected_text(spec) + ", got " + got(element));
          ok = false;
          continue;
        }
        std::string m;
        if (const auto v = check_list_element(spec, scalar_text(element), m)) {
          out.push_back(*v);
        } else {
          error(element.Mark(), element_path, std::move(m));
          ok = false;
        }
      }
      if (!ok) return std::nullopt;
      return ParamValue(std::move(out));
    }
    if (!node.IsScalar()) {
      error(where, path, "expected " + expected_text(spec, min_exclusive) + ", got " + got(node));
      return std::nullopt;
    }
    std::string m;
    auto v = check_scalar(spec, scalar_text(node), m, min_exclusive);
    if (!v) error(where, path, std::move(m));
    return v;
  }

  std::optional<ParamValue> value(const ParamSpec& spec, const Entry& e, const std::string& path,
                                  bool min_exclusive = false) {
    return value(spec, e.value, e.where(), path, min_exclusive);
  }

  /// A required or optional string scalar.
  std::optional<std::string> string(const Entry& e, const std::string& path) {
    ParamSpec spec;
    spec.type = ParamType::String;
    const auto v = value(spec, e, path);
    if (!v) return std::nullopt;
    return std::get<std::string>(*v);
  }

  void missing(const Section& s, const std::string& path, std::string_view key) {
    error(s.mark(), child(path, key), "missing required key '" + std::string(key) + "'");
  }

  /// Validates a params mapping against `schema`: defaults filled, required keys present.
  Params params(const ParamSchema& schema, const Entry* e, const YAML::Mark& parent, const std::string& path,
                const std::string& owner) {
    Params out = Params::defaults(schema);
    std::vector<std::string> known;
    for (const ParamSpec& spec : schema) known.push_back(spec.key);
    const YAML::Node node = e != nullptr ? e->value : YAML::Node();
    const YAML::Mark where = e != nullptr ? e->where() : parent;
    const auto section = mapping(node, where, path, known, owner + " takes no parameters");
    if (!section) return out;
    for (const ParamSpec& spec : schema) {
      if (const Entry* v = section->find(spec.key)) {
        if (auto value = this->value(spec, *v, child(path, spec.key))) out.set(spec.key, std::move(*value));
      } else if (spec.required()) {
        missing(*section, path, spec.key);
      }
    }
    return out;
  }

 private:
  std::string file_;
  std::vector<ConfigError>& errors_;
};

// ------------------------------------------------------------------------------------ the schema

const std::vector<std::string> kTopKeys = {"sample_rate_hz", "log_level", "plugin_dirs", "output", "link",
                                           "outputs", "devices", "localizers"};
const std::vector<std::string> kOutputKeys = {"path", "events"};
const std::vector<std::string> kDeviceKeys = {"id", "audio", "imu", "ble", "sync", "playback", "geometry", "detectors"};
const std::vector<std::string> kPlaybackKeys = {"sink", "max_pending", "params"};
const std::vector<std::string> kLinkKeys = {"type", "params"};
const std::vector<std::string> kEventOutputKeys = {"type", "events", "params"};

/// The `geometry:` section's schema (flat lists: a YAML schema has no nested lists).
const ParamSchema& geometry_schema() {
  static const ParamSchema schema{
      float_list_param("mics_m", std::vector<double>{}, -100.0, 100.0, "m",
                       "Microphone positions in the body frame, x y z per audio channel, flattened.", 0, 3 * 32),
      float_list_param("speaker_m", std::vector<double>{}, -100.0, 100.0, "m",
                       "Speaker position in the body frame (x, y, z); empty = none.", 0, 3),
      float_list_param("anchor_m", std::vector<double>{}, -1.0e6, 1.0e6, "m",
                       "Known world position of the device (x, y, z); empty = unknown.", 0, 3),
  };
  return schema;
}
const std::vector<std::string> kSensorKeys = {"source", "queue_capacity", "params"};
const std::vector<std::string> kAudioKeys = {"source", "ring_frames", "block_frames", "params"};
const std::vector<std::string> kComponentKeys = {"plugin", "name", "params"};
const std::vector<std::string> kLogLevels = {"trace", "debug", "info", "warn", "error"};

ParamSpec make_spec(ParamType type, std::optional<double> min, std::optional<double> max, std::string unit = {}) {
  ParamSpec s;
  s.type = type;
  s.min = min;
  s.max = max;
  s.unit = std::move(unit);
  return s;
}

/// A detector or localizer instance being checked, with what naming needs.
struct Component {
  ComponentConfig* config = nullptr;  // set after the vectors stop growing
  std::size_t device = 0;             // index in Config::devices (detectors only)
  bool is_detector = false;
  std::string path;                   // "devices[0].detectors[1]"
  YAML::Mark mark;                    // the component mapping
  std::optional<YAML::Mark> name_mark;  // the explicit name's value
  bool name_ok = true;                // the explicit name is valid
};

class ConfigChecker {
 public:
  ConfigChecker(const std::string& file, const std::string& base_dir, Registry& registry,
                std::vector<ConfigError>& errors)
      : c_(file, errors), base_dir_(base_dir.empty() ? "." : base_dir), registry_(registry) {
    config_.file = file;
  }

  Config run(const YAML::Node& root) {
    if (!root.IsDefined() || root.IsNull()) {
      c_.error(YAML::Mark::null_mark(), "",
               "the file is empty; expected a mapping with at least one device or localizer");
      return std::move(config_);
    }
    const auto top = c_.mapping(root, root.Mark(), "", kTopKeys);
    if (!top) return std::move(config_);

    if (const Entry* e = top->find("sample_rate_hz")) {
      if (const auto v = c_.value(make_spec(ParamType::Float, 0.0, 384000.0, "Hz"), *e, "sample_rate_hz", true)) {
        config_.sample_rate_hz = std::get<double>(*v);
      }
    }
    if (const Entry* e = top->find("log_level")) {
      ParamSpec spec = make_spec(ParamType::Enum, std::nullopt, std::nullopt);
      spec.choices = kLogLevels;
      if (const auto v = c_.value(spec, *e, "log_level")) {
        const auto i = std::find(kLogLevels.begin(), kLogLevels.end(), std::get<std::string>(*v)) - kLogLevels.begin();
        config_.log_level = static_cast<LogLevel>(i);
      }
    }
    if (const Entry* e = top->find("plugin_dirs")) plugin_dirs(*e);
    if (const Entry* e = top->find("output")) output(*e);
    if (const Entry* e = top->find("link")) link(*e);
    if (const Entry* e = top->find("outputs")) outputs(*e);

    // Entries seen in devices and localizers (a list that is not a list counts as seen: it was reported).
    std::size_t entries = 0;
    if (const Entry* e = top->find("devices")) {
      if (const auto items = c_.list(*e, "devices", "devices")) {
        entries += items->size();
        for (std::size_t i = 0; i < items->size(); ++i) device((*items)[i], i, e->where());
      } else {
        ++entries;
      }
    }
    if (const Entry* e = top->find("localizers")) {
      if (const auto items = c_.list(*e, "localizers", "localizers")) {
        entries += items->size();
        for (std::size_t i = 0; i < items->size(); ++i) {
          component((*items)[i], index_path("localizers", i), e->where(), LOCUS_PLUGIN_LOCALIZER, 0);
        }
      } else {
        ++entries;
      }
    }
    if (entries == 0) {
      const Entry* e = top->find("devices");
      c_.error(e != nullptr ? e->where() : top->mark(), "devices", "expected at least one device or one localizer");
    }
    name_instances();
    return std::move(config_);
  }

 private:
  /// When `name` is a backend this build lacks (Registry::find_not_built): "audio source 'jack' is not
  /// available: JACK support was not built in (LOCUS_WITH_JACK=OFF)". "" otherwise (then the caller
  /// says "unknown ...").
  std::string not_built(const std::string& what, const std::string& name) const {
    const NotBuiltBackend* nb = registry_.find_not_built(name);
    return nb == nullptr ? std::string() : what + " '" + name + "' is not available: " + nb->reason;
  }

  void plugin_dirs(const Entry& e) {
    const auto items = c_.list(e, "plugin_dirs", "directories");
    if (!items) return;
    for (std::size_t i = 0; i < items->size(); ++i) {
      const YAML::Node& n = (*items)[i];
      const std::string path = index_path("plugin_dirs", i);
      const YAML::Mark where = n.IsNull() ? e.where() : n.Mark();
      if (!n.IsScalar() || n.Scalar().empty()) {
        c_.error(where, path, "expected a directory, got " + (n.IsScalar() ? std::string("an empty string") : got(n)));
        continue;
      }
      fs::path dir(n.Scalar());
      if (dir.is_relative()) dir = fs::path(base_dir_) / dir;
      const std::string resolved = dir.lexically_normal().string();
      config_.plugin_dirs.push_back(resolved);
      try {
        for (const std::string& failure : registry_.load_directory(resolved)) c_.error(where, path, failure);
      } catch (const std::exception& ex) {
        c_.error(where, path, "plugin directory " + resolved + ": " + ex.what());
      }
    }
  }

  void output(const Entry& e) {
    const auto s = c_.mapping(e.value, e.where(), "output", kOutputKeys);
    if (!s) return;
    if (const Entry* p = s->find("path")) {
      if (auto v = c_.string(*p, "output.path")) {
        if (v->empty()) {
          c_.error(p->where(), "output.path", "expected a file path or \"-\" for stdout, got an empty string");
        } else {
          config_.output.path = std::move(*v);
        }
      }
    }
    if (const Entry* ev = s->find("events")) {
      if (auto events = event_list(*ev, "output.events")) {
        config_.output.events = std::move(*events);
        config_.output.events_given = true;
      }
    }
  }

  /// A list of event type names (no duplicates).
  std::optional<std::vector<EventType>> event_list(const Entry& ev, const std::string& list_path) {
    const auto items = c_.list(ev, list_path, "event types");
    if (!items) return std::nullopt;
    std::vector<std::string> known;
    for (std::size_t t = 0; t < kEventTypeCount; ++t) known.emplace_back(event_type_name(static_cast<EventType>(t)));
    std::vector<EventType> events;
    std::map<EventType, int> first_line;
    for (std::size_t i = 0; i < items->size(); ++i) {
      const YAML::Node& n = (*items)[i];
      const std::string path = index_path(list_path, i);
      const YAML::Mark where = n.IsNull() ? ev.where() : n.Mark();
      EventType t{};
      if (!n.IsScalar()) {
        c_.error(where, path, "expected an event type (" + join(known) + "), got " + got(n));
      } else if (!event_type_from_name(n.Scalar(), t)) {
        std::string m = "unknown event type '" + n.Scalar() + "'";
        if (const std::string guess = closest(n.Scalar(), known); !guess.empty()) m += "; did you mean '" + guess + "'?";
        c_.error(where, path, m + " (known: " + join(known) + ")");
      } else if (const auto seen = first_line.find(t); seen != first_line.end()) {
        c_.error(where, path, "event type '" + n.Scalar() + "' is listed twice (first at line " +
                                  std::to_string(seen->second) + ")");
      } else {
        first_line.emplace(t, where.line + 1);
        events.push_back(t);
      }
    }
    return events;
  }

  /// The shared shape of `playback:`, `link:` and `outputs[i]`: a registry name under `name_key`
  /// (looked up with `find`, listed by `names` in the error) and `params` validated against its
  /// schema. Returns the name ("" when missing) and the validated params.
  template <typename Descriptor>
  std::pair<std::string, Params> named_params(const Section& s, const std::string& path, const char* name_key,
                                              const std::vector<Descriptor>& registered, const std::string& what) {
    std::string name;
    const Descriptor* found = nullptr;
    if (const Entry* e = s.find(name_key)) {
      if (auto v = c_.string(*e, child(path, name_key))) {
        name = *v;
        std::vector<std::string> names;
        for (const Descriptor& d : registered) {
          names.push_back(d.name);
          if (d.name == name) found = &d;
        }
        if (found == nullptr) {
          std::string m = not_built(what, name);
          if (m.empty()) {
            m = "unknown " + what + " '" + name + "'";
            if (const std::string guess = closest(name, names); !guess.empty()) m += "; did you mean '" + guess + "'?";
            m += names.empty() ? " (no " + what + "s are registered)" : " (registered: " + join(names) + ")";
          }
          c_.error(e->where(), child(path, name_key), std::move(m));
        }
      }
    } else {
      c_.missing(s, path, name_key);
    }
    const Entry* params = s.find("params");
    Params out;
    if (found != nullptr) {
      out = c_.params(found->schema, params, s.mark(), child(path, "params"), what + " '" + found->name + "'");
    } else if (params != nullptr && !params->value.IsNull() && !params->value.IsMap()) {
      c_.error(params->where(), child(path, "params"), "expected a mapping, got " + got(params->value));
    }
    return {name, std::move(out)};
  }

  void link(const Entry& e) {
    const auto s = c_.mapping(e.value, e.where(), "link", kLinkKeys);
    if (!s) return;
    auto [type, params] = named_params(*s, "link", "type", registry_.links(), "link");
    config_.link = LinkConfig{std::move(type), std::move(params)};
  }

  void outputs(const Entry& e) {
    const auto items = c_.list(e, "outputs", "outputs");
    if (!items) return;
    for (std::size_t i = 0; i < items->size(); ++i) {
      const std::string path = index_path("outputs", i);
      const YAML::Node& n = (*items)[i];
      const auto s = c_.mapping(n, n.IsNull() ? e.where() : n.Mark(), path, kEventOutputKeys);
      if (!s) continue;
      EventOutputConfig out;
      auto [type, params] = named_params(*s, path, "type", registry_.outputs(), "output");
      out.type = std::move(type);
      out.params = std::move(params);
      if (const Entry* ev = s->find("events")) {
        if (auto events = event_list(*ev, child(path, "events"))) out.events = std::move(*events);
      }
      config_.outputs.push_back(std::move(out));
    }
  }

  std::optional<PlaybackConfig> playback(const Entry& e, const std::string& path) {
    const auto s = c_.mapping(e.value, e.where(), path, kPlaybackKeys);
    if (!s) return std::nullopt;
    PlaybackConfig out;
    auto [sink, params] = named_params(*s, path, "sink", registry_.sinks(), "playback sink");
    out.sink = std::move(sink);
    out.params = std::move(params);
    if (const Entry* q = s->find("max_pending")) {
      if (const auto v = c_.value(make_spec(ParamType::Int, 1.0, 4096.0), *q, child(path, "max_pending"))) {
        out.max_pending = static_cast<std::uint32_t>(std::get<std::int64_t>(*v));
      }
    }
    return out;
  }

  std::optional<GeometryConfig> geometry(const Entry& e, const std::string& path) {
    if (!e.value.IsMap()) {
      c_.error(e.where(), path, "expected a mapping {mics_m, speaker_m, anchor_m}, got " + got(e.value));
      return std::nullopt;
    }
    const Params p = c_.params(geometry_schema(), &e, e.where(), path, "geometry");
    if (!p.has("mics_m") || !p.has("speaker_m") || !p.has("anchor_m")) return std::nullopt;  // reported
    GeometryConfig g;
    bool ok = true;
    const auto mark_of = [&](const char* key) {
      const YAML::Node n = e.value[key];
      return n.IsDefined() && !n.IsNull() ? n.Mark() : e.where();
    };
    const std::vector<double>& mics = p.get_floats("mics_m");
    if (mics.size() % 3 != 0) {
      c_.error(mark_of("mics_m"), child(path, "mics_m"),
               "expected x, y, z per microphone (a multiple of 3 numbers), got " + std::to_string(mics.size()));
      ok = false;
    }
    for (std::size_t i = 0; i + 2 < mics.size(); i += 3) g.mics_m.push_back({mics[i], mics[i + 1], mics[i + 2]});
    auto point = [&](const char* key, std::optional<std::array<double, 3>>& out) {
      const std::vector<double>& v = p.get_floats(key);
      if (v.empty()) return true;
      if (v.size() != 3) {
        c_.error(mark_of(key), child(path, key), "expected 3 numbers [x, y, z] or an empty list, got " +
                                                  std::to_string(v.size()));
        return false;
      }
      out = std::array<double, 3>{v[0], v[1], v[2]};
      return true;
    };
    ok = point("speaker_m", g.speaker_m) && ok;
    ok = point("anchor_m", g.anchor_m) && ok;
    if (!ok) return std::nullopt;
    return g;
  }

  void device(const YAML::Node& node, std::size_t index, const YAML::Mark& list_mark) {
    const std::string path = index_path("devices", index);
    const YAML::Mark mark = node.IsNull() ? list_mark : node.Mark();
    const auto s = c_.mapping(node, mark, path, kDeviceKeys);
    DeviceConfig dev;
    const std::size_t device_index = config_.devices.size();
    if (!s) {
      config_.devices.push_back(std::move(dev));
      return;
    }
    if (const Entry* e = s->find("id")) {
      if (auto id = c_.string(*e, child(path, "id"))) {
        if (!valid_id(*id) && *id != kTemplateDeviceId) {
          c_.error(e->where(), child(path, "id"), "expected a device id of " + id_expected() + ", got " +
                                                      got_text(scalar_text(e->value)));
        } else if (const auto seen = device_lines_.find(*id); seen != device_lines_.end()) {
          c_.error(e->where(), child(path, "id"), "duplicate device id '" + *id + "' (first defined at line " +
                                                      std::to_string(seen->second) + ")");
        } else {
          device_lines_.emplace(*id, e->where().line + 1);
        }
        dev.id = std::move(*id);
      }
    } else {
      c_.missing(*s, path, "id");
    }
    if (const Entry* e = s->find("audio")) dev.audio = audio(*e, child(path, "audio"));
    for (const SensorKind kind : {SensorKind::Imu, SensorKind::Ble, SensorKind::Sync}) {
      const std::string key(sensor_kind_name(kind));
      if (const Entry* e = s->find(key)) dev.sensor(kind) = sensor(*e, child(path, key), kind);
    }
    if (const Entry* e = s->find("playback")) dev.playback = playback(*e, child(path, "playback"));
    if (const Entry* e = s->find("geometry")) dev.geometry = geometry(*e, child(path, "geometry"));
    config_.devices.push_back(std::move(dev));
    if (const Entry* e = s->find("detectors")) {
      const std::string list_path = child(path, "detectors");
      if (const auto items = c_.list(*e, list_path, "detectors")) {
        for (std::size_t i = 0; i < items->size(); ++i) {
          component((*items)[i], index_path(list_path, i), e->where(), LOCUS_PLUGIN_DETECTOR, device_index);
        }
      }
    }
  }

  std::optional<AudioConfig> audio(const Entry& e, const std::string& path) {
    const auto s = c_.mapping(e.value, e.where(), path, kAudioKeys);
    if (!s) return std::nullopt;
    AudioConfig a;
    const SourceDescriptor* source = nullptr;
    if (const Entry* src = s->find("source")) {
      if (auto name = c_.string(*src, child(path, "source"))) {
        source = registry_.find_source(*name);
        if (source == nullptr) {
          std::string m = not_built("audio source", *name);
          if (m.empty()) {
            std::vector<std::string> names;
            for (const SourceDescriptor& d : registry_.sources()) names.push_back(d.name);
            m = "unknown audio source '" + *name + "'";
            if (const std::string guess = closest(*name, names); !guess.empty()) m += "; did you mean '" + guess + "'?";
            m += names.empty() ? std::string(" (no audio sources are registered)") : " (registered: " + join(names) + ")";
          }
          c_.error(src->where(), child(path, "source"), std::move(m));
        }
        a.source = std::move(*name);
      }
    } else {
      c_.missing(*s, path, "source");
    }
    const Entry* ring = s->find("ring_frames");
    const Entry* block = s->find("block_frames");
    bool ring_ok = true;
    if (ring != nullptr) {
      const auto v = c_.value(make_spec(ParamType::Int, 1024.0, 16777216.0), *ring, child(path, "ring_frames"));
      if (v) a.ring_frames = static_cast<std::uint32_t>(std::get<std::int64_t>(*v));
      ring_ok = v.has_value();
    }
    if (block != nullptr) {
      const auto v = c_.value(make_spec(ParamType::Int, 16.0, 65536.0), *block, child(path, "block_frames"));
      if (v) {
        a.block_frames = static_cast<std::uint32_t>(std::get<std::int64_t>(*v));
        if (ring_ok && a.block_frames > a.ring_frames / 2) {
          c_.error(block->where(), child(path, "block_frames"),
                   "expected at most half of ring_frames (" + std::to_string(a.ring_frames / 2) + "), got '" +
                       block->value.Scalar() + "'");
        }
      }
    }
    const Entry* params = s->find("params");
    if (source != nullptr) {
      a.params = c_.params(source->schema, params, s->mark(), child(path, "params"),
                           "audio source '" + source->name + "'");
    } else if (params != nullptr && !params->value.IsNull() && !params->value.IsMap()) {
      c_.error(params->where(), child(path, "params"), "expected a mapping, got " + got(params->value));
    }
    return a;
  }

  std::optional<SensorConfig> sensor(const Entry& e, const std::string& path, SensorKind kind) {
    const auto s = c_.mapping(e.value, e.where(), path, kSensorKeys);
    if (!s) return std::nullopt;
    SensorConfig out;
    const SensorSourceDescriptor* source = nullptr;
    const std::string kind_name(sensor_kind_name(kind));
    if (const Entry* src = s->find("source")) {
      if (auto name = c_.string(*src, child(path, "source"))) {
        source = registry_.find_sensor_source(*name);
        std::vector<std::string> names;
        for (const SensorSourceDescriptor& d : registry_.sensor_sources()) {
          if (d.kind == kind) names.push_back(d.name);
        }
        if (source == nullptr || source->kind != kind) {
          std::string m = source == nullptr ? not_built(kind_name + " source", *name) : std::string();
          if (m.empty()) {
            m = source == nullptr ? "unknown " + kind_name + " source '" + *name + "'"
                                  : "'" + *name + "' is " + with_article(sensor_kind_name(source->kind)) +
                                        " source, not " + with_article(kind_name) + " source";
            if (const std::string guess = closest(*name, names); !guess.empty() && guess != *name) {
              m += "; did you mean '" + guess + "'?";
            }
            m += names.empty() ? " (no " + kind_name + " sources are registered)" : " (registered: " + join(names) + ")";
          }
          c_.error(src->where(), child(path, "source"), std::move(m));
          source = nullptr;
        }
        out.source = std::move(*name);
      }
    } else {
      c_.missing(*s, path, "source");
    }
    if (const Entry* q = s->find("queue_capacity")) {
      if (const auto v = c_.value(make_spec(ParamType::Int, 16.0, 16777216.0), *q, child(path, "queue_capacity"))) {
        out.queue_capacity = static_cast<std::uint32_t>(std::get<std::int64_t>(*v));
      }
    }
    const Entry* params = s->find("params");
    if (source != nullptr) {
      out.params = c_.params(source->schema, params, s->mark(), child(path, "params"),
                             kind_name + " source '" + source->name + "'");
    } else if (params != nullptr && !params->value.IsNull() && !params->value.IsMap()) {
      c_.error(params->where(), child(path, "params"), "expected a mapping, got " + got(params->value));
    }
    return out;
  }

  void component(const YAML::Node& node, const std::string& path, const YAML::Mark& list_mark, std::uint32_t kind,
                 std::size_t device_index) {
    const YAML::Mark mark = node.IsNull() ? list_mark : node.Mark();
    const auto s = c_.mapping(node, mark, path, kComponentKeys);
    ComponentConfig cfg;
    Component meta;
    meta.device = device_index;
    meta.is_detector = kind == LOCUS_PLUGIN_DETECTOR;
    meta.path = path;
    meta.mark = s ? s->mark() : mark;
    if (s) {
      const locus_plugin_descriptor* d = nullptr;
      if (const Entry* p = s->find("plugin")) {
        if (auto name = c_.string(*p, child(path, "plugin"))) {
          d = registry_.find_plugin(*name);
          if (d == nullptr) {
            std::vector<std::string> names;
            for (const auto& entry : registry_.plugins()) {
              if (entry.descriptor->kind == kind) names.emplace_back(entry.descriptor->name);
            }
            std::string m = "unknown plugin '" + *name + "'";
            if (const std::string guess = closest(*name, names); !guess.empty()) m += "; did you mean '" + guess + "'?";
            m += names.empty() ? " (no " + plugin_kind_name(kind) + "s are registered)"
                               : " (registered " + plugin_kind_name(kind) + "s: " + join(names) + ")";
            c_.error(p->where(), child(path, "plugin"), std::move(m));
          } else if (d->kind != kind) {
            c_.error(p->where(), child(path, "plugin"),
                     "plugin '" + *name + "' is a " + plugin_kind_name(d->kind) + ", not a " + plugin_kind_name(kind));
            d = nullptr;
          }
          cfg.plugin = std::move(*name);
        }
      } else {
        c_.missing(*s, path, "plugin");
      }
      if (const Entry* n = s->find("name")) {
        meta.name_mark = n->where();
        meta.name_ok = false;
        if (auto name = c_.string(*n, child(path, "name"))) {
          if (!valid_id(*name)) {
            c_.error(n->where(), child(path, "name"),
                     "expected an instance name of " + id_expected() + ", got " + got_text(scalar_text(n->value)));
          } else {
            meta.name_ok = true;
          }
          cfg.name = std::move(*name);
        }
      }
      if (d != nullptr) {
        cfg.params = c_.params(*d->schema(), s->find("params"), s->mark(), child(path, "params"),
                               "plugin '" + cfg.plugin + "'");
      } else if (const Entry* params = s->find("params");
                 params != nullptr && !params->value.IsNull() && !params->value.IsMap()) {
        c_.error(params->where(), child(path, "params"), "expected a mapping, got " + got(params->value));
      }
    }
    if (meta.is_detector) {
      config_.devices[device_index].detectors.push_back(std::move(cfg));
    } else {
      config_.localizers.push_back(std::move(cfg));
    }
    components_.push_back(std::move(meta));
  }

  /// Default instance names, then uniqueness over the whole node.
  void name_instances() {
    // Point every component at its config, now that the vectors are complete (same order as pushed).
    std::vector<std::size_t> next_detector(config_.devices.size(), 0);
    std::size_t next_localizer = 0;
    for (Component& m : components_) {
      m.config = m.is_detector ? &config_.devices[m.device].detectors[next_detector[m.device]++]
                               : &config_.localizers[next_localizer++];
    }
    // How many devices use each detector plugin.
    std::map<std::string, std::set<std::size_t>> devices_using;
    for (const Component& m : components_) {
      if (m.is_detector && !m.config->plugin.empty()) devices_using[m.config->plugin].insert(m.device);
    }
    std::map<std::string, int, std::less<>> first_line;
    for (Component& m : components_) {
      ComponentConfig& cfg = *m.config;
      const std::string name_path = child(m.path, "name");
      bool defaulted = false;
      if (!m.name_mark) {
        if (cfg.plugin.empty()) continue;  // already reported
        defaulted = true;
        cfg.name = cfg.plugin;
        const std::string& id = config_.devices.empty() || !m.is_detector ? std::string() : config_.devices[m.device].id;
        if (m.is_detector && devices_using[cfg.plugin].size() > 1 && !id.empty()) cfg.name += "_" + id;
        if (cfg.name.size() > kMaxNameLength) {
          c_.error(m.mark, name_path, "the default instance name '" + cfg.name + "' is longer than " +
                                          std::to_string(kMaxNameLength) + " characters; set 'name'");
          continue;
        }
      } else if (!m.name_ok) {
        continue;  // already reported
      }
      const YAML::Mark where = m.name_mark ? *m.name_mark : m.mark;
      if (const auto seen = first_line.find(cfg.name); seen != first_line.end()) {
        std::string msg = "duplicate instance name '" + cfg.name + "' (first defined at line " +
                          std::to_string(seen->second) + ")";
        if (defaulted) msg += "; it is the default name, set 'name' to tell them apart";
        c_.error(where, name_path, std::move(msg));
      } else {
        first_line.emplace(cfg.name, where.line + 1);
      }
    }
  }

  Checker c_;
  std::string base_dir_;
  Registry& registry_;
  Config config_;
  std::map<std::string, int, std::less<>> device_lines_;
  std::vector<Component> components_;
};

[[noreturn]] void throw_one(const std::string& file, int line, int column, std::string message) {
  ConfigError e;
  e.file = file;
  e.line = line;
  e.column = column;
  e.message = std::move(message);
  throw ConfigErrors({std::move(e)});
}

/// Counts the documents of a YAML stream and where the second one starts. An empty document (a lone
/// null) after the first ends the count: yaml-cpp 0.7's parser keeps returning such documents forever
/// on some malformed input (a lone ',': jbeder/yaml-cpp#1040; LoadAll then allocates
/// until the machine runs out of memory; fixed upstream by #1319, after Debian 12's 0.7).
class DocumentCounter final : public YAML::EventHandler {
 public:
  void OnDocumentStart(const YAML::Mark&) override {
    ++documents;
    content = false;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { node(m); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t, const std::string&) override { node(m); }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(m);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(m);
  }
  void OnMapEnd() override {}

  int documents = 0;
  bool content = false;  ///< the current document holds more than a null
  YAML::Mark start;      ///< where the current document's first node is

 private:
  void node(const YAML::Mark& m) {
    if (!content) start = m;
    content = true;
  }
};

/// The first document of `text` (null when there is none) and, when a second non-empty one follows,
/// its start. Never loops: YAML::Load builds one document, the counter stops at the second.
struct Documents {
  YAML::Node first;
  int count = 0;                        ///< the first and every non-empty one after it
  std::optional<YAML::Mark> second_at;  ///< set when count > 1
};
Documents load_documents(const std::string& text) {
  Documents d;
  d.first = YAML::Load(text);
  std::istringstream in(text);
  YAML::Parser parser(in);
  DocumentCounter counter;
  while (parser.HandleNextDocument(counter)) {
    if (counter.documents == 1) {
      d.count = 1;
      continue;
    }
    if (!counter.content) break;  // an empty document after the first: the end (or yaml-cpp looping)
    ++d.count;
    if (!d.second_at) d.second_at = counter.start;
  }
  return d;
}

}  // namespace

// ------------------------------------------------------------------------------------ entry points

Config load_config_string(std::string_view yaml, const std::string& name, Registry& registry,
                          const std::string& base_dir) {
  Documents docs;
  try {
    docs = load_documents(std::string(yaml));
  } catch (const YAML::ParserException& e) {
    throw_one(name, e.mark.line >= 0 ? e.mark.line + 1 : 0, e.mark.column >= 0 ? e.mark.column + 1 : 0,
              "YAML syntax error: " + e.msg);
  } catch (const YAML::Exception& e) {
    throw_one(name, e.mark.line >= 0 ? e.mark.line + 1 : 0, e.mark.column >= 0 ? e.mark.column + 1 : 0,
              "cannot parse YAML: " + e.msg);
  }
  if (docs.second_at) {
    const YAML::Mark m = *docs.second_at;
    throw_one(name, m.line >= 0 ? m.line + 1 : 0, m.column >= 0 ? m.column + 1 : 0,
              "expected one YAML document, found " + std::to_string(docs.count) + " (remove the '---' separators)");
  }
  std::vector<ConfigError> errors;
  ConfigChecker checker(name, base_dir, registry, errors);
  Config config = checker.run(docs.first);
  if (!errors.empty()) {
    std::stable_sort(errors.begin(), errors.end(), [](const ConfigError& a, const ConfigError& b) {
      return std::pair(a.line, a.column) < std::pair(b.line, b.column);
    });
    throw ConfigErrors(std::move(errors));
  }
  return config;
}

Config load_config(const std::string& path, Registry& registry) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw_one(path, 0, 0, "cannot read the config file: it is a directory");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_one(path, 0, 0, std::string("cannot read the config file: ") + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw_one(path, 0, 0, std::string("cannot read the config file: ") + std::strerror(errno));
  std::string base = fs::path(path).parent_path().string();
  if (base.empty()) base = ".";
  return load_config_string(text.str(), path, registry, base);
}

Params validate_params(const ParamSchema& schema, const std::vector<std::pair<std::string, std::string>>& kv,
                       std::vector<ConfigError>& errors) {
  Params out = Params::defaults(schema);
  std::vector<std::string> known;
  for (const ParamSpec& spec : schema) known.push_back(spec.key);
  const auto error = [&errors](const std::string& key, std::string message) {
    ConfigError e;
    e.key = key;
    e.message = std::move(message);
    errors.push_back(std::move(e));
  };
  std::set<std::string, std::less<>> seen;
  for (const auto& [key, text] : kv) {
    // (by name, not by capture: clang 14, which builds the fuzz targets, cannot capture a structured binding)
    const auto spec = std::find_if(schema.begin(), schema.end(), [&k = key](const ParamSpec& s) { return s.key == k; });
    if (spec == schema.end()) {
      error(key, unknown_key_message(key, known));
      continue;
    }
    if (!seen.insert(key).second) {
      error(key, "duplicate key '" + key + "' (given more than once)");
      continue;
    }
    if (spec->type != ParamType::FloatList) {
      std::string m;
      if (auto v = check_scalar(*spec, ScalarText{text, true}, m)) {
        out.set(key, std::move(*v));
      } else {
        error(key, std::move(m));
      }
      continue;
    }
    // A list: "1, 2, 3" or "[1, 2, 3]".
    std::string_view body(text);
    const auto trim = [](std::string_view s) {
      while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
      while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
      return s;
    };
    body = trim(body);
    if (body.size() >= 2 && body.front() == '[' && body.back() == ']') body = trim(body.substr(1, body.size() - 2));
    std::vector<double> values;
    bool ok = true;
    std::size_t count = 0;
    if (!body.empty()) {
      std::size_t start = 0;
      while (true) {
        const std::size_t comma = body.find(',', start);
        const std::string_view item = trim(body.substr(start, comma == std::string_view::npos ? body.npos : comma - start));
        std::string m;
        if (const auto v = check_list_element(*spec, ScalarText{std::string(item), true}, m)) {
          values.push_back(*v);
        } else {
          error(key + "[" + std::to_string(count) + "]", std::move(m));
          ok = false;
        }
        ++count;
        if (comma == std::string_view::npos) break;
        start = comma + 1;
      }
    }
    if (std::string m = check_list_length(*spec, count); !m.empty()) {
      error(key, std::move(m));
      ok = false;
    }
    if (ok) out.set(key, std::move(values));
  }
  for (const ParamSpec& spec : schema) {
    if (spec.required() && seen.find(spec.key) == seen.end()) {
      error(spec.key, "missing required key '" + spec.key + "'");
    }
  }
  return out;
}

}  // namespace locus
