"""gripsim.run writing the CLI's files: the same files, closed and readable when stopped."""

import _thread
import threading

import numpy as np
import pytest

import gripsim
from conftest import cli, scenario


def test_the_files_of_a_run_are_the_cli_files(tmp):
    path = scenario("jaw-grasp-hold")
    r = gripsim.run(path, keep=["positions"], csv=tmp / "py.csv", mcap=tmp / "py.mcap",
                    rrd=tmp / "py.rrd", detail="step")
    assert r.completed
    cli("run", "--quiet", "--detail", "step", "--csv", tmp / "cli.csv", path)
    assert (tmp / "py.csv").read_bytes() == (tmp / "cli.csv").read_bytes()
    rec = gripsim.read(tmp / "py.mcap")
    assert np.array_equal(rec.positions[0], r.positions[0].astype(np.float32).astype(np.float64))
    assert gripsim.check(tmp / "py.mcap")["flagged"] is False
    assert (tmp / "py.rrd").stat().st_size > 10_000
    assert not list(tmp.glob("*.partial"))


def test_auto_detail_keeps_fewer_steps_than_step_detail(tmp):
    path = scenario("jaw-grasp-hold")
    gripsim.run(path, keep=[], mcap=tmp / "auto.mcap")
    r = gripsim.read(tmp / "auto.mcap")
    full = gripsim.run(path, keep=[])
    assert 0 < len(r.steps) < len(full.steps)


def test_an_output_that_is_the_scenario_is_refused_before_anything_is_written(tmp):
    path = tmp / "s.toml"
    path.write_text(scenario("jaw-grasp-hold").read_text())
    before = path.read_bytes()
    with pytest.raises(ValueError, match="s.toml"):
        gripsim.run(path, csv=path)
    assert path.read_bytes() == before
    with pytest.raises(ValueError, match="detail"):
        gripsim.run(path, csv=tmp / "x.csv", detail="often")
    assert not (tmp / "x.csv").exists() and not list(tmp.glob("*.partial"))


def test_ctrl_c_leaves_a_closed_recording_that_replay_reads(tmp):
    sc = gripsim.Scenario.load(scenario("jaw-grasp-hold")).set("solve.t_end", 1000.0)
    timer = threading.Timer(1.0, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            gripsim.run(sc, keep=[], mcap=tmp / "long.mcap", detail="step")
    finally:
        timer.cancel()
    assert not (tmp / "long.mcap").exists()
    partial = tmp / "long.partial.mcap"
    rec = gripsim.read(partial)
    # The drawing's survey of the whole run (before the first recorded step) may be what the
    # interrupt stopped: the file then holds the initial state and the run's end.
    assert rec.completed is False and len(rec.steps) >= 1
    assert (rec.events["kind"] == "run_end").sum() == 1
    report = gripsim.check(partial)
    assert report["warning"] is None
