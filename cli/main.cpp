// pneuma: breathing 3D lungs. This file only parses the command line and reports errors.
#include <tbb/global_control.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "pneuma/core/error.h"
#include "pneuma/core/heap.h"
#include "pneuma/core/interrupt.h"
#include "pneuma/core/text.h"

namespace {

int run(int argc, char** argv) {
  // Ctrl-C and SIGTERM remove half-written files and stages, then exit 130 / 143.
  pneuma::install_interrupt_handlers();
  pneuma::keep_large_blocks_in_heap();  // a speed setting: where it is refused, nothing else changes

  // Named explicitly: Usage lines say "pneuma", not the path the binary was started from.
  CLI::App app{"pneuma " PNEUMA_VERSION ": breathing 3D lungs for visualization, training and imaging research",
               "pneuma"};
  pneuma::cli::add_examples(
      app, {"pneuma run scenarios/quiet-breathing.yaml -o out/demo",
            "pneuma phantom --lung right --edge 2mm -o right.ply", "pneuma mesh info right.ply",
            "pneuma field phantom:right --tissue healthy-upright -o field.h5", "pneuma SUBCOMMAND --help"});
  app.set_version_flag("--version", "pneuma " PNEUMA_VERSION);
  app.require_subcommand(1);
  app.failure_message([](const CLI::App*, const CLI::Error& e) {
    return "pneuma: " + pneuma::quote_bytes(e.what()) + " (see 'pneuma --help')\n";
  });
  // Every parallel loop (TBB) and the software renderer (llvmpipe) use at most N threads; the
  // outputs are the same bytes at any N. Accepted after the subcommand too (fallthrough).
  unsigned threads = 0;
  app.add_option("--threads", threads, "Use at most N threads (default: every core); the same outputs at any N")
      ->option_text("N")
      ->envname("PNEUMA_THREADS")
      ->check(CLI::Range(1u, 4096u));
  app.fallthrough();
  std::unique_ptr<tbb::global_control> thread_limit;
  app.parse_complete_callback([&] {
    if (threads == 0) return;
    thread_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads);
    ::setenv("LP_NUM_THREADS", std::to_string(threads).c_str(), /*overwrite=*/0);
  });
  pneuma::cli::register_simulate(app);
  pneuma::cli::register_field(app);
  pneuma::cli::register_run(app);
  pneuma::cli::register_compare(app);
  pneuma::cli::register_mesh(app);
  pneuma::cli::register_phantom(app);
  pneuma::cli::register_render(app);
  pneuma::cli::register_cohort(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : static_cast<int>(pneuma::ExitCode::usage);
  } catch (const pneuma::Error& e) {
    // Text copied from a bad input (a control character, bytes that are not UTF-8) as "\x1b".
    std::fprintf(stderr, "%s\n", pneuma::quote_bytes(e.what()).c_str());
    return static_cast<int>(e.code());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pneuma: internal error: %s\n", pneuma::quote_bytes(e.what()).c_str());
    return static_cast<int>(pneuma::ExitCode::failure);
  }
  return 0;
}

}  // namespace

// Whatever escapes run() (setting up the command line, not running a command) is still one line
// and an exit code, never std::terminate.
int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pneuma: internal error: %s\n", e.what());
  } catch (...) {
    std::fprintf(stderr, "pneuma: internal error: unknown exception\n");
  }
  return static_cast<int>(pneuma::ExitCode::failure);
}
