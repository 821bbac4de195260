// Scenarios: pneuma.Scenario, load_scenario (file or dict), simulate, run, Animation.
#include <fmt/format.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <type_traits>

#include "bindings.h"
#include "pneuma/core/atomic_file.h"
#include "pneuma/core/error.h"
#include "pneuma/core/units.h"
#include "pneuma/frame/frame.h"
#include "pneuma/model/compile.h"
#include "pneuma/outputs/voxels_output.h"
#include "pneuma/runner/output_registry.h"
#include "pneuma/runner/runner.h"
#include "pneuma/scenario/scenario.h"

namespace pneuma::python {
namespace {

constexpr double kMl = 1.0 / units::m3_per_ml;
constexpr double kLitre = 1.0 / units::m3_per_litre;
constexpr double kCmH2O = 1.0 / units::pa_per_cmh2o;
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

// pneuma.Scenario: the typed scenario and, for one made from a dict, its YAML text (run()
// writes it to <output>/scenario.yaml, so the manifest records and checksums a real file).
struct ScenarioHandle {
  scenario::Scenario scenario;
  std::string yaml;  // empty for a scenario read from a file
};

ScenarioHandle scenario_from_dict(const py::dict& d) {
  const YAML::Node root = to_yaml(d, "");
  return {runner::read_scenario(config::Node::from_yaml(root, kDictName), kDictName), YAML::Dump(root) + "\n"};
}

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

// The time series of a simulation, in the physiology CSV's units and column names.
struct Simulation {
  py::dict columns;  // name -> (n,) float64
  py::dict breaths;  // name -> (b,) array
  std::vector<std::string> compartments;
  physiology::SolverStats stats;
};

Simulation to_python(const physiology::SimulationResult& r) {
  Simulation out;
  const auto& s = r.series;
  out.columns["time_s"] = column(s.time_s);
  out.columns["volume_mL"] = column(s.volume_m3, kMl);
  out.columns["flow_L_per_s"] = column(s.flow_m3_per_s, kLitre);
  out.columns["airway_pressure_cmH2O"] = column(s.airway_pressure_pa, kCmH2O);
  out.columns["alveolar_pressure_cmH2O"] = column(s.alveolar_pressure_pa, kCmH2O);
  out.columns["pleural_pressure_cmH2O"] = column(s.pleural_pressure_pa, kCmH2O);
  out.columns["muscle_pressure_cmH2O"] = column(s.muscle_pressure_pa, kCmH2O);
  if (r.compartment_names.size() > 1) {
    for (std::size_t c = 0; c < r.compartment_names.size(); ++c) {
      out.columns[py::str("volume_" + r.compartment_names[c] + "_mL")] = column(s.compartment_volume_m3[c], kMl);
    }
  }
  out.compartments = r.compartment_names;
  out.stats = r.stats;

  const auto& b = r.breaths;
  const auto field = [&](auto get, double factor) {
    std::vector<double> values(b.size());
    std::transform(b.begin(), b.end(), values.begin(), get);
    return column(values, factor);
  };
  std::vector<double> number(b.size());
  for (std::size_t i = 0; i < b.size(); ++i) number[i] = static_cast<double>(i + 1);
  py::list modes;
  for (const auto& breath : b) modes.append(py::str(breath.mode));
  out.breaths["breath"] = column(number).attr("astype")("int64");
  out.breaths["start_s"] = field([](const auto& x) { return x.start_s; }, 1.0);
  out.breaths["duration_s"] = field([](const auto& x) { return x.duration_s; }, 1.0);
  out.breaths["mode"] = py::module_::import("numpy").attr("array")(modes, "str");
  out.breaths["tidal_volume_mL"] = field([](const auto& x) { return x.tidal_volume_m3; }, kMl);
  out.breaths["minute_ventilation_L_per_min"] =
      field([](const auto& x) { return x.minute_ventilation_m3_per_s; }, kLitre * 60.0);
  out.breaths["peak_pressure_cmH2O"] = field([](const auto& x) { return x.peak_pressure_pa; }, kCmH2O);
  out.breaths["plateau_pressure_cmH2O"] = field([](const auto& x) { return x.plateau_pressure_pa; }, kCmH2O);
  out.breaths["peep_cmH2O"] = field([](const auto& x) { return x.peep_pa; }, kCmH2O);
  out.breaths["dynamic_compliance_mL_per_cmH2O"] =
      field([](const auto& x) { return x.dynamic_compliance_m3_per_pa; }, kMl / kCmH2O);
  out.breaths["end_expiratory_volume_mL"] = field([](const auto& x) { return x.end_expiratory_volume_m3; }, kMl);
  out.breaths["muscle_amplitude_cmH2O"] = field([](const auto& x) { return x.muscle_amplitude_pa; }, kCmH2O);
  out.breaths["inspired_volume_mL"] = field([](const auto& x) { return x.inspired_volume_m3; }, kMl);
  out.breaths["set_tidal_volume_mL"] =
      field([](const auto& x) { return x.set_tidal_volume_m3 > 0.0 ? x.set_tidal_volume_m3 : std::nan(""); }, kMl);
  // Ventilator columns: empty strings and NaN for spontaneous breaths, as in the CSV.
  const auto ventilated = [](const auto& x) { return *x.trigger != '\0'; };
  py::list triggers, cycles;
  for (const auto& breath : b) {
    triggers.append(py::str(breath.trigger));
    cycles.append(py::str(breath.cycle));
  }
  const auto numpy = py::module_::import("numpy");
  const auto nan = std::nan("");
  out.breaths["trigger"] = numpy.attr("array")(triggers, "str");
  out.breaths["trigger_delay_s"] = field([&](const auto& x) { return ventilated(x) ? x.trigger_delay_s : nan; }, 1.0);
  out.breaths["cycle"] = numpy.attr("array")(cycles, "str");
  out.breaths["inspiratory_time_s"] =
      field([&](const auto& x) { return ventilated(x) ? x.inspiratory_time_s : nan; }, 1.0);
  out.breaths["ie_ratio"] = field(
      [&](const auto& x) { return ventilated(x) ? x.inspiratory_time_s / (x.duration_s - x.inspiratory_time_s) : nan; },
      1.0);
  out.breaths["mean_airway_pressure_cmH2O"] = field([](const auto& x) { return x.mean_airway_pressure_pa; }, kCmH2O);
  out.breaths["intrinsic_peep_cmH2O"] =
      field([&](const auto& x) { return ventilated(x) ? x.intrinsic_peep_pa : nan; }, kCmH2O);
  out.breaths["missed_triggers"] =
      field([](const auto& x) { return static_cast<double>(x.missed_triggers); }, 1.0).attr("astype")("int64");
  out.breaths["double_trigger"] =
      field([](const auto& x) { return x.double_triggered ? 1.0 : 0.0; }, 1.0).attr("astype")("int64");
  py::list types;
  for (const auto& breath : b) types.append(py::str(breath.breath_type));
  out.breaths["breath_type"] = numpy.attr("array")(types, "str");
  out.breaths["expiratory_hold_s"] =
      field([&](const auto& x) { return x.expiratory_hold_s > 0.0 ? x.expiratory_hold_s : nan; }, 1.0);
  out.breaths["total_peep_cmH2O"] =
      field([&](const auto& x) { return x.expiratory_hold_s > 0.0 ? x.total_peep_pa : nan; }, kCmH2O);
  return out;
}

// A scenario's frames in memory: its model (mesh, field, volume map) and the scale of every
// frame, as `pneuma run` computes them, without writing outputs. Two lungs: every per-surface
// value is a dict by side ('right', 'left'); one lung: the value itself, as always.
struct Animation {
  scenario::Scenario scenario;
  std::shared_ptr<const model::Model> model;
  std::vector<double> time_s, lung_volume_m3;
  std::vector<std::vector<double>> scales;  // [lung][frame]
  bool field_reused = false;
  // The voxel outputs' setting (outputs.voxels), made at the first voxels() call.
  std::shared_ptr<const outputs::VoxelsSpec> voxels_spec;
  mutable std::shared_ptr<const outputs::VoxelScene> voxel_scene;

  std::size_t frame_count() const { return time_s.size(); }

  // f(lung index) for the one lung, or {side: f(i)} for two.
  template <class F>
  py::object by_lung(F f) const {
    if (!model->two_lungs()) {
      auto value = f(std::size_t{0});
      if constexpr (std::is_base_of_v<py::handle, decltype(value)>) {
        return py::object(std::move(value));
      } else {
        return py::cast(value);
      }
    }
    py::dict out;
    for (std::size_t i = 0; i < model->lungs.size(); ++i) out[scenario::lung_name(model->lungs[i].side)] = f(i);
    return out;
  }

  py::object frame(std::size_t index) const {
    if (index >= frame_count()) {
      throw ValueError(fmt::format("index: expected a frame index from 0 to {}, got {}", frame_count() - 1, index));
    }
    frame::Frame frame(*model);
    {
      py::gil_scoped_release release;
      frame::FrameInput input{index, time_s[index], lung_volume_m3[index], {}};
      for (std::size_t i = 0; i < scales.size(); ++i) input.scale[i] = scales[i][index];
      frame::advance(*model, input, frame);
    }
    return by_lung([&](std::size_t i) { return points_to_array(frame.lungs[i].positions); });
  }
  // The voxel outputs of frame `index`, as `pneuma run` writes them (outputs.voxels).
  py::dict voxels(std::size_t index) const {
    if (!voxels_spec) {
      throw ValueError("voxels: the scenario has no `outputs: voxels` (the lungs' inside is made only for it)");
    }
    if (index >= frame_count()) {
      throw ValueError(fmt::format("index: expected a frame index from 0 to {}, got {}", frame_count() - 1, index));
    }
    voxels::TimePoint point;
    {
      py::gil_scoped_release release;
      if (!voxel_scene) voxel_scene = std::make_shared<const outputs::VoxelScene>(*model, scenario, *voxels_spec);
      std::vector<double> at;
      for (const auto& lung : scales) at.push_back(lung[index]);
      voxel_scene->compute(at, point);
    }
    const voxels::Grid& grid = voxel_scene->grid();
    const auto nx = static_cast<py::ssize_t>(grid.size[0]), ny = static_cast<py::ssize_t>(grid.size[1]),
               nz = static_cast<py::ssize_t>(grid.size[2]);
    // Indexed [i, j, k(, component)] like the NIfTI files (i fastest in memory).
    auto field = [&](const voxels::DisplacementField& f) {
      constexpr auto d = static_cast<py::ssize_t>(sizeof(double));
      py::array_t<double> out({nx, ny, nz, py::ssize_t{3}}, {3 * d, 3 * d * nx, 3 * d * nx * ny, d});
      std::copy_n(f.displacement_m.front().data(), 3 * f.displacement_m.size(), out.mutable_data());
      return out;
    };
    constexpr auto w = static_cast<py::ssize_t>(sizeof(std::int32_t));
    py::array_t<std::int32_t> labels({nx, ny, nz}, {w, w * nx, w * nx * ny});
    std::copy(point.labels->labels.begin(), point.labels->labels.end(), labels.mutable_data());
    py::dict out;
    out["forward_m"] = field(point.forward);
    out["pullback_m"] = field(point.pullback);
    out["labels"] = labels;
    if (point.ct) {
      constexpr auto f = static_cast<py::ssize_t>(sizeof(float));
      py::array_t<float> ct({nx, ny, nz}, {f, f * nx, f * nx * ny});
      std::copy(point.ct->values.begin(), point.ct->values.end(), ct.mutable_data());
      out["ct"] = ct;
    }
    py::array_t<double> affine({4, 4});
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) affine.mutable_at(r, c) = grid.ijk_to_lps(r, c);
    out["ijk_to_lps"] = affine;
    out["min_jacobian"] = point.jacobian.min;
    out["max_jacobian"] = point.jacobian.max;
    out["folded_tets"] = point.jacobian.folded_tets;
    out["lung_volume_m3"] = voxel_scene->lung_volume_m3(*point.labels);
    return out;
  }
  // The frame whose time is nearest to t (frames are 1 / frame_rate apart).
  std::size_t index_at(double t) const {
    if (!(t >= time_s.front() - 1e-9 && t <= time_s.back() + 1e-9)) {
      throw ValueError(
          fmt::format("time_s: expected a time from {:g} to {:g} s, got {:g}", time_s.front(), time_s.back(), t));
    }
    const auto it = std::lower_bound(time_s.begin(), time_s.end(), t);
    std::size_t k = static_cast<std::size_t>(it - time_s.begin());
    if (k == time_s.size() || (k > 0 && t - time_s[k - 1] <= time_s[k] - t)) --k;
    return k;
  }
};

Animation make_animation(const scenario::Scenario& given, const std::optional<std::filesystem::path>& output_dir,
                         std::optional<double> edge_m) {
  Animation a;
  a.scenario = given;
  // No output folder: the field is computed (or read from an explicit cache file), not cached in one.
  if (!output_dir && a.scenario.field.cache == scenario::FieldCache::automatic)
    a.scenario.field.cache = scenario::FieldCache::off;
  model::CompileOptions options;
  if (output_dir) options.output_dir = *output_dir;
  options.edge_override_m = edge_m;
  if (const scenario::OutputRequest* voxels = a.scenario.output("voxels")) {
    a.voxels_spec = std::make_shared<const outputs::VoxelsSpec>(std::any_cast<outputs::VoxelsSpec>(voxels->settings));
    options.interior = true;
  }
  py::gil_scoped_release release;
  const physiology::SimulationResult drive = scenario::simulate_physiology(a.scenario, a.scenario.frame_rate_hz);
  model::Compiled compiled = model::compile(a.scenario, drive, options);  // what `pneuma run` animates
  a.model = std::make_shared<const model::Model>(std::move(compiled.model));
  a.field_reused = compiled.field_reused;
  a.time_s = drive.series.time_s;
  a.lung_volume_m3 = drive.series.volume_m3;
  for (model::LungScales& lung : compiled.lungs) a.scales.push_back(std::move(lung.scales));
  return a;
}

}  // namespace

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

  py::class_<Simulation>(m, "Simulation",
                         "The physiology of a scenario: time series (numpy arrays in the physiology CSV's columns "
                         "and units) and the per-breath table.")
      .def_property_readonly(
          "time_s", [](const Simulation& s) { return s.columns["time_s"]; }, "(n,) seconds.")
      .def_property_readonly(
          "volume_mL", [](const Simulation& s) { return s.columns["volume_mL"]; },
          "(n,) lung volume above the relaxed volume (FRC at zero pressure), mL.")
      .def_property_readonly(
          "flow_L_per_s", [](const Simulation& s) { return s.columns["flow_L_per_s"]; },
          "(n,) flow into the lung, L/s.")
      .def_property_readonly(
          "airway_pressure_cmH2O", [](const Simulation& s) { return s.columns["airway_pressure_cmH2O"]; },
          "(n,) cmH2O.")
      .def_property_readonly(
          "alveolar_pressure_cmH2O", [](const Simulation& s) { return s.columns["alveolar_pressure_cmH2O"]; },
          "(n,) cmH2O.")
      .def_property_readonly(
          "pleural_pressure_cmH2O", [](const Simulation& s) { return s.columns["pleural_pressure_cmH2O"]; },
          "(n,) cmH2O.")
      .def_property_readonly(
          "muscle_pressure_cmH2O", [](const Simulation& s) { return s.columns["muscle_pressure_cmH2O"]; },
          "(n,) cmH2O.")
      .def_readonly("columns", &Simulation::columns,
                    "dict of every time series by its physiology.csv column name (time_s, volume_mL, flow_L_per_s, "
                    "<airway|alveolar|pleural|muscle>_pressure_cmH2O, and volume_<compartment>_mL for two or more "
                    "compartments), each (n,) float64.")
      .def_readonly("breaths", &Simulation::breaths,
                    "dict of per-breath arrays by physiology-breaths.csv column name (completed breaths only): breath, "
                    "start_s, duration_s, mode, tidal_volume_mL, minute_ventilation_L_per_min, peak_pressure_cmH2O, "
                    "plateau_pressure_cmH2O, peep_cmH2O, dynamic_compliance_mL_per_cmH2O, end_expiratory_volume_mL, "
                    "muscle_amplitude_cmH2O, inspired_volume_mL, set_tidal_volume_mL (NaN: none set), trigger, "
                    "trigger_delay_s, cycle, inspiratory_time_s, ie_ratio, mean_airway_pressure_cmH2O, "
                    "intrinsic_peep_cmH2O, missed_triggers, double_trigger, breath_type, expiratory_hold_s, "
                    "total_peep_cmH2O (ventilator columns: '' or NaN for spontaneous breaths; the hold's NaN "
                    "without one).")
      .def_readonly("compartments", &Simulation::compartments, "Compartment names.")
      .def_property_readonly(
          "solver_stats",
          [](const Simulation& s) {
            py::dict d;
            d["steps"] = s.stats.steps;
            d["rhs_evaluations"] = s.stats.rhs_evaluations;
            d["restarts"] = s.stats.restarts;
            return d;
          },
          "dict: CVODE steps, rhs_evaluations, restarts.")
      .def(
          "__len__", [](const Simulation& s) { return py::len(s.columns["time_s"]); }, "Number of samples.")
      .def("__repr__", [](const Simulation& s) {
        return fmt::format("<pneuma.Simulation {} samples, {} breaths>", py::len(s.columns["time_s"]),
                           py::len(s.breaths["breath"]));
      });

  m.def(
      "simulate",
      [](const py::handle& scenario, std::optional<double> output_rate_hz) {
        const scenario::Scenario s = to_scenario(scenario).scenario;
        if (output_rate_hz && !(*output_rate_hz > 0.0)) {
          throw ValueError(fmt::format("output_rate_hz: expected a positive rate, got {}", *output_rate_hz));
        }
        physiology::SimulationResult r;
        {
          py::gil_scoped_release release;
          r = scenario::simulate_physiology(s, output_rate_hz);
        }
        return to_python(r);
      },
      py::arg("scenario"), py::arg("output_rate_hz") = py::none(),
      "simulate(scenario, output_rate_hz=None) -> Simulation\n\n"
      "Runs only the physiology of a scenario (a Scenario, dict or path), as `pneuma simulate` does: the same "
      "numbers as its physiology.csv, sampled at output_rate_hz (default: the scenario's physiology.output_rate). "
      "Raises pneuma.InputError for a bad scenario, pneuma.Error when the solver fails.");

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
        if (edge_m && !(*edge_m > 0.0))
          throw ValueError(fmt::format("edge_m: expected a positive length, got {}", *edge_m));
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

  py::class_<Animation>(m, "Animation",
                        "A scenario's frames in memory, as `pneuma run` makes them (physiology at the frame rate, "
                        "the field, the volume-to-scale map), without writing outputs.")
      .def(py::init([](const py::handle& scenario, const std::optional<std::filesystem::path>& output_dir,
                       std::optional<double> edge_m) {
             if (edge_m && !(*edge_m > 0.0)) {
               throw ValueError(fmt::format("edge_m: expected a positive length, got {}", *edge_m));
             }
             return make_animation(to_scenario(scenario).scenario, output_dir, edge_m);
           }),
           py::arg("scenario"), py::arg("output_dir") = py::none(), py::kw_only(), py::arg("edge_m") = py::none(),
           "Animation(scenario, output_dir=None, *, edge_m=None)\n\n"
           "scenario: a Scenario, dict or path. output_dir: where the field cache (field.h5) is looked up and "
           "written as in run(); None computes the field without caching it (unless the scenario names a cache "
           "file). edge_m overrides the mesh edge length (metres).")
      .def_property_readonly(
          "time_s", [](const Animation& a) { return column(a.time_s); }, "(N,) frame times, s.")
      .def_property_readonly(
          "volume_mL", [](const Animation& a) { return column(a.lung_volume_m3, kMl); },
          "(N,) lung volume above FRC at each frame (physiology), mL.")
      .def_property_readonly(
          "lungs",
          [](const Animation& a) {
            std::vector<std::string> names;
            for (const model::LungModel& lung : a.model->lungs) names.emplace_back(scenario::lung_name(lung.side));
            return names;
          },
          "The lungs: ['right', 'left'] for two (then every per-surface value below is a dict by side), else "
          "one name ('right', 'left' for a phantom, 'lung' for a file or label map).")
      .def_property_readonly(
          "scales", [](const Animation& a) { return a.by_lung([&](std::size_t i) { return column(a.scales[i]); }); },
          "(N,) the scale s of each frame.")
      .def_property_readonly(
          "frame_count", [](const Animation& a) { return a.frame_count(); }, "N.")
      .def_property_readonly(
          "vertices",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return points_to_array(a.model->lungs[i].rest.vertices); });
          },
          "Rest vertices (V, 3), metres.")
      .def_property_readonly(
          "triangles",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return triangles_to_array(a.model->lungs[i].rest.triangles); });
          },
          "Triangles (F, 3) uint32.")
      .def_property_readonly(
          "unit_displacement",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return points_to_array(a.model->lungs[i].unit_displacement); });
          },
          "u (V, 3), metres per unit scale.")
      .def_property_readonly(
          "rest_volume_m3",
          [](const Animation& a) {
            return a.by_lung([&](std::size_t i) { return a.model->lungs[i].volume_map.volume(0.0); });
          },
          "Enclosed volume of the rest mesh, m^3.")
      .def_property_readonly(
          "share",
          [](const Animation& a) {
            if (!a.model->two_lungs()) return py::cast(a.scenario.mesh.share);
            return a.by_lung([&](std::size_t i) { return a.model->lungs[i].share; });
          },
          "The mesh's share of the lung volume change (mesh.share; two lungs: each lung's).")
      .def_property_readonly(
          "reference_volume_mL", [](const Animation& a) { return a.scenario.mesh.reference_volume_m3 * kMl; },
          "The lung volume the rest mesh shows (mesh.reference_volume), mL.")
      .def_readonly("field_reused", &Animation::field_reused, "True when the field came from the cache.")
      .def("frame", &Animation::frame, py::arg("index"),
           "frame(index) -> (V, 3) float64: the positions of frame `index` (0 to N - 1), metres; its enclosed "
           "volume is rest_volume + share * (volume_mL[index] - reference_volume_mL). Two lungs: a dict by side.")
      .def(
          "frame_at_time", [](const Animation& a, double t) { return a.frame(a.index_at(t)); }, py::arg("time_s"),
          "frame_at_time(time_s) -> (V, 3) float64: the frame nearest to time_s (frames are 1 / frame_rate apart).")
      .def("index_at_time", &Animation::index_at, py::arg("time_s"), "The index of the frame nearest to time_s.")
      .def("voxels", &Animation::voxels, py::arg("index"),
           "voxels(index) -> dict: the voxel outputs of frame `index` as `pneuma run` writes them (the scenario "
           "needs `outputs: voxels`; docs/voxels.md): 'forward_m' and 'pullback_m' (nx, ny, nz, 3) float64 "
           "displacement fields in metres, LPS (forward: where each rest point goes; pull-back: out(x) = in(x + "
           "v(x))), 'labels' (nx, ny, nz) int32 the label map warped to that frame, 'ct' (nx, ny, nz) float32 "
           "where the scenario names an image, 'ijk_to_lps' (4, 4) the grid (metres), 'min_jacobian', "
           "'max_jacobian', 'folded_tets', 'lung_volume_m3' (the warped lungs' voxels).")
      .def("__len__", [](const Animation& a) { return a.frame_count(); })
      .def("__repr__", [](const Animation& a) {
        return fmt::format("<pneuma.Animation '{}' {} frames, {} vertices{}>", a.scenario.name, a.frame_count(),
                           a.model->vertex_count(), a.model->two_lungs() ? " in two lungs" : "");
      });
}

}  // namespace pneuma::python
