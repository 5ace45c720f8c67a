// scene.yaml: load (validate everything, collect every issue with line:column) and write.
//
// Reading is strict about what the format requires and tolerant about what it allows: unknown keys
// are ignored, `emits` entries of an unknown type are kept (require_known_signal_types() turns them
// into errors for a consumer that needs them). Numbers are written in their shortest round-trip form,
// so load_scene(write_scene_yaml(x)) reproduces x exactly.
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "locus/ids.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"

namespace locus::scene {

namespace {

const char* const kKnownTypes[] = {"lfm", "gold", "multitone", "ble"};
constexpr int kGoldDegrees[] = {5, 6, 7, 9, 10, 11};

std::string shown(const YAML::Node& n) {
  if (n.IsScalar()) return "'" + n.Scalar() + "'";
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "nothing";
}

/// Collects issues while walking the YAML tree.
class Checker {
 public:
  explicit Checker(std::string file) : file_(std::move(file)) {}

  void issue(const YAML::Node& at, const std::string& where, const std::string& msg) {
    SceneIssue is;
    is.file = file_;
    const YAML::Mark m = at.IsDefined() ? at.Mark() : YAML::Mark::null_mark();
    if (!m.is_null()) {
      is.line = m.line + 1;
      is.column = m.column + 1;
    }
    is.message = where.empty() ? msg : where + ": " + msg;
    issues.push_back(std::move(is));
  }

  /// `parent[key]`; records "missing required key" at the parent when absent.
  YAML::Node required(const YAML::Node& parent, const char* key, const std::string& where, const std::string& expect) {
    YAML::Node n = parent[key];
    if (!n.IsDefined() || n.IsNull()) {
      issue(parent, where, std::string("missing required key '") + key + "' (expected " + expect + ")");
      return YAML::Node(YAML::NodeType::Undefined);
    }
    return n;
  }

  std::optional<double> number(const YAML::Node& n, const std::string& where) {
    if (!n.IsScalar()) {
      issue(n, where, "expected a number, got " + shown(n));
      return std::nullopt;
    }
    double v = 0.0;
    if (!YAML::convert<double>::decode(n, v) || !std::isfinite(v)) {
      issue(n, where, "expected a number, got " + shown(n));
      return std::nullopt;
    }
    return v;
  }

  std::optional<long long> integer(const YAML::Node& n, const std::string& where) {
    long long v = 0;
    if (!n.IsScalar() || !YAML::convert<long long>::decode(n, v)) {
      issue(n, where, "expected an integer, got " + shown(n));
      return std::nullopt;
    }
    return v;
  }

  std::optional<std::string> string(const YAML::Node& n, const std::string& where) {
    if (!n.IsScalar()) {
      issue(n, where, "expected a string, got " + shown(n));
      return std::nullopt;
    }
    return n.Scalar();
  }

  std::optional<Vec3> vec3(const YAML::Node& n, const std::string& where, const char* what = "3 numbers [x, y, z]") {
    if (!n.IsSequence() || n.size() != 3) {
      issue(n, where,
            std::string("expected ") + what + ", got " +
                (n.IsSequence() ? std::to_string(n.size()) + " element" + (n.size() == 1 ? "" : "s") : shown(n)));
      return std::nullopt;
    }
    Vec3 v{};
    bool ok = true;
    for (std::size_t i = 0; i < 3; ++i) {
      auto x = number(n[i], where + "[" + std::to_string(i) + "]");
      if (x) v[i] = *x;
      else ok = false;
    }
    if (!ok) return std::nullopt;
    return v;
  }

  std::vector<SceneIssue> issues;

 private:
  std::string file_;
};

dsp::SignalSpec parse_signal(Checker& ck, const YAML::Node& e, const std::string& where) {
  dsp::SignalSpec s;
  if (!e.IsMap()) {
    ck.issue(e, where, "expected a mapping {type: ..., ...}, got " + shown(e));
    return s;
  }
  const YAML::Node tn = ck.required(e, "type", where, "lfm, gold, multitone, ble or a project type");
  if (!tn.IsDefined()) return s;
  if (auto t = ck.string(tn, where + ".type")) s.type = *t;
  auto num = [&](const char* key, double& out, bool req, double lo, double hi, const char* range) {
    YAML::Node n = req ? ck.required(e, key, where, std::string("'") + key + "' for type " + s.type) : e[key];
    if (!n.IsDefined() || n.IsNull()) return;
    auto v = ck.number(n, where + "." + key);
    if (!v) return;
    if (*v < lo || *v > hi) {
      ck.issue(n, where + "." + key, "value " + format_double(*v) + " out of range (expected " + range + ")");
      return;
    }
    out = *v;
  };
  auto integer = [&](const char* key, int& out, long long lo, long long hi, const std::string& range) {
    YAML::Node n = ck.required(e, key, where, std::string("'") + key + "' for type " + s.type);
    if (!n.IsDefined()) return;
    auto v = ck.integer(n, where + "." + key);
    if (!v) return;
    if (*v < lo || *v > hi) {
      ck.issue(n, where + "." + key, "value " + std::to_string(*v) + " out of range (expected " + range + ")");
      return;
    }
    out = static_cast<int>(*v);
  };
  constexpr double kInf = 1e300;
  if (s.type == "lfm") {
    num("f0", s.f0_hz, true, 0.0, kInf, ">= 0 Hz");
    num("f1", s.f1_hz, true, 0.0, kInf, ">= 0 Hz");
    num("duration", s.duration_s, true, 1e-12, kInf, "> 0 s");
    num("fade", s.fade_s, false, 0.0, kInf, ">= 0 s");
    num("amplitude", s.amplitude, false, 0.0, 1.0, "0..1");
  } else if (s.type == "multitone") {
    const YAML::Node tn2 = ck.required(e, "tones_hz", where, "a list of frequencies in Hz");
    if (tn2.IsDefined()) {
      if (!tn2.IsSequence() || tn2.size() == 0) {
        ck.issue(tn2, where + ".tones_hz", "expected a non-empty list of frequencies in Hz, got " + shown(tn2));
      } else {
        for (std::size_t i = 0; i < tn2.size(); ++i) {
          auto v = ck.number(tn2[i], where + ".tones_hz[" + std::to_string(i) + "]");
          if (v && *v <= 0.0)
            ck.issue(tn2[i], where + ".tones_hz[" + std::to_string(i) + "]",
                     "value " + format_double(*v) + " out of range (expected > 0 Hz)");
          else if (v)
            s.tones_hz.push_back(*v);
        }
      }
    }
    num("duration", s.duration_s, true, 1e-12, kInf, "> 0 s");
    num("fade", s.fade_s, false, 0.0, kInf, ">= 0 s");
    num("amplitude", s.amplitude, false, 0.0, 1.0, "0..1");
  } else if (s.type == "gold") {
    const YAML::Node cn = e["chips"];
    if (cn.IsDefined() && !cn.IsNull()) {
      if (auto c = ck.string(cn, where + ".chips")) {
        const auto bad = c->find_first_not_of("01");
        if (c->empty())
          ck.issue(cn, where + ".chips", "expected a string of 0 and 1, got an empty string");
        else if (bad != std::string::npos)
          ck.issue(cn, where + ".chips",
                   "expected only '0' and '1', got '" + std::string(1, (*c)[bad]) + "' at position " +
                       std::to_string(bad));
        else
          s.chips = *c;
      }
    }
    const YAML::Node dn = ck.required(e, "degree", where, "'degree' for type gold");
    if (dn.IsDefined()) {
      if (auto d = ck.integer(dn, where + ".degree")) {
        bool listed = false;
        for (int g : kGoldDegrees) listed = listed || g == *d;
        if (!listed && s.chips.empty() && !(cn.IsDefined() && !cn.IsNull()))
          ck.issue(dn, where + ".degree",
                   "degree " + std::to_string(*d) + " has no preferred pair (expected 5, 6, 7, 9, 10 or 11, or give 'chips')");
        else if (*d < 1 || *d > 30)
          ck.issue(dn, where + ".degree", "degree " + std::to_string(*d) + " out of range (expected 1..30)");
        else
          s.degree = static_cast<int>(*d);
      }
    }
    const long long max_index = s.degree > 0 ? (1LL << s.degree) : (1LL << 30);
    integer("index", s.index, 0, max_index, "0.." + std::to_string(max_index));
    num("carrier", s.carrier_hz, true, 0.0, kInf, ">= 0 Hz");
    integer("chip_samples", s.chip_samples, 1, 1 << 20, "1..1048576");
    num("amplitude", s.amplitude, false, 0.0, 1.0, "0..1");
  } else if (s.type == "ble") {
    const YAML::Node an = ck.required(e, "address", where, "a BLE address AA:BB:CC:DD:EE:FF");
    if (an.IsDefined()) {
      if (auto a = ck.string(an, where + ".address")) {
        std::array<std::uint8_t, 6> bytes{};
        if (!parse_ble_address(*a, bytes))
          ck.issue(an, where + ".address", "expected a BLE address AA:BB:CC:DD:EE:FF (hex), got '" + *a + "'");
        else
          s.address = *a;
      }
    }
    num("tx_power_dbm", s.tx_power_dbm, true, -200.0, 100.0, "-200..100 dBm");
    num("interval_s", s.interval_s, true, 1e-12, kInf, "> 0 s");
  }
  // else: a project-specific type, kept as is (require_known_signal_types reports it to consumers)
  if (s.acoustic()) {
    const YAML::Node sd = e["sync_delay_s"];
    if (sd.IsDefined() && !sd.IsNull()) {
      if (auto v = ck.number(sd, where + ".sync_delay_s")) s.sync_delay_s = *v;
    }
  }
  return s;
}

void parse_emits(Checker& ck, const YAML::Node& n, const std::string& where, std::vector<dsp::SignalSpec>& out,
                 std::vector<std::pair<int, int>>& at) {
  if (!n.IsDefined() || n.IsNull()) return;
  if (!n.IsSequence()) {
    ck.issue(n, where, "expected a list of signal entries, got " + shown(n));
    return;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const YAML::Node e = n[i];
    out.push_back(parse_signal(ck, e, where + "[" + std::to_string(i) + "]"));
    const YAML::Mark m = e.Mark();
    at.emplace_back(m.is_null() ? 0 : m.line + 1, m.is_null() ? 0 : m.column + 1);
  }
}

std::optional<Vec3> parse_anchor(Checker& ck, const YAML::Node& n, const std::string& where) {
  if (!n.IsDefined() || n.IsNull()) return std::nullopt;
  if (!n.IsMap()) {
    ck.issue(n, where, "expected a mapping {position: [x, y, z]}, got " + shown(n));
    return std::nullopt;
  }
  const YAML::Node p = ck.required(n, "position", where, "position: [x, y, z] in metres");
  if (!p.IsDefined()) return std::nullopt;
  return ck.vec3(p, where + ".position");
}

}  // namespace

dsp::SignalSpec parse_signal_text(std::string_view text, const std::string& name) {
  Checker ck(name);
  YAML::Node n;
  try {
    n = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    SceneIssue is;
    is.file = name;
    if (!e.mark.is_null()) {
      is.line = e.mark.line + 1;
      is.column = e.mark.column + 1;
    }
    is.message = "not valid YAML/JSON: " + e.msg;
    throw SceneError({is});
  }
  if (!n.IsMap()) {
    ck.issue(n, "", "expected one signal object ({\"type\": ..., ...}), got " + shown(n));
    throw SceneError(std::move(ck.issues));
  }
  dsp::SignalSpec spec = parse_signal(ck, n, "");
  if (!ck.issues.empty()) throw SceneError(std::move(ck.issues));
  return spec;
}

std::string signals_to_json(const std::vector<dsp::SignalSpec>& signals) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const dsp::SignalSpec& s : signals) {
    nlohmann::ordered_json j{{"type", s.type}};
    if (s.type == "lfm") {
      j["f0"] = s.f0_hz;
      j["f1"] = s.f1_hz;
      j["duration"] = s.duration_s;
      j["fade"] = s.fade_s;
      j["amplitude"] = s.amplitude;
    } else if (s.type == "multitone") {
      j["tones_hz"] = s.tones_hz;
      j["duration"] = s.duration_s;
      j["fade"] = s.fade_s;
      j["amplitude"] = s.amplitude;
    } else if (s.type == "gold") {
      j["degree"] = s.degree;
      j["index"] = s.index;
      j["carrier"] = s.carrier_hz;
      j["chip_samples"] = s.chip_samples;
      j["amplitude"] = s.amplitude;
      if (!s.chips.empty()) j["chips"] = s.chips;
    } else if (s.type == "ble") {
      j["address"] = s.address;
      j["tx_power_dbm"] = s.tx_power_dbm;
      j["interval_s"] = s.interval_s;
    }
    if (s.sync_delay_s) j["sync_delay_s"] = *s.sync_delay_s;
    out.push_back(std::move(j));
  }
  return out.dump();
}

std::string scene_emits_to_json(const Scene& scene) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  auto add = [&](const std::string& id, const std::vector<dsp::SignalSpec>& emits) {
    const nlohmann::ordered_json signals = nlohmann::ordered_json::parse(signals_to_json(emits));
    for (const auto& sig : signals) out.push_back(nlohmann::ordered_json{{"id", id}, {"signal", sig}});
  };
  for (const DeviceSpec& d : scene.devices) add(d.id, d.emits);
  for (const EmitterSpec& e : scene.emitters) add(e.id, e.emits);
  return out.dump();
}

bool is_known_signal_type(const std::string& type) noexcept {
  for (const char* k : kKnownTypes)
    if (type == k) return true;
  return false;
}

Scene load_scene(const std::string& dir) {
  Scene sc;
  sc.dir = dir;
  const std::string file = (std::filesystem::path(dir) / "scene.yaml").string();
  Checker ck(file);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    SceneIssue is;
    is.file = file;
    is.message = std::filesystem::is_directory(dir, ec) ? "no such file (a scene directory must hold scene.yaml)"
                                                        : "no such file (scene directory '" + dir + "' not found)";
    throw SceneError({is});
  }
  YAML::Node root;
  try {
    root = YAML::LoadFile(file);
  } catch (const YAML::ParserException& e) {
    SceneIssue is;
    is.file = file;
    is.line = e.mark.line + 1;
    is.column = e.mark.column + 1;
    is.message = "YAML syntax error: " + e.msg;
    throw SceneError({is});
  } catch (const YAML::Exception& e) {
    SceneIssue is;
    is.file = file;
    is.message = std::string("cannot read: ") + e.what();
    throw SceneError({is});
  }
  if (!root.IsMap()) {
    SceneIssue is;
    is.file = file;
    is.line = 1;
    is.column = 1;
    is.message = "expected a mapping at the top level (format, sample_rate, devices, ...), got " + shown(root);
    throw SceneError({is});
  }

  auto file_ref = [&](const YAML::Node& n, const std::string& where, std::string& out) {
    if (!n.IsDefined() || n.IsNull()) return;
    auto s = ck.string(n, where);
    if (!s) return;
    if (s->empty()) {
      ck.issue(n, where, "expected a file path relative to the scene directory, got an empty string");
      return;
    }
    const std::string full = sc.path(*s);
    std::error_code ec2;
    if (!std::filesystem::is_regular_file(full, ec2))
      ck.issue(n, where, "file '" + *s + "' not found (expected " + full + ")");
    out = *s;
  };

  // format
  if (YAML::Node n = ck.required(root, "format", "", std::string("'") + kFormatVersion + "'"); n.IsDefined()) {
    if (auto s = ck.string(n, "format")) {
      if (*s != kFormatVersion) ck.issue(n, "format", "expected '" + std::string(kFormatVersion) + "', got '" + *s + "'");
      sc.format = *s;
    }
  }
  if (YAML::Node n = root["name"]; n.IsDefined() && !n.IsNull()) {
    if (auto s = ck.string(n, "name")) sc.name = *s;
  }
  if (YAML::Node n = ck.required(root, "sample_rate", "", "the audio rate in Hz"); n.IsDefined()) {
    if (auto v = ck.number(n, "sample_rate")) {
      if (*v <= 0.0) ck.issue(n, "sample_rate", "expected a rate > 0 Hz, got " + format_double(*v));
      else sc.sample_rate_hz = *v;
    }
  }
  {
    const YAML::Node c = root["speed_of_sound"];
    const YAML::Node t = root["temperature_c"];
    const bool has_c = c.IsDefined() && !c.IsNull(), has_t = t.IsDefined() && !t.IsNull();
    if (has_t) {
      if (auto v = ck.number(t, "temperature_c")) {
        if (*v < -100.0 || *v > 100.0) ck.issue(t, "temperature_c", "value " + format_double(*v) + " out of range (expected -100..100 °C)");
        else {
          sc.temperature_c = *v;
          sc.speed_of_sound_mps = 331.3 + 0.606 * *v;
        }
      }
    }
    if (has_c) {  // authoritative when both are given
      if (auto v = ck.number(c, "speed_of_sound")) {
        if (*v <= 0.0) ck.issue(c, "speed_of_sound", "expected a speed > 0 m/s, got " + format_double(*v));
        else sc.speed_of_sound_mps = *v;
      }
    }
    if (!has_c && !has_t)
      ck.issue(root, "", "missing required key 'speed_of_sound' (m/s) or 'temperature_c' (°C)");
  }
  if (YAML::Node n = root["environment"]; n.IsDefined() && !n.IsNull()) {
    YAML::Emitter em;
    em << n;
    sc.environment_yaml = em.c_str();
  }

  std::map<std::string, std::string> seen_ids;  // id -> where first declared
  auto check_id = [&](const YAML::Node& obj, const std::string& where, std::string& out) {
    const YAML::Node n = ck.required(obj, "id", where, "an id [A-Za-z0-9_-]+");
    if (!n.IsDefined()) return;
    auto s = ck.string(n, where + ".id");
    if (!s) return;
    const IdProblem problem = id_problem(*s);
    if (problem == IdProblem::Empty || problem == IdProblem::BadCharacter) {
      ck.issue(n, where + ".id", "invalid id '" + *s + "' (expected letters, digits, '_' or '-' only)");
    } else if (problem == IdProblem::TooLong) {
      ck.issue(n, where + ".id", "id '" + *s + "' is longer than " + std::to_string(kMaxIdLength) + " characters");
    } else if (auto it = seen_ids.find(*s); it != seen_ids.end()) {
      ck.issue(n, where + ".id", "duplicate id '" + *s + "' (first declared at " + it->second + ")");
    } else {
      const YAML::Mark m = n.Mark();
      seen_ids[*s] = "line " + std::to_string(m.line + 1);
    }
    out = *s;
  };

  // devices
  if (YAML::Node devs = ck.required(root, "devices", "", "a list of devices"); devs.IsDefined()) {
    if (!devs.IsSequence()) {
      ck.issue(devs, "devices", "expected a list of devices, got " + shown(devs));
    } else {
      for (std::size_t i = 0; i < devs.size(); ++i) {
        const YAML::Node d = devs[i];
        const std::string where = "devices[" + std::to_string(i) + "]";
        if (!d.IsMap()) {
          ck.issue(d, where, "expected a mapping {id: ..., mics: ...}, got " + shown(d));
          continue;
        }
        DeviceSpec ds;
        ds.line = d.Mark().line + 1;
        check_id(d, where, ds.id);
        if (const YAML::Node m = d["mics"]; m.IsDefined() && !m.IsNull()) {
          if (!m.IsSequence() || m.size() == 0) {
            ck.issue(m, where + ".mics", "expected a non-empty list of rows [x, y, z], got " + shown(m));
          } else {
            for (std::size_t k = 0; k < m.size(); ++k) {
              if (auto v = ck.vec3(m[k], where + ".mics[" + std::to_string(k) + "]", "a row of 3 numbers [x, y, z]"))
                ds.mics_m.push_back(*v);
            }
          }
        }
        if (const YAML::Node n = d["speaker"]; n.IsDefined() && !n.IsNull()) ds.speaker_m = ck.vec3(n, where + ".speaker");
        parse_emits(ck, d["emits"], where + ".emits", ds.emits, ds.emits_at);
        file_ref(d["audio"], where + ".audio", ds.audio);
        file_ref(d["imu"], where + ".imu", ds.imu);
        file_ref(d["ble"], where + ".ble", ds.ble);
        file_ref(d["sync"], where + ".sync", ds.sync);
        if (!ds.audio.empty() && ds.mics_m.empty() && !(d["mics"].IsDefined() && !d["mics"].IsNull()))
          ck.issue(d, where, "device has 'audio' but no 'mics' (expected one mic row per audio channel)");
        ds.anchor_position_m = parse_anchor(ck, d["anchor"], where + ".anchor");
        sc.devices.push_back(std::move(ds));
      }
    }
  }
  // emitters
  if (YAML::Node ems = root["emitters"]; ems.IsDefined() && !ems.IsNull()) {
    if (!ems.IsSequence()) {
      ck.issue(ems, "emitters", "expected a list of emitters, got " + shown(ems));
    } else {
      for (std::size_t i = 0; i < ems.size(); ++i) {
        const YAML::Node e = ems[i];
        const std::string where = "emitters[" + std::to_string(i) + "]";
        if (!e.IsMap()) {
          ck.issue(e, where, "expected a mapping {id: ..., emits: ...}, got " + shown(e));
          continue;
        }
        EmitterSpec es;
        es.line = e.Mark().line + 1;
        check_id(e, where, es.id);
        if (YAML::Node n = ck.required(e, "emits", where, "a list of signal entries"); n.IsDefined())
          parse_emits(ck, n, where + ".emits", es.emits, es.emits_at);
        es.anchor_position_m = parse_anchor(ck, e["anchor"], where + ".anchor");
        sc.emitters.push_back(std::move(es));
      }
    }
  }
  // truth
  if (YAML::Node t = root["truth"]; t.IsDefined() && !t.IsNull()) {
    if (!t.IsMap()) {
      ck.issue(t, "truth", "expected a mapping {clocks, trajectories, magnetic_field_world}, got " + shown(t));
    } else {
      Truth tr;
      if (YAML::Node c = t["clocks"]; c.IsDefined() && !c.IsNull()) {
        if (!c.IsMap()) {
          ck.issue(c, "truth.clocks", "expected a mapping {<device id>: {offset_s, skew_ppm}}, got " + shown(c));
        } else {
          for (auto it = c.begin(); it != c.end(); ++it) {
            const YAML::Node key = it->first;
            const YAML::Node val = it->second;
            const std::string id = key.IsScalar() ? key.Scalar() : std::string();
            const std::string where = "truth.clocks." + id;
            if (!sc.find_device(id)) {
              ck.issue(key, "truth.clocks", "'" + id + "' is not a device id (expected one of the devices)");
              continue;
            }
            if (!val.IsMap()) {
              ck.issue(val, where, "expected a mapping {offset_s, skew_ppm}, got " + shown(val));
              continue;
            }
            ClockTruth ct;
            if (YAML::Node o = val["offset_s"]; o.IsDefined() && !o.IsNull())
              if (auto v = ck.number(o, where + ".offset_s")) ct.offset_s = *v;
            if (YAML::Node s = val["skew_ppm"]; s.IsDefined() && !s.IsNull()) {
              if (auto v = ck.number(s, where + ".skew_ppm")) {
                if (std::fabs(*v) >= 1e5) ck.issue(s, where + ".skew_ppm", "value " + format_double(*v) + " out of range (expected |skew| < 1e5 ppm)");
                else ct.skew_ppm = *v;
              }
            }
            tr.clocks[id] = ct;
          }
        }
      }
      file_ref(t["trajectories"], "truth.trajectories", tr.trajectories);
      if (YAML::Node m = t["magnetic_field_world"]; m.IsDefined() && !m.IsNull())
        tr.magnetic_field_world_ut = ck.vec3(m, "truth.magnetic_field_world");
      sc.truth = std::move(tr);
    }
  }
  if (!ck.issues.empty()) throw SceneError(std::move(ck.issues));
  return sc;
}

// ---------------------------------------------------------------------------------------------------
// writing

namespace {

void emit_num(YAML::Emitter& out, double v) { out << format_double(v); }

void emit_vec3(YAML::Emitter& out, const Vec3& v) {
  out << YAML::Flow << YAML::BeginSeq;
  for (double x : v) emit_num(out, x);
  out << YAML::EndSeq;
}

void emit_signal(YAML::Emitter& out, const dsp::SignalSpec& s) {
  out << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << s.type;
  if (s.type == "lfm" || s.type == "multitone") {
    if (s.type == "lfm") {
      out << YAML::Key << "f0" << YAML::Value;
      emit_num(out, s.f0_hz);
      out << YAML::Key << "f1" << YAML::Value;
      emit_num(out, s.f1_hz);
    } else {
      out << YAML::Key << "tones_hz" << YAML::Value << YAML::Flow << YAML::BeginSeq;
      for (double f : s.tones_hz) emit_num(out, f);
      out << YAML::EndSeq;
    }
    out << YAML::Key << "duration" << YAML::Value;
    emit_num(out, s.duration_s);
    out << YAML::Key << "fade" << YAML::Value;
    emit_num(out, s.fade_s);
    out << YAML::Key << "amplitude" << YAML::Value;
    emit_num(out, s.amplitude);
  } else if (s.type == "gold") {
    out << YAML::Key << "degree" << YAML::Value << s.degree;
    out << YAML::Key << "index" << YAML::Value << s.index;
    out << YAML::Key << "carrier" << YAML::Value;
    emit_num(out, s.carrier_hz);
    out << YAML::Key << "chip_samples" << YAML::Value << s.chip_samples;
    out << YAML::Key << "amplitude" << YAML::Value;
    emit_num(out, s.amplitude);
    if (!s.chips.empty()) out << YAML::Key << "chips" << YAML::Value << YAML::DoubleQuoted << s.chips;
  } else if (s.type == "ble") {
    out << YAML::Key << "address" << YAML::Value << YAML::DoubleQuoted << s.address;
    out << YAML::Key << "tx_power_dbm" << YAML::Value;
    emit_num(out, s.tx_power_dbm);
    out << YAML::Key << "interval_s" << YAML::Value;
    emit_num(out, s.interval_s);
  }
  if (s.acoustic() && s.sync_delay_s) {
    out << YAML::Key << "sync_delay_s" << YAML::Value;
    emit_num(out, *s.sync_delay_s);
  }
  out << YAML::EndMap;
}

void emit_emits(YAML::Emitter& out, const std::vector<dsp::SignalSpec>& v) {
  out << YAML::Key << "emits" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : v) emit_signal(out, s);
  out << YAML::EndSeq;
}

void emit_anchor(YAML::Emitter& out, const std::optional<Vec3>& a) {
  if (!a) return;
  out << YAML::Key << "anchor" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "position"
      << YAML::Value;
  emit_vec3(out, *a);
  out << YAML::EndMap;
}

}  // namespace

void write_scene_yaml(const Scene& sc) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << sc.format;
  out << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << sc.name;
  out << YAML::Key << "sample_rate" << YAML::Value;
  emit_num(out, sc.sample_rate_hz);
  out << YAML::Key << "speed_of_sound" << YAML::Value;
  emit_num(out, sc.speed_of_sound_mps);
  if (sc.temperature_c) {
    out << YAML::Key << "temperature_c" << YAML::Value;
    emit_num(out, *sc.temperature_c);
  }
  if (!sc.environment_yaml.empty()) {
    YAML::Node env;
    try {
      env = YAML::Load(sc.environment_yaml);
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(sc.path("scene.yaml") + ": environment_yaml is not valid YAML: " + e.what());
    }
    out << YAML::Key << "environment" << YAML::Value << env;
  }
  out << YAML::Key << "devices" << YAML::Value << YAML::BeginSeq;
  for (const auto& d : sc.devices) {
    out << YAML::BeginMap;
    out << YAML::Key << "id" << YAML::Value << d.id;
    if (!d.mics_m.empty()) {
      out << YAML::Key << "mics" << YAML::Value << YAML::BeginSeq;
      for (const auto& m : d.mics_m) emit_vec3(out, m);
      out << YAML::EndSeq;
    }
    if (d.speaker_m) {
      out << YAML::Key << "speaker" << YAML::Value;
      emit_vec3(out, *d.speaker_m);
    }
    if (!d.emits.empty()) emit_emits(out, d.emits);
    const std::pair<const char*, const std::string*> files[] = {
        {"audio", &d.audio}, {"imu", &d.imu}, {"ble", &d.ble}, {"sync", &d.sync}};
    for (const auto& [k, v] : files)
      if (!v->empty()) out << YAML::Key << k << YAML::Value << *v;
    emit_anchor(out, d.anchor_position_m);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  if (!sc.emitters.empty()) {
    out << YAML::Key << "emitters" << YAML::Value << YAML::BeginSeq;
    for (const auto& e : sc.emitters) {
      out << YAML::BeginMap;
      out << YAML::Key << "id" << YAML::Value << e.id;
      emit_emits(out, e.emits);
      emit_anchor(out, e.anchor_position_m);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }
  if (sc.truth) {
    const Truth& t = *sc.truth;
    out << YAML::Key << "truth" << YAML::Value << YAML::BeginMap;
    if (!t.clocks.empty()) {
      out << YAML::Key << "clocks" << YAML::Value << YAML::BeginMap;
      for (const auto& [id, c] : t.clocks) {
        out << YAML::Key << id << YAML::Value << YAML::Flow << YAML::BeginMap;
        out << YAML::Key << "offset_s" << YAML::Value;
        emit_num(out, c.offset_s);
        out << YAML::Key << "skew_ppm" << YAML::Value;
        emit_num(out, c.skew_ppm);
        out << YAML::EndMap;
      }
      out << YAML::EndMap;
    }
    if (!t.trajectories.empty()) out << YAML::Key << "trajectories" << YAML::Value << t.trajectories;
    if (t.magnetic_field_world_ut) {
      out << YAML::Key << "magnetic_field_world" << YAML::Value;
      emit_vec3(out, *t.magnetic_field_world_ut);
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (!out.good()) throw std::runtime_error(sc.path("scene.yaml") + ": YAML emitter error: " + out.GetLastError());

  std::error_code ec;
  if (!sc.dir.empty()) std::filesystem::create_directories(sc.dir, ec);
  if (ec) throw std::runtime_error(sc.dir + ": cannot create directory: " + ec.message());
  const std::string file = (std::filesystem::path(sc.dir.empty() ? "." : sc.dir) / "scene.yaml").string();
  std::ofstream f(file, std::ios::binary | std::ios::trunc);
  if (!f) throw std::runtime_error(file + ": cannot create");
  f << "# Locus scene (" << kFormatVersion << "), see docs/scene-format.md\n" << out.c_str() << "\n";
  f.close();
  if (!f) throw std::runtime_error(file + ": write failed");
}

// ---------------------------------------------------------------------------------------------------
// cross-file checks

std::vector<std::string> validate_scene_streams(const Scene& sc) {
  std::vector<SceneIssue> issues;
  std::vector<std::string> warnings;
  for (const auto& d : sc.devices) {
    if (d.audio.empty()) continue;
    const std::string path = sc.path(d.audio);
    try {
      const WavInfo info = read_wav_info(path);
      if (static_cast<std::size_t>(info.channels) != d.mics_m.size()) {
        SceneIssue is;
        is.file = path;
        is.byte_offset = static_cast<long long>(info.fmt_offset) + 2;
        is.message = std::to_string(info.channels) + " channel" + (info.channels == 1 ? "" : "s") +
                     ", expected " + std::to_string(d.mics_m.size()) + " (one per mic of device '" + d.id +
                     "' in scene.yaml)";
        issues.push_back(is);
      }
      if (info.sample_rate_hz != sc.sample_rate_hz) {
        SceneIssue is;
        is.file = path;
        is.byte_offset = static_cast<long long>(info.fmt_offset) + 4;
        is.message = "sample rate " + format_double(info.sample_rate_hz) + " Hz, expected " +
                     format_double(sc.sample_rate_hz) + " Hz (scene.yaml sample_rate)";
        issues.push_back(is);
      }
      if (info.truncated) {
        SceneIssue is;
        is.file = path;
        is.byte_offset = static_cast<long long>(info.data_offset) - 4;
        is.message = "truncated data chunk: header declares " + std::to_string(info.declared_data_bytes) +
                     " bytes; " + std::to_string(info.frames) + " whole frames present";
        warnings.push_back(is.format());
      }
    } catch (const SceneError& e) {
      issues.insert(issues.end(), e.issues().begin(), e.issues().end());
    }
  }
  if (!issues.empty()) throw SceneError(std::move(issues));
  return warnings;
}

void require_known_signal_types(const Scene& sc, const std::vector<std::string>& ids) {
  std::vector<SceneIssue> issues;
  const std::string file = sc.path("scene.yaml");
  auto wanted = [&](const std::string& id) {
    if (ids.empty()) return true;
    for (const auto& i : ids)
      if (i == id) return true;
    return false;
  };
  auto check = [&](const char* kind, const std::string& id, const std::vector<dsp::SignalSpec>& emits,
                   const std::vector<std::pair<int, int>>& at) {
    for (std::size_t i = 0; i < emits.size(); ++i) {
      if (is_known_signal_type(emits[i].type)) continue;
      SceneIssue is;
      is.file = file;
      if (i < at.size()) {
        is.line = at[i].first;
        is.column = at[i].second;
      }
      is.message = std::string(kind) + " '" + id + "': emits[" + std::to_string(i) + "]: unknown signal type '" +
                   emits[i].type + "' (known: lfm, gold, multitone, ble)";
      issues.push_back(is);
    }
  };
  for (const auto& d : sc.devices)
    if (wanted(d.id)) check("device", d.id, d.emits, d.emits_at);
  for (const auto& e : sc.emitters)
    if (wanted(e.id)) check("emitter", e.id, e.emits, e.emits_at);
  if (!issues.empty()) throw SceneError(std::move(issues));
}

}  // namespace locus::scene
