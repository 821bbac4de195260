// pneuma: breathing 3D lungs. This file only parses the command line and reports errors.
#include <csignal>
#include <cstdio>
#include <unistd.h>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"

namespace {

// Ctrl-C: remove half-written temporaries, then die with the conventional status.
void on_interrupt(int signal) {
  pneuma::remove_pending_temporaries();
  ::_exit(128 + signal);
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGINT, on_interrupt);
  std::signal(SIGTERM, on_interrupt);

  // Named explicitly: Usage lines say "pneuma", not the path the binary was started from.
  CLI::App app{"pneuma " PNEUMA_VERSION ": breathing 3D lungs for visualization, training and imaging research",
               "pneuma"};
  app.footer("\nExamples:\n"
             "  pneuma run scenarios/quiet-breathing.yaml -o out/demo\n"
             "  pneuma phantom --lung right --edge 2mm -o right.ply\n"
             "  pneuma mesh info right.ply\n"
             "  pneuma field phantom:right --tissue healthy-upright -o field.h5\n"
             "  pneuma SUBCOMMAND --help\n");
  app.set_version_flag("--version", "pneuma " PNEUMA_VERSION);
  app.require_subcommand(1);
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return std::string("pneuma: ") + e.what() + " (see 'pneuma --help')\n";
  });
  pneuma::cli::register_simulate(app);
  pneuma::cli::register_field(app);
  pneuma::cli::register_run(app);
  pneuma::cli::register_compare(app);
  pneuma::cli::register_mesh(app);
  pneuma::cli::register_phantom(app);
  pneuma::cli::register_render(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : static_cast<int>(pneuma::ExitCode::usage);
  } catch (const pneuma::Error& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return static_cast<int>(e.code());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pneuma: internal error: %s\n", e.what());
    return static_cast<int>(pneuma::ExitCode::failure);
  }
  return 0;
}
