// Model files of `locus train` as a localizer reads them (config/<name>-*.yaml): the LocBLE EnvAware
// model and the SpyLoc LoS/NLoS model, each input through both readers. A malformed file is a
// std::runtime_error naming the field; nothing else may escape.
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz_support.hpp"
#include "locble/envaware.hpp"
#include "spyloc/classifier.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    (void)locus::plugins::locble::parse_envaware_model(std::string(locus::fuzz::as_text(data, size)), "fuzz.yaml");
  } catch (const std::runtime_error&) {
  }
  try {
    locus::plugins::spyloc::LosClassifier c;
    c.load_text(std::string(locus::fuzz::as_text(data, size)), "fuzz.yaml");
  } catch (const std::runtime_error&) {
  }
  return 0;
}
