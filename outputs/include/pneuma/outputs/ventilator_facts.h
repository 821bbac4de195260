#pragma once
// The ventilator's part of manifest.json: what was set and what the breaths did. Keys are flat
// ("ventilator.settings[0].mode", "ventilator.peak_pressure_cmH2O.mean"), values strings in the
// clinical units their names carry, as every manifest fact.
#include <string>
#include <utility>
#include <vector>

#include "pneuma/physiology/simulate.h"

namespace pneuma::outputs {

// For a protocol with a ventilator driver at any time, else nothing:
// - ventilator.settings[i].*: every ventilator setting in force from `at_s` (the first, and each
//   action that changes the driver or the patient's effort): mode and its settings;
// - ventilator.expiratory_holds: the holds asked for ("at 30 s for 3 s; ...");
// - a summary of the ventilated breaths of physiology-breaths.csv: their count, by breath type
//   and by trigger, missed triggers, double triggers, and the mean, min and max of peak, plateau
//   and mean airway pressure, intrinsic PEEP, delivered tidal volume, inspiratory time, trigger
//   delay (patient triggers) and total PEEP (breaths with an expiratory hold).
std::vector<std::pair<std::string, std::string>> ventilator_facts(const physiology::Protocol& protocol,
                                                                  const physiology::SimulationResult& result);

}  // namespace pneuma::outputs
