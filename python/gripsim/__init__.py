"""gripsim from Python: read scenarios, run them, and get their summaries, trajectories,
contacts and events as numpy arrays and pandas DataFrames.

    import gripsim
    sc = gripsim.Scenario.load("scenarios/jaw-grasp-hold.toml").set("solve.dt", 1e-4)
    r = gripsim.run(sc)
    r.summary["peak_contact_force_n"], r.positions[0].shape   # steps × nodes × dimension
"""

from ._errors import RecordingError, ScenarioError
from ._replay import check, diff, read
from ._gripsim import __version__
from ._run import Run, run
from ._scenario import Scenario
from ._study import sweep, window

__all__ = [
    "RecordingError",
    "Run",
    "Scenario",
    "ScenarioError",
    "__version__",
    "check",
    "diff",
    "read",
    "run",
    "sweep",
    "window",
]
