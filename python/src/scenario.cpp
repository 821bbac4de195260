// Scenarios: pneuma.Scenario, load_scenario (file or dict) and run.
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <optional>

#include "bindings.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "scenario_handle.h"

namespace pneuma::python {
namespace {

// What stands for the file in messages about a scenario given as a dict.
constexpr const char* kDictName = "<dict>";

// A Python value as the YAML the scenario loader reads: numbers and strings become scalars
// (Python's own spelling), bools true/false, None null, dicts mappings, lists and tuples lists.
YAML::Node to_yaml(const py::handle& value, const std::string& path) {
  if (value.is_none()) return YAML::Node(YAML::NodeType::Null);
  if (py::isinstance<py::bool_>(value)) return YAML::Node(value.cast<bool>() ? "true" : "false");
  if (py::isinstance<py::str>(value) || py::isinstance<py::int_>(value) || py::isinstance<py::float_>(value)) {
    return YAML::Node(py::str(value).cast<std::string>());
  }
  if (py::isinstance(value, py::module_::import("os").attr("PathLike"))) {
    return YAML::Node(py::str(py::module_::import("os").attr("fspath")(value)).cast<std::string>());
  }
  if (py::isinstance<py::dict>(value)) {
    YAML::Node map(YAML::NodeType::Map);
    for (const auto& [key, item] : value.cast<py::dict>()) {
      if (!py::isinstance<py::str>(key)) {
        throw ValueError(fmt::format("{}: {}: expected string keys, got {}", kDictName,
                                     path.empty() ? "scenario" : path, py::repr(key).cast<std::string>()));
      }
      const std::string name = key.cast<std::string>();
      map[name] = to_yaml(item, path.empty() ? name : fmt::format("{}.{}", path, name));
    }
    return map;
  }
  if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
    YAML::Node list(YAML::NodeType::Sequence);
    std::size_t i = 0;
    for (const auto& item : value) list.push_back(to_yaml(item, fmt::format("{}[{}]", path, i++)));
    return list;
  }
  throw ValueError(fmt::format("{}: {}: expected a number, string, bool, list or dict, got {}", kDictName, path,
                               py::str(value.get_type().attr("__name__")).cast<std::string>()));
}

ScenarioHandle scenario_from_dict(const py::dict& d) {
  const YAML::Node root = to_yaml(d, "");
  return {runner::read_scenario(scenario::Node::from_yaml(root, kDictName), kDictName), YAML::Dump(root) + "\n"};
}

}  // namespace

// A Scenario, a dict, or a path (str or os.PathLike) to a scenario YAML file.
ScenarioHandle to_scenario(const py::handle& scenario) {
  if (py::isinstance<ScenarioHandle>(scenario)) return scenario.cast<ScenarioHandle>();
  if (py::isinstance<py::dict>(scenario)) return scenario_from_dict(scenario.cast<py::dict>());
  if (py::isinstance<py::str>(scenario) || py::isinstance(scenario, py::module_::import("os").attr("PathLike"))) {
    return {runner::load_scenario(scenario.cast<std::filesystem::path>()), ""};
  }
  throw py::type_error("scenario: expected a pneuma.Scenario, a dict or a path to a scenario YAML file, got " +
                       py::str(scenario.get_type().attr("__name__")).cast<std::string>());
}

void register_scenario(py::module_& m) {
  py::class_<ScenarioHandle>(m, "Scenario",
                             "A checked scenario (units converted, presets applied). Made by load_scenario(); "
                             "simulate(), run() and Animation() take one, a dict or a path.")
      .def_property_readonly(
          "file", [](const ScenarioHandle& h) { return h.scenario.file.string(); },
          "The YAML file it came from ('<dict>' for a dict).")
      .def_property_readonly(
          "name", [](const ScenarioHandle& h) { return h.scenario.name; }, "`name`, else the file's stem.")
      .def_property_readonly(
          "description", [](const ScenarioHandle& h) { return h.scenario.description; }, "`description`.")
      .def_property_readonly(
          "duration_s", [](const ScenarioHandle& h) { return h.scenario.duration_s; }, "`duration`, seconds.")
      .def_property_readonly(
          "frame_rate_hz", [](const ScenarioHandle& h) { return h.scenario.frame_rate_hz; }, "`frames.rate`, Hz.")
      .def_property_readonly(
          "output_rate_hz", [](const ScenarioHandle& h) { return h.scenario.physiology.options.output_rate_hz; },
          "`physiology.output_rate`, Hz: the rate of simulate()'s time series.")
      .def_property_readonly(
          "yaml", [](const ScenarioHandle& h) { return h.yaml; },
          "For a scenario made from a dict, the YAML it stands for (run() writes it to "
          "<output_dir>/scenario.yaml); empty for a file.")
      .def("__repr__", [](const ScenarioHandle& h) {
        return fmt::format("<pneuma.Scenario '{}' from {}, {} s>", h.scenario.name, h.scenario.file.string(),
                           h.scenario.duration_s);
      });

  m.def("load_scenario", &to_scenario, py::arg("scenario"),
        "load_scenario(scenario) -> Scenario\n\n"
        "Reads and checks a scenario: a path to a YAML file, or a dict with the same keys and values (numbers with "
        "their units as strings, e.g. {'duration': '10 s'}). Paths inside a dict are relative to the current "
        "folder. Every problem raises pneuma.InputError with one line: '<file>:<line>:<col>: <key.path>: <what was "
        "expected>' for a file, '<dict>: <key.path>: <what was expected>' for a dict; pneuma.IoError when the file "
        "cannot be read.");

  py::class_<runner::RunResult>(m, "RunResult", "What run() did: files written, counts, scales and timings.")
      .def_property_readonly(
          "files",
          [](const runner::RunResult& r) {
            std::vector<std::string> files;
            for (const auto& f : r.files) files.push_back(f.generic_string());
            return files;
          },
          "Files written, relative to the output folder, manifest.json last.")
      .def_property_readonly(
          "timings_s",
          [](const runner::RunResult& r) {
            py::dict d;
            for (const auto& [stage, seconds] : r.timings_s) d[py::str(stage)] = seconds;
            return d;
          },
          "dict: seconds per stage, in order.")
      .def_readonly("frame_count", &runner::RunResult::frame_count, "Frames written.")
      .def_readonly("vertex_count", &runner::RunResult::vertex_count, "Vertices of the mesh.")
      .def_readonly("field_reused", &runner::RunResult::field_reused, "True when the field came from the cache.")
      .def_readonly("min_scale", &runner::RunResult::min_scale, "Smallest frame scale s (area units).")
      .def_readonly("max_scale", &runner::RunResult::max_scale, "Largest frame scale s (area units).")
      .def("__repr__", [](const runner::RunResult& r) {
        return fmt::format("<pneuma.RunResult {} frames, {} files>", r.frame_count, r.files.size());
      });

  m.def(
      "run",
      [](const py::handle& scenario, const std::filesystem::path& output_dir, bool quiet,
         std::optional<double> edge_m) {
        ScenarioHandle h = to_scenario(scenario);
        if (edge_m) check_argument("edge_m", parameters::kEdge, *edge_m);
        py::gil_scoped_release release;
        if (!h.yaml.empty()) {
          // The manifest records and checksums the scenario file: a dict's is its YAML.
          h.scenario.file = output_dir / "scenario.yaml";
          write_stream_atomically(h.scenario.file, false, [&](std::ostream& out) { out << h.yaml; });
        }
        runner::RunOptions options;
        options.output_dir = output_dir;
        options.quiet = quiet;
        options.edge_override_m = edge_m;
        return runner::run_scenario(h.scenario, options);
      },
      py::arg("scenario"), py::arg("output_dir"), py::kw_only(), py::arg("quiet") = true,
      py::arg("edge_m") = py::none(),
      "run(scenario, output_dir, *, quiet=True, edge_m=None) -> RunResult\n\n"
      "Runs the whole scenario as `pneuma run` does and writes its outputs to output_dir (field.h5 cache, "
      "series.h5/.xdmf, breathing.glb, physiology.csv, ..., manifest.json); a dict scenario is first written to "
      "output_dir/scenario.yaml, which the manifest records. edge_m overrides the mesh edge "
      "length (metres). quiet=False prints the progress bar. Raises pneuma.Error (one line) on any failure; no "
      "partial file is left behind.");
}

}  // namespace pneuma::python
