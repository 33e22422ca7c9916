"""Type stubs of the gripsim package (python/gripsim)."""

import os
from typing import Iterable, Literal

import numpy as np
import numpy.typing as npt
import pandas as pd

__version__: str

_Path = str | os.PathLike[str]

class ScenarioError(ValueError):
    """A scenario that cannot be read: the file, the dotted key and the value at fault."""

    file: str
    key: str
    value: str
    hint: str | None
    message: str

class RecordingError(ValueError):
    """A recording that cannot be read; ``file`` names it."""

    file: str | None
    message: str

class Scenario:
    """A scenario (planar or 3D) and its ``--set`` overrides, checked when made or changed."""

    text: str
    file: str
    dir: str
    sets: list[str]
    def __init__(
        self, text: str, file: str = ..., dir: _Path = ..., sets: list[str] | None = ...
    ) -> None: ...
    @classmethod
    def load(cls, path: _Path, sets: list[str] | None = ...) -> Scenario:
        """The scenario in the TOML file ``path``."""
    @classmethod
    def from_toml(cls, text: str, name: str = ...) -> Scenario:
        """The scenario in the TOML ``text``."""
    @classmethod
    def from_dict(cls, d: dict, name: str = ...) -> Scenario:
        """The scenario whose sections are the dict ``d``."""
    def set(self, key: str, value: str | bool | int | float | list) -> Scenario:
        """Override ``key`` (``"rod.0.E"``) by the CLI's ``--set`` rules; checked at once."""
    def validate(self) -> dict:
        """``dimension``, ``name`` and ``warnings``, or raises :class:`ScenarioError`."""
    @property
    def name(self) -> str: ...
    @property
    def dimension(self) -> Literal[2, 3]: ...
    @property
    def warnings(self) -> list[str]: ...

_Keep = Literal["positions", "velocities", "contacts", "bodies", "events"]

class Run:
    """What a run (or a recording read back) gives."""

    summary: dict | None
    completed: bool | None
    error: str | None
    warning: str | None
    dimension: Literal[2, 3]
    rods: list[tuple[str, int]]
    steps: npt.NDArray[np.int64]
    t: npt.NDArray[np.float64]
    positions: list[npt.NDArray[np.float64]] | None
    """One array per rod: steps × nodes × dimension (m)."""
    velocities: list[npt.NDArray[np.float64]] | None
    """One array per rod: steps × nodes × dimension (m/s)."""
    contacts: pd.DataFrame | None
    """One row per contact per step."""
    bodies: pd.DataFrame | None
    """One row per free body per step."""
    body_names: list[str]
    events: pd.DataFrame | None
    """kind, step, t, text."""
    check: dict | None
    """``run(check=True)``: the live replay check's report."""

def run(
    scenario: Scenario | _Path,
    keep: Iterable[_Keep] = ...,
    *,
    rrd: _Path | None = ...,
    mcap: _Path | None = ...,
    csv: _Path | None = ...,
    detail: Literal["auto", "step", "iteration"] = ...,
    check: bool = ...,
) -> Run:
    """Run ``scenario`` to its end with the GIL released (Ctrl-C: ``KeyboardInterrupt``)."""

def read(path: _Path) -> Run:
    """The run recorded in a ``.mcap`` (planar or 3D)."""

def check(path: _Path) -> dict:
    """``gripsim replay check`` of a ``.mcap`` (planar or 3D): its report as a dict."""

def diff(a: _Path, b: _Path) -> dict:
    """``gripsim replay diff A B``: its report as a dict."""

def sweep(
    scenario: Scenario | _Path,
    vary: dict[str, str | list],
    out: _Path | None = ...,
    jobs: int = ...,
    client: object | None = ...,
) -> pd.DataFrame:
    """``gripsim sweep``: its ``summary.csv`` as a DataFrame, one row per case; with a
    ``dask.distributed.Client`` each case runs on its workers."""

def window(
    scenario: Scenario | _Path,
    vary: dict[str, str | list] | None = ...,
    knob: str | None = ...,
    range: tuple[float, float] | None = ...,
    rtol: float = ...,
    out: _Path | None = ...,
    jobs: int = ...,
    client: object | None = ...,
) -> pd.DataFrame:
    """``gripsim window``: without ``vary`` one search, its runs as a DataFrame (the result
    in ``df.attrs["window"]``); with ``vary`` its ``window.csv``, one row per design
    (``g_hold``, ``g_bruise``, their statuses, ``window_ratio``); with a
    ``dask.distributed.Client`` each design's search runs on its workers."""
