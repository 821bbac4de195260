#pragma once
// The columns of a simulation's outputs, declared once for every writer: physiology.csv (the time
// series), physiology-breaths.csv (one row per completed breath) and the Python module's
// Simulation.columns / .breaths. Each column has its name (which carries its unit), its unit, how
// the CSV writes it and its value in that unit.
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneuma/physiology/simulate.h"

namespace pneuma::physiology {

// How the CSV writes a cell.
enum class CellFormat {
  fixed6,        // six decimals ("{:.6f}"): times
  significant9,  // nine significant digits ("{:.9g}")
  whole,         // an integer ("{}"): counts, indices, flags
  text,          // a word, as it is
};

// A column of physiology.csv.
struct SeriesColumn {
  std::string name;  // "volume_mL"; a compartment's: "volume_<compartment>_mL"
  const char* unit;  // "mL"
  CellFormat format;
  double (*value)(const TimeSeries&, std::size_t sample);  // in `unit`; null for a compartment's volume
  int compartment = -1;                                    // the compartment whose volume the column is, or -1

  // The value of sample `sample` in `unit`.
  double at(const TimeSeries& series, std::size_t sample) const;
};

// physiology.csv's columns, in order: time_s, volume_mL, flow_L_per_s, the airway, alveolar,
// pleural and muscle pressures in cmH2O, then, for two or more compartments, each one's volume.
std::vector<SeriesColumn> series_columns(const SimulationResult& result);

// A column of physiology-breaths.csv. A number or whole column has `number`, a text column `text`.
struct BreathColumn {
  const char* name;  // "tidal_volume_mL"
  const char* unit;  // "mL"; "" for text, counts and ratios
  CellFormat format;
  // The value in `unit` of the breath at `index` (0 for the first); nothing where the breath has
  // none (ventilator columns of a spontaneous breath, no expiratory hold): an empty CSV cell, NaN
  // in Python.
  std::optional<double> (*number)(const BreathMetrics& breath, std::size_t index);
  const char* (*text)(const BreathMetrics& breath);
};

// physiology-breaths.csv's 36 columns, in order.
std::span<const BreathColumn> breath_columns();

}  // namespace pneuma::physiology
