"""pneuma: breathing 3D lungs from Python.

Lumped physiology (CVODE) gives the lung volume V(t); a precomputed elastostatic field u moves
the rest mesh: frame = rest + s(V) * u. Arrays are numpy, lengths in metres, volumes in mL where
the name says so. Every failure raises pneuma.Error (or a subclass) with the one-line message the
CLI prints. See docs/python.md for the API.

    import pneuma
    sim = pneuma.simulate("scenarios/quiet-breathing.yaml")
    sim.time_s, sim.volume_mL            # numpy arrays, as in physiology.csv
    field = pneuma.Field(pneuma.phantom("right", edge_m=0.008))
    positions = field.frame(volume_mL=250.0)   # (V, 3), metres
"""
from ._pneuma import (  # noqa: F401
    Animation,
    Error,
    Field,
    InputError,
    IoError,
    Mesh,
    RunResult,
    Scenario,
    Simulation,
    UnsupportedError,
    UsageError,
    ValueError,
    __version__,
    load_mesh,
    load_scenario,
    phantom,
    run,
    simulate,
)

__all__ = [
    "Animation", "Error", "Field", "InputError", "IoError", "Mesh", "RunResult", "Scenario", "Simulation",
    "UnsupportedError", "UsageError", "ValueError", "load_mesh", "load_scenario", "phantom", "run", "simulate",
]
