#!/usr/bin/python3
"""Write scenarios/rpm-trace.vxp: a Varian RPM 1.6 breathing trace made from a closed form.

    python3 scripts/make-rpm-trace.py [scenarios/rpm-trace.vxp]

Nothing in it was recorded: it is a made-up patient whose marker follows

    theta(t) = 2 pi t / 4 s + 0.6 sin(2 pi t / 23 s)         (the rate wanders, 13.5 to 16.5 /min)
    a(t)     = 0.9 cm (1 + 0.12 sin(2 pi t / 17 s)) ((1 - cos theta) / 2)^1.4   (a flat end-expiration)
             + 0.004 cm/s t + 1.3 cm                        (the baseline sinks as the patient relaxes)

sampled at 25 Hz for 32 s, written as RPM writes it (Data_layout amplitude,phase,timestamp,
validflag,ttlin,mark,ttlout; the amplitude in cm with Scale_factor 10, as plastimatch's readrpm.m
reads it: value * Scale_factor / 10 cm; the timestamp in ms; the
phase in radians with 0 at end-inspiration, marks Z at 0 and P at pi) and with the marker lost for
0.8 s at 20 s (validflag -1, the amplitude meaningless), as when the patient's arm covers it.
The same arguments give the same bytes.
"""
import math
import sys

RATE_HZ = 25.0
DURATION_S = 32.0


def theta(t):
    return 2.0 * math.pi * t / 4.0 + 0.6 * math.sin(2.0 * math.pi * t / 23.0)


def amplitude_cm(t):
    breath = ((1.0 - math.cos(theta(t))) / 2.0) ** 1.4
    return 0.9 * (1.0 + 0.12 * math.sin(2.0 * math.pi * t / 17.0)) * breath + 0.004 * t + 1.3


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "scenarios/rpm-trace.vxp"
    lines = [
        "[Header]",
        "CRC=0",
        "Version=1.6",
        "Data_layout=amplitude,phase,timestamp,validflag,ttlin,mark,ttlout",
        "Patient_ID=pneuma-closed-form",
        "Date=11-24-2026",
        "Total_study_time=%d" % int(DURATION_S),
        "Samples_per_second=%d" % int(RATE_HZ),
        "Scale_factor=10.0",
        "Comment=made by scripts/make-rpm-trace.py from a closed form; not a recording",
        "[Data]",
    ]
    previous_phase = None
    for k in range(int(DURATION_S * RATE_HZ) + 1):
        t = k / RATE_HZ
        phase = (theta(t) - math.pi) % (2.0 * math.pi)  # 0 at end-inspiration (theta = pi)
        mark = ""
        if previous_phase is not None:
            if phase < previous_phase:
                mark = "Z"
            elif previous_phase < math.pi <= phase:
                mark = "P"
        previous_phase = phase
        lost = 20.0 <= t < 20.8
        value = 9.9 if lost else amplitude_cm(t)
        lines.append("%.5f,%.4f,%d,%d,0,%s,0" % (value, phase, round(t * 1000.0), -1 if lost else 0, mark))
    with open(path, "w", newline="\r\n") as out:
        out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
