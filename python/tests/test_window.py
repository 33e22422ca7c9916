"""gripsim.window against the CLI's `gripsim window --vary`: the same window.csv."""

import pandas as pd
import pytest

import gripsim
from conftest import cli, scenario


def test_a_window_map_gives_the_cli_window_table(tmp):
    path = scenario("jaw-grasp-hold")
    vary = {"obstacle.1.mass": [0.05, 0.1]}
    got = gripsim.window(path, vary, range=(0.5, 4), rtol=0.05, jobs=2)
    cli("window", path, "--vary", "obstacle.1.mass=0.05,0.1", "--range", "0.5:4",
        "--rtol", "0.05", "--out", tmp / "cli", "--no-plots", "--quiet", "--jobs", "2")
    want = pd.read_csv(tmp / "cli" / "window.csv")
    assert len(got) == len(want) == 2
    pd.testing.assert_frame_equal(got, want)
    # The light fruit is held over the whole range; the heavy one from g_hold = 1.307 N.
    assert list(got["hold_status"]) == ["everywhere", "found"]
    assert got["g_hold"][1] == pytest.approx(1.3075, abs=1e-3)
    assert got["g_hold_other"][1] < got["g_hold"][1] < 1.06 * got["g_hold_other"][1]
    assert got["margin_at_hold"][1] > got["margin_needed"][1]


def test_a_window_map_on_a_2_worker_dask_cluster_gives_the_local_table(tmp):
    from dask.distributed import Client, LocalCluster

    path = scenario("jaw-grasp-hold")
    vary = {"obstacle.1.mass": [0.05, 0.1]}
    local = gripsim.window(path, vary, range=(0.5, 4), rtol=0.05, jobs=1)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        got = gripsim.window(path, vary, range=(0.5, 4), rtol=0.05, out=tmp / "dask",
                             client=client)
    pd.testing.assert_frame_equal(got, local)


def test_a_window_with_a_bad_range_or_no_vary_raises():
    path = scenario("jaw-grasp-hold")
    with pytest.raises(ValueError, match="LO = 4 is not below HI = 0.5"):
        gripsim.window(path, {"obstacle.1.mass": [0.05]}, range=(4, 0.5))
    with pytest.raises(ValueError, match="out= and client= go with vary"):
        gripsim.window(path, out="x")


def no_wall(v):
    """`v` without its wall times (the one number two runs do not share)."""
    if isinstance(v, dict):
        return {k: no_wall(x) for k, x in v.items() if k != "wall_time_s"}
    if isinstance(v, list):
        return [no_wall(x) for x in v]
    return v


def test_one_window_search_gives_the_cli_result_and_table(tmp):
    import json

    path = scenario("jaw-grasp-hold")
    got = gripsim.window(path, range=(0.5, 4), rtol=0.05, jobs=2)
    cli("window", path, "--range", "0.5:4", "--rtol", "0.05", "--json", tmp / "w.json",
        "--quiet", "--jobs", "2")
    want = json.loads((tmp / "w.json").read_text())
    runs = want.pop("runs")
    assert no_wall(got.attrs["window"]) == no_wall(want)
    assert want["hold"]["status"] == "found" and want["bruise"]["status"] == "not_applicable"
    assert want["hold"]["value"] == pytest.approx(got.attrs["window"]["hold"]["value"])
    # The table: one row per run, sorted by knob value, the CLI's numbers (wall time aside).
    assert len(got) == len(runs) == 6
    assert list(got["value"]) == sorted(r["value"] for r in runs)
    by_value = {r["value"]: r for r in runs}
    for _, row in got.iterrows():
        r = by_value[row["value"]]
        assert row["run"] == runs.index(r) + 1
        for k in ["held", "safety_margin_at_lift", "peak_grip_force_n", "steps"]:
            assert row[k] == r[k] or (row[k] != row[k] and r[k] is None)
    held = got[got["outcome"] == "held"]
    assert held["value"].min() == pytest.approx(want["hold"]["value"])
    assert (got[got["value"] < held["value"].min()]["outcome"] != "held").all()
