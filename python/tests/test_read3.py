"""gripsim.read, check and diff of a 3D run's .mcap (replay's guarded 3D reader) and
gripsim.run(check=True) of a 3D scenario, against the CLI."""

import json

import numpy as np
import pytest

import gripsim
from conftest import cli, scenario


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """3d-two-finger-sphere run by the CLI into an .mcap, and its replay check's JSON."""
    tmp = tmp_path_factory.mktemp("read3")
    path = scenario("3d-two-finger-sphere")
    cli("run", path, "--mcap", tmp / "a.mcap", "--quiet")
    cli("replay", "check", tmp / "a.mcap", "--json", tmp / "check.json")
    return path, tmp


def test_read_of_a_3d_mcap_equals_the_run_bit_for_bit(recorded):
    path, tmp = recorded
    got = gripsim.read(tmp / "a.mcap")
    run = gripsim.run(path, keep=("positions", "velocities"))
    assert got.dimension == 3 and got.completed and got.warning is None
    assert got.rods == run.rods == [("finger0", 10), ("finger1", 10)]
    assert len(got.t) == len(run.t) == 7524
    np.testing.assert_array_equal(got.steps, run.steps)
    np.testing.assert_array_equal(got.t, run.t)
    for a, b in zip(got.positions + got.velocities, run.positions + run.velocities):
        assert a.shape == (7524, 10, 3)
        np.testing.assert_array_equal(a, b)
    # The fingers touch the sphere from step 2471 on, both at node 6, symmetric.
    c = got.contacts
    assert c["step"].min() == 2471
    first = c[c["step"] == 2471]
    assert list(first["rod"]) == [0, 1] and list(first["node"]) == [6, 6]
    assert first["normal_force"].iloc[0] == pytest.approx(5.3665, rel=1e-4)
    assert np.isfinite(c[["x", "y", "z", "normal_force"]].to_numpy()).all()


def test_check_and_diff_of_a_3d_mcap_are_the_cli_reports(recorded):
    _, tmp = recorded
    got = gripsim.check(tmp / "a.mcap")
    want = json.loads((tmp / "check.json").read_text())
    assert got.pop("warning") is None
    assert got == want
    assert want["dimension"] == 3 and want["steps"] == 7523 and not want["flagged"]
    d = gripsim.diff(tmp / "a.mcap", tmp / "a.mcap")
    assert d["within_tolerance"]


def test_a_3d_and_a_planar_recording_are_not_comparable(recorded, tmp):
    _, rec = recorded
    cli("run", scenario("jaw-grasp-hold"), "--set", "solve.t_end=0.05", "--mcap",
        tmp / "p.mcap", "--quiet")
    with pytest.raises(gripsim.RecordingError, match="one is a 3D run, the other is not"):
        gripsim.diff(rec / "a.mcap", tmp / "p.mcap")


def test_run_check_of_a_3d_scenario_counts_what_replay_check_finds(recorded):
    path, tmp = recorded
    r = gripsim.run(path, keep=(), check=True)
    want = json.loads((tmp / "check.json").read_text())
    assert r.check["dimension"] == 3
    assert r.check["flagged"] == want["flagged"] is False
    counts = r.check["counts"]
    assert counts["spikes"] == len(want["spikes"]) == 0
    assert counts["sticking"] == len(want["sticking"]) == 0
    assert sum(counts.values()) == 0
    with pytest.raises(ValueError, match="record a 3D run with `gripsim run`"):
        gripsim.run(path, check=True, mcap=tmp / "b.mcap")
