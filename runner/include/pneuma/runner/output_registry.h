#pragma once
// Every output a scenario can ask for, registered in one place (output_registry.cpp, one line
// each): a new output is one outputs::OutputPlugin and one line there, not a change to the run
// loop or the scenario reader.
#include <filesystem>
#include <memory>
#include <vector>

#include "pneuma/outputs/output.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::runner {

// The registered outputs, in the order they receive each frame and finish.
const std::vector<outputs::OutputPlugin>& output_registry();

// Their keys under `outputs:`, for scenario::load_scenario / read_scenario.
const std::vector<scenario::OutputKey>& output_keys();

// A scenario file read with every registered output's key (what `pneuma run` and the Python
// module load). Throws as scenario::load_scenario.
scenario::Scenario load_scenario(const std::filesystem::path& file);
scenario::Scenario read_scenario(const scenario::Node& root, const std::filesystem::path& file);

// The plugins of the outputs `scenario` asks for, in registry order.
std::vector<const outputs::OutputPlugin*> requested_outputs(const scenario::Scenario& scenario);

// What those outputs need of the run, together (each computed once, for all of them).
outputs::OutputNeeds requested_needs(const scenario::Scenario& scenario);

}  // namespace pneuma::runner
