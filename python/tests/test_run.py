"""gripsim.run against the CLI: the same summary, the same trajectories."""

import tomllib

import numpy as np
import pandas as pd
import pytest

import gripsim
from conftest import cli, cli_summary, scenario, without_wall


def test_run_summary_equals_the_cli_summary_key_for_key(tmp):
    path = scenario("jaw-grasp-hold")
    r = gripsim.run(gripsim.Scenario.load(path))
    want = cli_summary(path, tmp)
    got = r.summary
    assert r.completed and r.error is None
    assert set(got) == set(want)
    for k in without_wall(want):
        assert got[k] == want[k], k
    assert got["steps"] == want["steps"] > 100


def test_run_positions_equal_the_cli_csv(tmp):
    path = scenario("jaw-grasp-hold")
    r = gripsim.run(path)
    csv = tmp / "run.csv"
    cli("run", "--quiet", "--detail", "step", "--csv", csv, path)
    # The CSV holds the shortest text of each f64 (pandas reads it back exactly).
    table = pd.read_csv(csv)
    nodes = table[table["rod"].notna()]
    steps = np.unique(nodes["step"].to_numpy())
    assert np.array_equal(steps, r.steps), (len(steps), len(r.steps))
    assert len(r.positions) == len(r.rods) >= 1
    for i, (name, n) in enumerate(r.rods):
        rod = nodes[nodes["rod"] == name].sort_values(["step", "node"], kind="stable")
        xy = rod[["x", "y"]].to_numpy().reshape(len(steps), n, 2)
        assert r.positions[i].shape == (len(steps), n, 2)
        assert np.array_equal(r.positions[i], xy), name
        vxy = rod[["vx", "vy"]].to_numpy().reshape(len(steps), n, 2)
        assert np.array_equal(r.velocities[i], vxy), name
    t = nodes.groupby("step")["t"].first().to_numpy()
    assert np.array_equal(r.t, t)


def test_a_3d_scenario_runs_with_three_components(tmp):
    path = scenario("3d-two-finger-sphere")
    sc = gripsim.Scenario.load(path)
    assert sc.dimension == 3
    r = gripsim.run(sc)
    assert r.dimension == 3 and r.completed
    assert len(r.positions) >= 2
    for p, (_, n) in zip(r.positions, r.rods):
        assert p.shape == (len(r.t), n, 3)
        assert np.isfinite(p).all()
    assert without_wall(r.summary) == without_wall(cli_summary(path, tmp))
    assert np.abs(r.positions[0][:, :, 2]).max() > 0


def test_contacts_and_events_are_tables_of_the_run():
    r = gripsim.run(scenario("jaw-grasp-hold"))
    c = r.contacts
    assert len(c) > 0
    assert {"step", "t", "rod", "node", "normal_force", "friction_force", "stuck"} <= set(c)
    # The peak contact force of the table is the summary's peak reaction of a node.
    assert c["normal_force"].max() > 0
    assert set(c["step"]) <= set(r.steps)
    added = r.events[r.events["kind"] == "contact_added"]
    assert len(added) == r.summary["contacts_added"]


def test_keep_keeps_only_what_is_asked():
    r = gripsim.run(scenario("jaw-grasp-hold"), keep=["positions"])
    assert r.positions is not None and r.velocities is None
    assert r.contacts is None and r.events is None
    with pytest.raises(ValueError, match="keep"):
        gripsim.run(scenario("jaw-grasp-hold"), keep=["forces"])


def test_from_dict_and_from_toml_read_as_the_file():
    path = scenario("jaw-grasp-hold")
    text = path.read_text()
    d = tomllib.loads(text)
    a = gripsim.run(gripsim.Scenario.from_dict(d), keep=[])
    b = gripsim.run(gripsim.Scenario.from_toml(text), keep=[])
    c = gripsim.run(gripsim.Scenario.load(path), keep=[])
    assert without_wall(a.summary) == without_wall(c.summary)
    assert without_wall(b.summary) == without_wall(c.summary)


def test_set_follows_the_cli_set(tmp):
    path = scenario("jaw-grasp-hold")
    sc = gripsim.Scenario.load(path).set("solve.dt", 2e-4)
    assert sc.sets == ["solve.dt=0.0002"]
    js = tmp / "s.json"
    cli("run", "--no-record", "--quiet", "--summary", js, "--set", "solve.dt=0.0002", path)
    import json

    want = json.loads(js.read_text())
    assert without_wall(gripsim.run(sc, keep=[]).summary) == without_wall(want)


def test_check_gives_the_cli_run_check_report(tmp):
    import json

    path = scenario("jaw-grasp-hold")
    r = gripsim.run(path, keep=[], check=True)
    js = tmp / "check.json"
    cli("run", "--no-record", "--quiet", "--check", "--check-json", js, path)
    want = json.loads(js.read_text())
    assert r.check == want
    assert r.check["flagged"] is False
    assert gripsim.run(path, keep=[]).check is None
