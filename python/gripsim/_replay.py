"""Recordings read back and checked through the replay's guarded reader."""

from __future__ import annotations

import json
import os

from . import _gripsim
from ._run import Run


def read(path: str | os.PathLike) -> Run:
    """The run recorded in the ``.mcap`` at ``path``, as a :class:`Run`: ``t``,
    ``positions`` and ``velocities`` at the recording's precision (planar: f32 by default;
    3D: f64, steps × nodes × 3), the recorded contacts (3D: step, rod, node, shape, stuck,
    t, x, y, z, normal_force, gap) and events (planar; a 3D recording has none). A file cut short (a killed run) is read up to its last
    complete chunk and ``Run.warning`` says so; a damaged or foreign file raises
    :class:`gripsim.RecordingError` naming it."""
    path = os.fspath(path)
    if path.endswith(".rrd"):
        from ._errors import RecordingError

        raise RecordingError(f"{path}: gripsim.read reads .mcap recordings; open an .rrd "
                             "with rerun", file=path)
    return Run(_gripsim.read_mcap(path))


def check(path: str | os.PathLike) -> dict:
    """``gripsim replay check`` of the ``.mcap`` at ``path`` (planar or 3D) with the default
    thresholds: its report as a dict (``flagged``, the findings and the figures the CLI's
    ``--json`` writes), with ``warning`` set when the file was read only in part."""
    report, warning = _gripsim.check_mcap(os.fspath(path))
    out = json.loads(report)
    out["warning"] = warning
    return out


def diff(a: str | os.PathLike, b: str | os.PathLike) -> dict:
    """``gripsim replay diff A B`` of two recordings (``.mcap``) with the default tolerances:
    its report as a dict (``within_tolerance``, ``first_divergence``, ``parameters``, … as
    the CLI's ``--json`` writes them)."""
    return json.loads(_gripsim.diff_mcap(os.fspath(a), os.fspath(b)))
