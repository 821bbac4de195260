// pneuma.Simulation and simulate(): a scenario's physiology as numpy arrays, in the physiology
// CSV's columns and units.
#include <fmt/format.h>
#include <pybind11/stl.h>

#include <cmath>
#include <optional>

#include "bindings.h"
#include "pneuma/core/error.h"
#include "pneuma/physiology/columns.h"
#include "scenario_handle.h"

namespace pneuma::python {
namespace {

// The time series of a simulation, in the physiology CSV's units and column names.
struct Simulation {
  py::dict columns;  // name -> (n,) float64
  py::dict breaths;  // name -> (b,) array
  std::vector<std::string> compartments;
  physiology::SolverStats stats;
};

Simulation to_python(const physiology::SimulationResult& r) {
  Simulation out;
  for (const physiology::SeriesColumn& c : physiology::series_columns(r)) {
    std::vector<double> values(r.series.time_s.size());
    for (std::size_t k = 0; k < values.size(); ++k) values[k] = c.at(r.series, k);
    out.columns[py::str(c.name)] = column(values);
  }
  out.compartments = r.compartment_names;
  out.stats = r.stats;
  const auto numpy = py::module_::import("numpy");
  const auto& b = r.breaths;
  for (const physiology::BreathColumn& c : physiology::breath_columns()) {
    if (c.format == physiology::CellFormat::text) {
      py::list words;
      for (const auto& breath : b) words.append(py::str(c.text(breath)));
      out.breaths[c.name] = numpy.attr("array")(words, "str");
      continue;
    }
    std::vector<double> values(b.size());
    for (std::size_t i = 0; i < b.size(); ++i) values[i] = c.number(b[i], i).value_or(std::nan(""));
    py::object array = column(values);
    if (c.format == physiology::CellFormat::whole) array = array.attr("astype")("int64");
    out.breaths[c.name] = array;
  }
  return out;
}

}  // namespace

void register_simulation(py::module_& m) {
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
      .def_readonly(
          "breaths", &Simulation::breaths,
          "dict of per-breath arrays by physiology-breaths.csv column name (completed breaths only): breath, "
          "start_s, duration_s, mode, tidal_volume_mL, minute_ventilation_L_per_min, peak_pressure_cmH2O, "
          "plateau_pressure_cmH2O, peep_cmH2O, dynamic_compliance_mL_per_cmH2O, end_expiratory_volume_mL, "
          "muscle_amplitude_cmH2O, inspired_volume_mL, set_tidal_volume_mL (NaN: none set), trigger, "
          "trigger_delay_s, cycle, inspiratory_time_s, ie_ratio, mean_airway_pressure_cmH2O, "
          "intrinsic_peep_cmH2O, missed_triggers, double_trigger, breath_type, expiratory_hold_s, "
          "total_peep_cmH2O, vti_mL, vte_mL, leak_percent, inspiratory_pressure_cmH2O, alarms, cycle_delay_s, "
          "early_cycling, late_cycling, flow_starvation_cmH2O, flow_starvation (ventilator "
          "columns: '' or NaN for spontaneous breaths; the hold's NaN without one).")
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
}

}  // namespace pneuma::python
