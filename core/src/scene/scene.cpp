// scene.yaml: load (validate everything, collect every issue with line:column) and write.
//
// Reading is strict about what the format requires and tolerant about what it allows: unknown keys
// are ignored, `emits` entries of an unknown type are kept (require_known_signal_types() turns them
// into errors for a consumer that needs them). Signals are read and written by the one signal parser
// and writer (locus/signal_yaml.hpp); this file only places their issues in scene.yaml. Numbers are written in their shortest round-trip form,
// so load_scene(write_scene_yaml(x)) reproduces x exactly.
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "locus/ids.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/streams.hpp"
#include "locus/signal_yaml.hpp"

namespace locus::scene {

namespace {

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

  /// One signal object (the one signal parser, locus/signal_yaml.hpp), its issues collected here.
  dsp::SignalSpec signal(const YAML::Node& n, const std::string& where) {
    std::vector<SignalIssue> found;
    dsp::SignalSpec spec = parse_signal_node(n, where, found);
    for (SignalIssue& f : found) {
      SceneIssue is;
      is.file = file_;
      is.line = f.line;
      is.column = f.column;
      is.message = f.field.empty() ? std::move(f.message) : f.field + ": " + f.message;
      issues.push_back(std::move(is));
    }
    return spec;
  }

  std::vector<SceneIssue> issues;

 private:
  std::string file_;
};

void parse_emits(Checker& ck, const YAML::Node& n, const std::string& where, std::vector<dsp::SignalSpec>& out,
                 std::vector<std::pair<int, int>>& at) {
  if (!n.IsDefined() || n.IsNull()) return;
  if (!n.IsSequence()) {
    ck.issue(n, where, "expected a list of signal entries, got " + shown(n));
    return;
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const YAML::Node e = n[i];
    out.push_back(ck.signal(e, where + "[" + std::to_string(i) + "]"));
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

std::vector<SceneSignal> scene_signals(const Scene& scene) {
  std::vector<SceneSignal> out;
  auto add = [&out](const std::string& id, const dsp::SignalSpec& sig, const std::optional<Vec3>& anchor) {
    SceneSignal s{id, sig};
    if (anchor) {
      s.has_anchor = true;
      s.anchor_m = *anchor;
    }
    out.push_back(std::move(s));
  };
  for (const DeviceSpec& d : scene.devices)
    for (const dsp::SignalSpec& sig : d.emits) add(d.id, sig, d.anchor_position_m);
  for (const EmitterSpec& e : scene.emitters)
    for (const dsp::SignalSpec& sig : e.emits) add(e.id, sig, e.anchor_position_m);
  return out;
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

void emit_emits(YAML::Emitter& out, const std::vector<dsp::SignalSpec>& v) {
  out << YAML::Key << "emits" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : v) emit_signal_yaml(out, s);
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
                   emits[i].type + "' (known: " + kKnownSignalTypes + ")";
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
