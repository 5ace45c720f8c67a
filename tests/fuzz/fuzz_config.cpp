// Config YAML, schema validation included: every plugin's declared parameters (the built-in registry).
// The only exception load_config_string may throw is ConfigErrors; anything else, a crash, a leak or
// undefined behaviour is a finding. Inputs that name plugin_dirs are skipped: they would dlopen
// whatever library the fuzzer names (plugin loading has its own tests).
#include <cstdint>
#include <string>

#include "fuzz_support.hpp"
#include "locus/config.hpp"
#include "locus/registry.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = locus::fuzz::as_text(data, size);
  if (text.find("plugin_dirs") != std::string_view::npos) return -1;  // not added to the corpus
  static locus::Registry* registry = [] {
    auto* r = new locus::Registry();
    locus::register_builtins(*r);
    return r;
  }();
  try {
    locus::load_config_string(text, "fuzz.yaml", *registry, locus::fuzz::work_dir().string());
  } catch (const locus::ConfigErrors&) {
  }
  return 0;
}
