"""Ctrl-C during a run: KeyboardInterrupt within a second, the run's state released."""

import _thread
import threading
import time

import pytest

import gripsim
from conftest import scenario


def test_ctrl_c_stops_a_long_run_within_a_second():
    # 0.9 s of simulated time runs in about a second; 1000 s would take many minutes.
    sc = gripsim.Scenario.load(scenario("jaw-grasp-hold")).set("solve.t_end", 1000.0)
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        _thread.interrupt_main()

    timer = threading.Timer(0.5, interrupt)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            gripsim.run(sc, keep=[])
        back = time.monotonic()
    finally:
        timer.cancel()
    assert sent, "the run ended before the interrupt"
    assert back - sent[0] < 1.0, f"{back - sent[0]:.3f} s after Ctrl-C"
    # The package still runs after an interrupted run.
    r = gripsim.run(scenario("jaw-grasp-hold"), keep=[])
    assert r.completed
