// A `locus` subcommand contributed by a tool module (tools/<name>/cli.hpp): the CLI11 subcommand it
// added and the function that runs it once parsed (returns the exit status, see app.hpp).
#pragma once

#include <functional>

// CLI11 is not included here: it costs ~10 s of compile time per translation unit (its headers define
// validator objects with static constructors); only the files that build command lines include it.
namespace CLI {
class App;
}  // namespace CLI

namespace locus::app {

struct Subcommand {
  CLI::App* cmd = nullptr;
  std::function<int()> run;
};

}  // namespace locus::app
