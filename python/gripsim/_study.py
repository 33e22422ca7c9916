"""Design studies: the CLI's sweep from Python."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from . import _gripsim
from ._run import _scenario
from ._scenario import _set_text


def _vary_spec(key: str, values) -> str:
    """One ``--vary``: ``"START:STOP:COUNT[:log]"`` or ``"V1,V2"`` as given, or a list of
    values (each by the ``--set`` rules)."""
    if isinstance(values, str):
        return f"{key}={values}"
    return f"{key}=" + ",".join(_set_text(v) for v in values)


def _case(scenario: str, sets: list, specs: list, folder: str, index: int, count: int,
          window=None) -> int:
    """One case of a sweep (or one design of a window map) on a Dask worker: the shard
    ``index``/``count`` of one case."""
    from gripsim import _gripsim as native

    report = native.sweep(scenario, sets, specs, folder, 1, (index, count), window)
    return report["ran"]


def sweep(scenario, vary: dict, out: str | os.PathLike | None = None, jobs: int = 0,
          client=None):
    """``gripsim sweep`` of ``scenario`` (a :class:`Scenario` or a file's path; its ``--set``
    overrides apply to every case) over ``vary`` (``{key: "a:b:n" | "v1,v2" | [v1, v2]}``;
    the first key varies slowest), without figures. Returns ``summary.csv`` as a DataFrame,
    one row per case in grid order.

    Without ``client`` the cases run on ``jobs`` local threads (0: one per core). With a
    ``dask.distributed.Client`` each case is one task on its workers (the sweep's shard
    k/N of the one case k, ``gripsim sweep --shard``), and the shards are merged as ``gripsim
    sweep merge`` does: the same table as a local sweep, row for row. The workers need the
    package and the folder ``out`` (a shared file system on a real cluster).

    ``out``: the sweep's folder (case results, ``summary.csv``; a re-run resumes, finished
    cases are skipped); by default a temporary folder that is removed (then, with a client,
    the workers must see this machine's temporary folder). Ctrl-C stops a local sweep
    (finished cases stay in ``out``) and raises ``KeyboardInterrupt``."""
    return _study(scenario, vary, out, jobs, client, None)


def window(scenario, vary: dict | None = None, knob: str | None = None, range: tuple | None = None,
           rtol: float = 0.01, out: str | os.PathLike | None = None, jobs: int = 0,
           client=None):
    """``gripsim window``. Without ``vary``: one grasp-window search of the scenario along
    ``knob`` (by default the squeeze's grip target) over ``range`` ``(LO, HI)`` (by default
    the scenario's value / 8 to × 8) to the relative tolerance ``rtol``, on ``jobs`` threads.
    Returns its runs as a DataFrame sorted by knob ``value`` (the CLI's table: ``value``,
    ``outcome``, ``safety_margin_at_lift``, ``bruise_ratio``, …, ``run`` the order run), and
    the result (``hold`` and ``bruise`` boundaries with ``value``, ``status`` and ``note``,
    ``window_ratio``, ``headline``, the resolved ``knob``) as ``df.attrs["window"]``, what
    ``gripsim window --json`` writes.

    With ``vary``: ``gripsim window --vary``, a map of the grasp window over design
    parameters. Each
    design (a case of ``vary``, as in :func:`sweep`) is one grasp-window search along
    ``knob`` (by default the squeeze's grip target) over ``range`` ``(LO, HI)`` (by default
    the scenario's value / 8 to × 8) to the relative tolerance ``rtol``. Returns
    ``window.csv`` as a DataFrame, one row per design in grid order: the design's values,
    ``g_hold`` and ``g_bruise`` with their brackets and statuses, ``window_ratio``, the
    number of runs. ``out``, ``jobs`` and ``client`` as for :func:`sweep` (with a client each
    design is one task)."""
    spec = (knob, None if range is None else (float(range[0]), float(range[1])), float(rtol))
    if vary:
        return _study(scenario, vary, out, jobs, client, spec)
    if client is not None or out is not None:
        raise ValueError("window: out= and client= go with vary (a map of windows); one "
                         "search runs here")
    return _search(scenario, spec, jobs)


def _search(scenario, spec, jobs):
    """One window search (``gripsim window`` without ``--vary``): its runs as a DataFrame."""
    import json

    import pandas as pd

    sc = _scenario(scenario)
    with tempfile.TemporaryDirectory(prefix="gripsim-window-") as tmp:
        path = Path(sc.file)
        if not path.is_file():
            path = Path(tmp) / "scenario.toml"
            path.write_text(sc.text)
        result = json.loads(_gripsim.window_search(str(path.resolve()), sc.sets, spec, jobs))
    runs = pd.DataFrame(result.pop("runs"))
    runs.insert(len(runs.columns), "run", range(1, len(runs) + 1))
    runs = runs.sort_values("value", kind="stable").reset_index(drop=True)
    runs.attrs["window"] = result
    return runs


def _study(scenario, vary, out, jobs, client, window_spec):
    """A sweep (``window_spec`` None) or a window map, locally or on a Dask client."""
    import pandas as pd

    sc = _scenario(scenario)
    specs = [_vary_spec(k, v) for k, v in vary.items()]
    with tempfile.TemporaryDirectory(prefix="gripsim-sweep-") as tmp:
        path = Path(sc.file)
        if not path.is_file():
            # A scenario made from a text or a dict: its text as a file.
            path = Path(out if out is not None else tmp) / "scenario.toml"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(sc.text)
        folder = Path(out) if out is not None else Path(tmp) / "sweep"
        if client is None:
            report = _gripsim.sweep(str(path.resolve()), sc.sets, specs, str(folder), jobs,
                                    None, window_spec)
            return pd.read_csv(report["summary"])
        n = 1
        for spec in specs:
            n *= len(_gripsim.vary_values(spec))
        futures = [
            client.submit(_case, str(path.resolve()), sc.sets, specs, str(folder.resolve()), k,
                          n, window_spec, pure=False)
            for k in range(n)
        ]
        client.gather(futures)
        return pd.read_csv(_gripsim.merge([str(folder)], str(folder)))
