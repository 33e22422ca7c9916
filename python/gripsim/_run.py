"""Running a scenario and what a run gives."""

from __future__ import annotations

import json
import os

import numpy as np

from . import _gripsim
from ._scenario import Scenario

KEEP = ("positions", "velocities", "contacts", "bodies", "events")


def _table(columns):
    import pandas as pd

    return pd.DataFrame({name: np.frombuffer(data, dtype=dtype) for name, dtype, data in columns})


class Run:
    """What a run gives.

    - ``summary``: dict, the CLI's ``--summary`` JSON (``wall_time_s`` is this run's).
    - ``completed``, ``error``: whether it ran to its end, else why it stopped (a message).
    - ``dimension``: 2 or 3; ``rods``: list of (name, nodes).
    - ``steps``, ``t``: the step number and time (s) of every state (the initial one first).
    - ``positions``, ``velocities``: one array per rod, steps × nodes × dimension (m, m/s).
    - ``contacts``: DataFrame, one row per contact per step (rod/segment/body −1 for none;
      ``stuck`` 1 when sticking): point, normal, normal and friction force, slip velocity,
      utilisation, and a compliant fruit's indentation, half-width and peak pressure.
    - ``bodies``: DataFrame, one row per free body per step (centroid, angle, velocity,
      contact force).
    - ``events``: DataFrame of contact changes, stick/slip switches, phases, dt changes and
      warnings (kind, step, t, text).
    - ``check``: with ``check=True``, the live replay check's report (dict), else ``None``.

    What was not kept (``gripsim.run(..., keep=...)``) is ``None``. A run read from a
    recording (:func:`gripsim.read`) has no ``summary`` (``None``), its recorded contacts
    (rod, node, obstacle, point, peak pressure) and events (kind, step, t, text), and
    ``warning`` set when the file was read only in part."""

    def __init__(self, raw: dict):
        if "summary" in raw:
            self.summary = json.loads(raw["summary"])
            self.error = raw["error"]
            self.completed = bool(self.summary.get("completed"))
        else:
            # Read from a recording: its run end says whether it completed.
            self.summary = None
            self.error = None
            self.completed = raw["completed"]
        self.warning = raw.get("warning")
        self.check = json.loads(raw["check"]) if "check" in raw else None
        self.dimension = raw["dimension"]
        self.rods = [tuple(r) for r in raw["rods"]]
        self.steps = np.frombuffer(raw["steps"], dtype=np.int64)
        self.t = np.frombuffer(raw["t"], dtype=np.float64)
        n = len(self.t)
        d = self.dimension

        def arrays(key):
            if key not in raw:
                return None
            return [
                np.frombuffer(b, dtype=np.float64).reshape(n, nodes, d)
                for b, (_, nodes) in zip(raw[key], self.rods)
            ]

        self.positions = arrays("positions")
        self.velocities = arrays("velocities")
        self.contacts = _table(raw["contacts"]) if "contacts" in raw else None
        self.bodies = None
        if "bodies" in raw:
            self.bodies = _table(raw["bodies"])
            self.body_names = list(raw["body_names"])
        self.events = None
        if "events" in raw:
            import pandas as pd

            self.events = pd.DataFrame(raw["events"], columns=["kind", "step", "t", "text"])

    def __repr__(self) -> str:
        state = "completed" if self.completed else f"stopped: {self.error}"
        return f"Run({self.rods!r}, {len(self.t)} states, {state})"


def _scenario(scenario) -> Scenario:
    if isinstance(scenario, Scenario):
        return scenario
    if isinstance(scenario, (str, os.PathLike)):
        return Scenario.load(scenario)
    raise TypeError(f"a Scenario or the path of a scenario file, not {type(scenario).__name__}")


def run(scenario, keep=KEEP, *, rrd=None, mcap=None, csv=None, detail="auto",
        check=False) -> Run:
    """Run ``scenario`` (a :class:`Scenario` or a scenario file's path) to its end.

    The GIL is released while it runs; Ctrl-C stops it between steps and raises
    ``KeyboardInterrupt``, its files closed and readable under their ``.partial`` names. A
    run that stops on a failure (a divergence) returns its :class:`Run` as far as it went,
    with ``completed`` False and ``error`` set.

    ``keep``: what to keep in memory (any of ``positions``, ``velocities``, ``contacts``,
    ``bodies``, ``events``); the summary, ``steps`` and ``t`` are always there. ``keep=()``
    with files streams a long run to disk without holding it.

    ``rrd``, ``mcap``, ``csv``: the files ``gripsim run --rrd/--mcap/--csv`` writes (planar
    runs), at ``detail`` ``"auto"``, ``"step"`` or ``"iteration"``; each is written under its
    ``.partial`` name and renamed into place when the run completed.

    ``check``: run ``gripsim replay check``'s rules on the live run, as ``gripsim run
    --check`` does; its report (a dict) is ``Run.check``. A 3D run's is the counts of what
    the check found: ``{"dimension": 3, "flagged": bool, "counts": {"spikes": …,
    "sticking": …, "slip": …, "drop": …, "held": …, "bruise": …, …}}`` (files of a 3D run:
    ``gripsim run``)."""
    sc = _scenario(scenario)
    keep = list(keep)
    unknown = [k for k in keep if k not in KEEP]
    if unknown:
        raise ValueError(f"keep: unknown {unknown!r}; choose from {list(KEEP)!r}")
    paths = [None if p is None else os.fspath(p) for p in (rrd, mcap, csv)]
    return Run(_gripsim.run(sc.text, sc.file, sc.dir, sc.sets, keep, *paths, detail, check))
