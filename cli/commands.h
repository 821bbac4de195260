#pragma once
// Each subcommand registers itself on the app; its callback does the work and throws
// pneuma::Error on failure (main() turns that into one line and an exit code).
#include <CLI/CLI.hpp>
#include <initializer_list>
#include <string>

#include "pneuma/core/parameters.h"

namespace pneuma::cli {

void register_simulate(CLI::App& app);
void register_run(CLI::App& app);
void register_field(CLI::App& app);
void register_compare(CLI::App& app);
void register_mesh(CLI::App& app);
void register_phantom(CLI::App& app);
void register_render(CLI::App& app);
void register_cohort(CLI::App& app);

// Shared option helpers.
// Adds `--name VALUE` that parses a quantity with its unit (e.g. "3mm") into SI.
CLI::Option* add_quantity_option(CLI::App& command, const std::string& name, double& value_si,
                                 const std::string& description, const char* kind_name);

// Throws UsageError "pneuma: <option>: expected ..., got ..." unless `parameter` takes `value`
// (SI): the rule and its words are the parameter table's, as in a scenario and in Python.
void check_option(const std::string& option, const parameters::Parameter& parameter, double value);

// Ends the command's --help with "Examples:" and one command line per entry.
void add_examples(CLI::App& command, std::initializer_list<const char*> lines);

}  // namespace pneuma::cli
