// locusd: the Locus node daemon. Runs the pipeline a config describes until its finite sources end
// or SIGINT/SIGTERM arrives, writing estimates and events as JSON lines (docs/events.md).
#include "app.hpp"

int main(int argc, char** argv) {
  CLI::App cli{"locusd: the Locus localization daemon"};
  locus::app::RunOptions opts;
  locus::app::add_run_options(cli, opts);
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = cli.exit(e);
    return code == 0 ? 0 : locus::app::kExitBadConfig;
  }
  return locus::app::run_node(opts);
}
