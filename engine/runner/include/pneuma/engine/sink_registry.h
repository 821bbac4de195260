#pragma once
// Every frame sink a scenario can ask for, registered in one place (sink_registry.cpp): a new
// output is one new FrameSink and one entry there, not a change to the run loop.
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "pneuma/engine/frame.h"
#include "pneuma/engine/scenario.h"

namespace pneuma::engine {

struct SinkEntry {
  std::string name;  // its key under `outputs:` in a scenario
  // The sink for this scenario, writing under `output_dir`; nullptr when the scenario leaves it off.
  std::function<std::unique_ptr<FrameSink>(const Scenario&, const std::filesystem::path& output_dir)> make;
};

// The registered sinks, in the order they receive each frame.
const std::vector<SinkEntry>& sink_registry();

// The sinks `scenario` asks for, in registry order.
std::vector<std::unique_ptr<FrameSink>> make_sinks(const Scenario& scenario, const std::filesystem::path& output_dir);

}  // namespace pneuma::engine
