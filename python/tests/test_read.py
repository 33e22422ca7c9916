"""gripsim.read and gripsim.check of a recorded .mcap against gripsim.run."""

import numpy as np
import pytest

import gripsim
from conftest import cli, scenario


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    mcap = tmp_path_factory.mktemp("rec") / "run.mcap"
    cli("run", "--quiet", "--detail", "step", "--mcap", mcap, scenario("jaw-grasp-hold"))
    return mcap


def test_read_gives_the_run_to_the_recording_f32_precision(recorded):
    run = gripsim.run(scenario("jaw-grasp-hold"), keep=["positions", "velocities"])
    rec = gripsim.read(recorded)
    assert rec.completed is True and rec.warning is None
    assert rec.dimension == 2 and rec.rods == run.rods
    assert np.array_equal(rec.steps, run.steps)
    assert np.array_equal(rec.t, run.t)
    for a, b in zip(rec.positions, run.positions):
        assert a.shape == b.shape
        # The recording holds each node's numbers as f32: the run's rounded once.
        assert np.array_equal(a, b.astype(np.float32).astype(np.float64))
    for a, b in zip(rec.velocities, run.velocities):
        assert np.array_equal(a, b.astype(np.float32).astype(np.float64))
    assert len(rec.contacts) > 0 and set(rec.contacts["step"]) <= set(rec.steps)
    assert (rec.events["kind"] == "run_end").sum() == 1


def test_check_of_a_clean_recording_flags_nothing(recorded):
    report = gripsim.check(recorded)
    assert report["flagged"] is False
    assert report["warning"] is None


def test_a_damaged_recording_raises_naming_the_file(tmp):
    bad = tmp / "bad.mcap"
    bad.write_bytes(b"not an mcap file at all")
    with pytest.raises(gripsim.RecordingError) as e:
        gripsim.read(bad)
    assert e.value.file == str(bad)
    with pytest.raises(gripsim.RecordingError):
        gripsim.check(bad)


def test_diff_of_a_recording_with_itself_and_with_another_run(recorded, tmp):
    same = gripsim.diff(recorded, recorded)
    assert same["within_tolerance"] is True and same["first_divergence"] is None
    other = tmp / "softer.mcap"
    gripsim.run(gripsim.Scenario.load(scenario("jaw-grasp-hold")).set("obstacle.1.mass", 0.2),
                keep=[], mcap=other, detail="step")
    d = gripsim.diff(recorded, other)
    assert d["within_tolerance"] is False
    assert any(p["key"] == "obstacle.1.mass" for p in d["parameters"]), d["parameters"]
