#pragma once
// Each subcommand registers itself on the app; its callback does the work and throws
// pneuma::Error on failure (main() turns that into one line and an exit code).
#include <CLI/CLI.hpp>
#include <vector>

#include "pneuma/engine/runner.h"

namespace pneuma::cli {

void register_simulate(CLI::App& app);
// `extra_sinks`: outputs built outside engine (the PNG renderer).
void register_run(CLI::App& app, std::vector<engine::SinkFactory> extra_sinks);
void register_field(CLI::App& app);
void register_compare(CLI::App& app);
void register_mesh(CLI::App& app);
void register_phantom(CLI::App& app);
void register_render(CLI::App& app);
// The `png` scenario output (render::PngFrameSink), passed to register_run.
engine::SinkFactory png_sink_factory();

// Shared option helpers.
// Adds `--name VALUE` that parses a quantity with its unit (e.g. "3mm") into SI.
CLI::Option* add_quantity_option(CLI::App& command, const std::string& name, double& value_si,
                                 const std::string& description, const char* kind_name);

}  // namespace pneuma::cli
