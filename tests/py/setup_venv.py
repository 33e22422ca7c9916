#!/usr/bin/env python3
"""Create the test venv `.venv` at the repository root with the independent readers that
`tests/recordings.rs` checks recordings with (the Rerun CLI from rerun-sdk, the mcap Python
reader with its protobuf decoder (mcap-protobuf-support, which brings Google's `protobuf`),
jsonschema), and what the Python package's tests need (numpy, pandas, pytest, dask.distributed,
and nbclient, ipykernel and matplotlib for the notebook).

Idempotent and safe to run concurrently: an exclusive file lock serialises callers, and a
marker file inside the venv records which requirements are installed, so a second call only
takes the lock and returns. Needs only python3 (with or without ensurepip) and network access
to PyPI. Prints the venv's directory on success.
"""

import fcntl
import os
import subprocess
import sys
from pathlib import Path

REQUIREMENTS = [
    "rerun-sdk==0.36.3",
    "mcap==1.6.0",
    "jsonschema==4.26.0",
    "mcap-protobuf-support==0.6.0",
    "protobuf==7.36.2",
    # The Python package's pytest suite (python/tests, run by tests/suite/python.rs).
    "numpy==2.4.6",
    "pandas==3.1.1",
    "pytest==9.2.0",
    # gripsim.sweep on a dask.distributed cluster (python/tests/test_sweep.py).
    "dask==2026.8.0",
    "distributed==2026.8.0",
    # docs/notebooks/design-study.ipynb, executed by python/tests/test_notebook.py.
    "nbclient==0.11.0",
    "nbformat==5.11.1",
    "ipykernel==7.4.0",
    "matplotlib==3.11.2",
]

ROOT = Path(__file__).resolve().parents[2]
VENV = Path(os.environ.get("GRIPSIM_TEST_VENV", ROOT / ".venv"))
MARKER = VENV / ".gripsim-test-readers"
WANT = "\n".join(REQUIREMENTS) + "\n"


def run(*cmd):
    subprocess.run([str(c) for c in cmd], check=True)


def create_venv():
    python = VENV / "bin" / "python"
    if not python.exists():
        try:
            run(sys.executable, "-m", "venv", VENV)
        except subprocess.CalledProcessError:
            # Debian's python3 without python3-venv has no ensurepip: make the venv without
            # pip and let the system pip install into it.
            run(sys.executable, "-m", "venv", "--without-pip", VENV)
    if subprocess.run([str(python), "-m", "pip", "--version"], capture_output=True).returncode == 0:
        pip = [python, "-m", "pip"]
    else:
        pip = [sys.executable, "-m", "pip", "--python", python]
    run(*pip, "install", "--disable-pip-version-check", "--quiet", *REQUIREMENTS)


def main():
    VENV.mkdir(parents=True, exist_ok=True)
    with open(VENV / ".gripsim-setup.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (MARKER.exists() and MARKER.read_text() == WANT):
            MARKER.unlink(missing_ok=True)
            create_venv()
            MARKER.write_text(WANT)
    print(VENV)


if __name__ == "__main__":
    main()
