#!/usr/bin/env python3
"""Run the nine bench cases of Pulse's mechanical ventilator validation with pneuma.

    python3 scripts/ventilator-validation.py [--pneuma build/release/cli/pneuma] [--out out/ventilator-validation]

Pulse Physiology Engine validated its ventilator against an IngMar ASL 5000 lung simulator
ventilated by a Drager Evita Infinity V500 (docs/Methodology/MechanicalVentilatorMethodology.md in
Pulse's sources). The lung and ventilator settings and the bench's ground truth below are copied
from Pulse's own data file, src/python/pulse/study/ventilator_analysis/baseline.py (Kitware,
Apache-2.0; the same numbers as .../gt/gt.json), which generates the methodology's tables.

For each case this writes a scenario (one-compartment lung with the published R and C, the
patient's effort at the published rate, muscle pressure and neural inspiratory time, the
ventilator as published), runs `pneuma simulate`, averages the breaths that start after
--settle seconds (the periodic state) and prints a Markdown table of pneuma's numbers next to
the bench's. docs/ventilator-validation.md holds its output and the differences explained.
"""
import argparse
import csv
import math
import pathlib
import subprocess
import sys

# Patient settings (baseline.py "patientSettings"): R cmH2O*s/L, C mL/cmH2O, muscle pressure
# cmH2O, spontaneous rate /min, neural inspiratory time s.
PATIENTS = {
    "Healthy": dict(R=13, C=50, Pmus=13, rate=15, Ti=0.9),
    "Restrictive": dict(R=20, C=30, Pmus=8, rate=25, Ti=0.6),
    "Obstructive": dict(R=21, C=53, Pmus=14, rate=18, Ti=1.0),
}
# Ventilator settings ("ventilatorSettings"); PIP is absolute (Pulse's PeakInspiratoryPressure),
# the flow of VC-AC is the constant inspiratory flow in L/min. Pulse's LeakSeverity (a leak added
# to match the bench's measured leak) has no counterpart in pneuma and is not used.
VENTILATOR = {
    "Healthy_VC_AC": dict(mode="vc_ac", VT=900, Ti=1.0, rate=12, PEEP=5, flow=60),
    "Healthy_PC_AC": dict(mode="pc_ac", Ti=1.0, rate=12, PEEP=5, PIP=19),
    "Healthy_CPAP": dict(mode="cpap_psv", dP=10, PEEP=5, slope=0.2),
    "Restrictive_VC_AC": dict(mode="vc_ac", VT=550, Ti=1.1, rate=12, PEEP=5, flow=40),
    "Restrictive_PC_AC": dict(mode="pc_ac", Ti=1.1, rate=12, PEEP=5, PIP=23),
    "Restrictive_CPAP": dict(mode="cpap_psv", dP=10, PEEP=5, slope=0.2),
    "Obstructive_VC_AC": dict(mode="vc_ac", VT=500, Ti=1.1, rate=12, PEEP=5, flow=40),
    "Obstructive_PC_AC": dict(mode="pc_ac", Ti=1.2, rate=12, PEEP=5, PIP=12),
    "Obstructive_CPAP": dict(mode="cpap_psv", dP=10, PEEP=5, slope=0.2),
}
# The bench's ground truth ("validationData"): rate /min, mean airway pressure cmH2O, tidal
# volume, inspiratory and expiratory tidal volume mL, leak fraction.
BENCH = {
    "Healthy_VC_AC": (15, 7.9, 900, 960, 829, 0.13),
    "Healthy_PC_AC": (15, 8.6, 1047, 1116, 985, 0.12),
    "Healthy_CPAP": (15, 6.9, 905, 941, 827, 0.11),
    "Restrictive_VC_AC": (25, 13, 550, 596, 526, 0.11),
    "Restrictive_PC_AC": (25, 12, 528, 579, 509, 0.13),
    "Restrictive_CPAP": (25, 10, 387, 410, 365, 0.08),
    "Obstructive_VC_AC": (18, 7.3, 493, 518, 462, 0.11),
    "Obstructive_PC_AC": (18, 7.8, 571, 604, 543, 0.11),
    "Obstructive_CPAP": (18, 8.5, 657, 714, 635, 0.15),
}


def scenario(case, duration_s):
    p = PATIENTS[case.split("_")[0]]
    v = VENTILATOR[case]
    te = 60.0 / p["rate"] - p["Ti"]
    lines = [
        f"name: pulse-bench-{case.lower()}",
        f"duration: {duration_s} s",
        "physiology:",
        "  model: single",
        f"  compliance: {p['C']} mL/cmH2O",
        f"  resistance: {p['R']} cmH2O*s/L",
        f"  effort: {{rate: {p['rate']} /min, ie_ratio: '{p['Ti']}:{te:.6g}', muscle_pressure: {p['Pmus']} cmH2O}}",
        "  driver:",
        f"    mode: {v['mode']}",
        f"    peep: {v['PEEP']} cmH2O",
    ]
    if v["mode"] == "vc_ac":
        flow_time = v["VT"] / 1000.0 / (v["flow"] / 60.0)  # s at the set constant flow
        lines += [f"    rate: {v['rate']} /min", f"    tidal_volume: {v['VT']} mL",
                  f"    inspiratory_time: {v['Ti']} s", f"    pause: {v['Ti'] - flow_time:.6g} s"]
    elif v["mode"] == "pc_ac":
        lines += [f"    rate: {v['rate']} /min", f"    inspiratory_pressure: {v['PIP'] - v['PEEP']} cmH2O",
                  f"    inspiratory_time: {v['Ti']} s"]
    else:
        lines += [f"    pressure_support: {v['dP']} cmH2O", f"    rise_time: {v['slope']} s"]
    lines += ["  output_rate: 100 Hz", ""]
    return "\n".join(lines)


def passive_vt_ml(case):
    """Tidal volume of a passive one-compartment lung under the case's ventilator (closed form)."""
    p = PATIENTS[case.split("_")[0]]
    v = VENTILATOR[case]
    if v["mode"] == "vc_ac":
        return float(v["VT"])
    if v["mode"] == "pc_ac":
        tau = p["R"] * p["C"] / 1000.0
        return p["C"] * (v["PIP"] - v["PEEP"]) * (1 - math.exp(-v["Ti"] / tau))
    return float("nan")  # CPAP: a passive patient triggers nothing


def summarise(breaths_csv, settle_s):
    with open(breaths_csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r["start_s"]) >= settle_s]
    duration = sum(float(r["duration_s"]) for r in rows)
    paw = sum(float(r["mean_airway_pressure_cmH2O"]) * float(r["duration_s"]) for r in rows) / duration
    vt = sum(float(r["inspired_volume_mL"]) for r in rows) / len(rows)
    patient = sum(r["trigger"].startswith("patient") for r in rows)
    return dict(rate=60.0 * len(rows) / duration, paw=paw, vt=vt, breaths=len(rows), patient=patient)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pneuma", default="build/release/cli/pneuma")
    parser.add_argument("--out", default="out/ventilator-validation")
    parser.add_argument("--duration", type=float, default=80.0)
    parser.add_argument("--settle", type=float, default=20.0)
    args = parser.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("| case | RR bench | RR pneuma | MAP bench | MAP pneuma | VT bench | VTi / VTe bench | VT pneuma "
          "| VT passive (closed form) | leak bench | patient-triggered |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for case in VENTILATOR:
        yaml = out / f"{case}.yaml"
        yaml.write_text(scenario(case, args.duration))
        csv_path = out / f"{case}.csv"
        subprocess.run([args.pneuma, "simulate", str(yaml), "-o", str(csv_path)], check=True,
                       stdout=subprocess.DEVNULL)
        s = summarise(out / f"{case}-breaths.csv", args.settle)
        rr, paw, vt, vti, vte, leak = BENCH[case]
        passive = passive_vt_ml(case)
        print(f"| {case} | {rr} | {s['rate']:.1f} | {paw} | {s['paw']:.1f} | {vt} | {vti} / {vte} | {s['vt']:.0f} "
              f"| {'-' if math.isnan(passive) else f'{passive:.0f}'} | {leak} | {s['patient']} of {s['breaths']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
