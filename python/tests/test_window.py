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
    with pytest.raises(ValueError, match="vary is empty"):
        gripsim.window(path, {})
