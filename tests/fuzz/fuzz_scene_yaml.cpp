// scene.yaml (the locus-scene/1 format, docs/scene-format.md): load_scene on a directory holding only
// the input as scene.yaml. The streams it names do not exist, so a well-formed scene ends in a
// SceneError too, after the whole YAML was validated.
#include <cstdint>

#include "fuzz_support.hpp"
#include "locus/scene/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  locus::fuzz::write_input("scene.yaml", data, size);
  try {
    locus::scene::load_scene(locus::fuzz::work_dir().string());
  } catch (const locus::scene::SceneError&) {
  }
  return 0;
}
