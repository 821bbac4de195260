#pragma once
// Physiology CSV output. Units at the edge are the clinical ones, named in each column:
// volume in mL, flow in L/s, pressures in cmH2O.
#include <filesystem>

#include "pneuma/outputs/output.h"
#include "pneuma/physiology/simulate.h"

namespace pneuma::outputs {

// One row per sample: time_s, volume_mL, flow_L_per_s, airway/alveolar/pleural/muscle
// pressure in cmH2O, then one volume_<compartment>_mL column per compartment (two or more).
void write_time_series_csv(const std::filesystem::path& path, const physiology::SimulationResult& result);

// One row per completed breath: start, mode, tidal volume, minute ventilation, peak and
// plateau pressure, PEEP, dynamic compliance, end-expiratory volume.
void write_breaths_csv(const std::filesystem::path& path, const physiology::SimulationResult& result);

// `outputs: {physiology_csv: true}` (on by default): physiology.csv and physiology-breaths.csv,
// sampled at the scenario's physiology output rate; its manifest facts are the ventilator's
// (ventilator_facts.h).
OutputPlugin physiology_csv_output();

}  // namespace pneuma::outputs
