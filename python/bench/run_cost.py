#!/usr/bin/env python3
"""What `gripsim.run` costs against `gripsim run --no-record`: two-prong-grasp (or the scenario
given) without recordings, in blocks. Each block is its own process: BLOCK runs of the CLI
(one process per run, as a user runs it) or BLOCK runs of `gripsim.run` in one fresh Python
process, for each of keep=() (the summary only), keep=("positions",) and the default keep
(positions, velocities, contacts, bodies, events); the blocks alternate ROUNDS times, so a
drift of the machine's load falls on all alike. Reported: the medians of the summary's
`wall_time_s` (the run itself, the same clock in both), and of the CPU time (the Python run's
thread time; the CLI process's user + system time, start-up and parsing included).

Usage (after `cargo build --release --all-targets`, in a venv with numpy and pandas):

    PYTHONPATH=<folder with the package> python python/bench/run_cost.py [SCENARIO] [ROUNDS] [BLOCK]

Interleaving a CLI subprocess and an in-process run one by one measures the machine, not the
package: on a loaded machine the in-process run right after a subprocess waits longer for a
core (its CPU time is unchanged), which is why the blocks are separate processes.
"""

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BIN = os.environ.get("GRIPSIM_BIN", str(ROOT / "target" / "release" / "gripsim"))

PY_BLOCK = """
import json, sys, time
import gripsim
sc = gripsim.Scenario.load(sys.argv[1])
keep = {"none": (), "positions": ("positions",), "default": gripsim._run.KEEP}[sys.argv[2]]
out = []
for _ in range(int(sys.argv[3])):
    c0 = time.thread_time()
    r = gripsim.run(sc, keep=keep)
    out.append((r.summary["wall_time_s"], time.thread_time() - c0))
print(json.dumps(out))
"""


def cli_block(scenario: str, n: int) -> list:
    out = []
    with tempfile.TemporaryDirectory() as tmp:
        js = Path(tmp) / "summary.json"
        for _ in range(n):
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            subprocess.run([BIN, "run", "--no-record", "--quiet", "--summary", js, scenario],
                           check=True)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
            out.append((json.loads(js.read_text())["wall_time_s"], cpu))
    return out


def py_block(scenario: str, keep: str, n: int) -> list:
    text = subprocess.run([sys.executable, "-c", PY_BLOCK, scenario, keep, str(n)], check=True,
                          capture_output=True, text=True).stdout
    return json.loads(text)


def main():
    scenario = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "scenarios/two-prong-grasp.toml")
    rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    block = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    got = {k: [] for k in ["cli", "none", "positions", "default"]}
    for _ in range(rounds):
        got["cli"] += cli_block(scenario, block)
        for keep in ["none", "positions", "default"]:
            got[keep] += py_block(scenario, keep, block)
    names = {"cli": "gripsim run --no-record", "none": "gripsim.run keep=()",
             "positions": "gripsim.run keep=positions", "default": "gripsim.run (default keep)"}
    base = statistics.median(w for w, _ in got["cli"])
    print(f"{Path(scenario).name}: {rounds} rounds of {block} runs each")
    for k, v in got.items():
        wall = statistics.median(w for w, _ in v)
        cpu = statistics.median(c for _, c in v)
        print(f"{names[k]:<30} wall_time_s median {1e3 * wall:7.2f} ms "
              f"({100 * (wall / base - 1):+5.1f} %), CPU median {1e3 * cpu:7.2f} ms")


if __name__ == "__main__":
    main()
