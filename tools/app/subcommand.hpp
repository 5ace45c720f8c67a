// A `locus` subcommand contributed by a tool module (tools/<name>/cli.hpp): the CLI11 subcommand it
// added and the function that runs it once parsed (returns the exit status, see app.hpp).
#pragma once

#include <functional>

#include <CLI/CLI.hpp>

namespace locus::app {

struct Subcommand {
  CLI::App* cmd = nullptr;
  std::function<int()> run;
};

}  // namespace locus::app
