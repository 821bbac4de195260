#pragma once
// pneuma.Scenario as the translation units of the module share it (scenario.cpp makes it;
// simulation.cpp and animation.cpp take one).
#include <pybind11/pybind11.h>

#include <string>

#include "pneuma/scenario/scenario.h"

namespace pneuma::python {

// pneuma.Scenario: the typed scenario and, for one made from a dict, its YAML text (run()
// writes it to <output>/scenario.yaml, so the manifest records and checksums a real file).
struct ScenarioHandle {
  scenario::Scenario scenario;
  std::string yaml;  // empty for a scenario read from a file
};

// A Scenario, a dict, or a path (str or os.PathLike) to a scenario YAML file. Raises TypeError
// for anything else; pneuma.InputError / IoError as the scenario loader.
ScenarioHandle to_scenario(const pybind11::handle& scenario);

}  // namespace pneuma::python
