// Scene model helpers (lookups, paths) and the error type; parsing lives in scene.cpp.
#include <string>

#include "locus/scene/scene.hpp"

namespace locus::scene {

const DeviceSpec* Scene::find_device(const std::string& id) const {
  for (const DeviceSpec& d : devices) {
    if (d.id == id) return &d;
  }
  return nullptr;
}

const EmitterSpec* Scene::find_emitter(const std::string& id) const {
  for (const EmitterSpec& e : emitters) {
    if (e.id == id) return &e;
  }
  return nullptr;
}

std::string Scene::path(const std::string& relative) const {
  if (relative.empty()) return {};
  if (relative.front() == '/' || dir.empty()) return relative;
  return dir.back() == '/' ? dir + relative : dir + "/" + relative;
}

std::string SceneIssue::format() const {
  std::string out = file;
  if (line > 0) {
    out += ":" + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  } else if (byte_offset >= 0) {
    out += ": byte " + std::to_string(byte_offset);
  }
  return out + ": " + message;
}

namespace {
std::string join_issues(const std::vector<SceneIssue>& issues) {
  std::string out;
  for (const SceneIssue& i : issues) {
    if (!out.empty()) out += "\n";
    out += i.format();
  }
  return out;
}
}  // namespace

SceneError::SceneError(std::vector<SceneIssue> issues) : std::runtime_error(join_issues(issues)), issues_(std::move(issues)) {}

}  // namespace locus::scene
