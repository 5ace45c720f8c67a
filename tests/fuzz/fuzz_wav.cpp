// The WAV reader (libsndfile underneath, our header validation and truncation handling on top):
// header, then every frame in blocks, then a seek back and a re-read.
#include <cstdint>
#include <vector>

#include "fuzz_support.hpp"
#include "locus/scene/scene.hpp"
#include "locus/scene/wav.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = locus::fuzz::write_input("audio.wav", data, size);
  try {
    locus::scene::WavReader r(path);
    std::vector<float> buf(256 * static_cast<std::size_t>(r.info().channels));
    std::uint64_t frames = 0;
    while (std::size_t n = r.read(buf.data(), 256)) frames += n;
    r.seek(frames / 2);
    r.read(buf.data(), 256);
    (void)r.truncation_message();
  } catch (const locus::scene::SceneError&) {
  }
  return 0;
}
