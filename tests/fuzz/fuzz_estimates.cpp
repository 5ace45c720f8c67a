// `locus eval`'s estimates reader (JSON lines of estimate and step events, docs/eval.md): InputError
// is the only exception.
#include <cstdint>
#include <sstream>

#include "fuzz_support.hpp"
#include "locus/eval/error.hpp"
#include "locus/eval/estimates.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(locus::fuzz::as_text(data, size)));
  try {
    locus::eval::parse_estimates(in, "fuzz.jsonl");
  } catch (const locus::eval::InputError&) {
  }
  return 0;
}
