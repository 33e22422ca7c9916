"""What the tests share: the repository, its shipped scenarios and the CLI binary of the same
build (GRIPSIM_BIN, set by tests/suite/python.rs)."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BIN = os.environ.get("GRIPSIM_BIN", str(ROOT / "target" / "release" / "gripsim"))


def scenario(name: str) -> Path:
    return ROOT / "scenarios" / f"{name}.toml"


def cli(*args) -> subprocess.CompletedProcess:
    """Run the CLI from the repository root; fail with its output unless it succeeds."""
    out = subprocess.run([BIN, *map(str, args)], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, f"gripsim {args}: {out.returncode}\n{out.stdout}\n{out.stderr}"
    return out


def cli_summary(path, tmp: Path) -> dict:
    """The CLI's `--summary` JSON of a run of `path` without recordings."""
    js = tmp / "summary.json"
    cli("run", "--no-record", "--quiet", "--summary", js, path)
    return json.loads(js.read_text())


def without_wall(d: dict) -> dict:
    return {k: v for k, v in d.items() if k != "wall_time_s"}


@pytest.fixture
def tmp(tmp_path):
    return tmp_path
