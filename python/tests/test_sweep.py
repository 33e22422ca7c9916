"""gripsim.sweep against the CLI's sweep: the same summary.csv."""

import pandas as pd

import gripsim
from conftest import cli, scenario


def test_a_sweep_gives_the_cli_summary_table(tmp):
    path = scenario("jaw-grasp-hold")
    sc = gripsim.Scenario.load(path).set("solve.t_end", 0.3)
    vary = {"obstacle.1.mass": [0.05, 0.1], "friction.mu_s": "0.5:0.7:2"}
    got = gripsim.sweep(sc, vary, jobs=2)
    cli("sweep", path, "--set", "solve.t_end=0.3", "--vary", "obstacle.1.mass=0.05,0.1",
        "--vary", "friction.mu_s=0.5:0.7:2", "--out", tmp / "cli", "--no-plots",
        "--quiet", "--jobs", "2")
    want = pd.read_csv(tmp / "cli" / "summary.csv")
    assert len(got) == len(want) == 4
    wall = [c for c in want.columns if "wall" in c]
    pd.testing.assert_frame_equal(got.drop(columns=wall), want.drop(columns=wall))


def test_a_sweep_of_8_cases_on_a_2_worker_dask_cluster_gives_the_cli_table(tmp):
    from dask.distributed import Client, LocalCluster

    path = scenario("jaw-grasp-hold")
    sc = gripsim.Scenario.load(path).set("solve.t_end", 0.3)
    vary = {"obstacle.1.mass": [0.05, 0.1], "friction.mu_s": "0.5:0.8:4"}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        got = gripsim.sweep(sc, vary, out=tmp / "dask", client=client)
        # Each case ran on a worker process, not here.
        assert len(client.scheduler_info()["workers"]) == 2
    cli("sweep", path, "--set", "solve.t_end=0.3", "--vary", "obstacle.1.mass=0.05,0.1",
        "--vary", "friction.mu_s=0.5:0.8:4", "--out", tmp / "cli", "--no-plots",
        "--quiet", "--jobs", "2")
    want = pd.read_csv(tmp / "cli" / "summary.csv")
    assert len(got) == len(want) == 8
    wall = [c for c in want.columns if "wall" in c]
    pd.testing.assert_frame_equal(got.drop(columns=wall), want.drop(columns=wall))
    # Resuming: a second sweep into the folder skips the finished cases.
    again = gripsim.sweep(sc, vary, out=tmp / "dask", jobs=1)
    pd.testing.assert_frame_equal(again.drop(columns=wall), want.drop(columns=wall))
