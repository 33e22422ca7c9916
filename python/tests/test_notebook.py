"""docs/notebooks/design-study.ipynb, executed on a fresh kernel with this build's package (the
kernel inherits PYTHONPATH) in a temporary folder: no cell fails, and its numbers are the
study's."""

import os
import re

import nbformat
from nbclient import NotebookClient

from conftest import ROOT


def text_of(cell) -> str:
    parts = []
    for o in cell.get("outputs", []):
        if o.get("output_type") == "stream":
            parts.append(o["text"])
        elif "data" in o and "text/plain" in o["data"]:
            parts.append(o["data"]["text/plain"])
    return "".join(parts)


def test_the_design_study_notebook_runs_and_finds_the_window(tmp, monkeypatch):
    monkeypatch.setenv("GRIPSIM_ROOT", str(ROOT))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    nb = nbformat.read(ROOT / "docs" / "notebooks" / "design-study.ipynb", as_version=4)
    NotebookClient(nb, timeout=300, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp)}}).execute()
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(o.get("output_type") != "error" for c in code for o in c.get("outputs", []))
    out = "\n".join(text_of(c) for c in code)
    # Two figures (the sweep, the window) reached the notebook as images.
    images = [o for c in code for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(images) == 2
    # The softest prongs (12.5 MPa) let the apple slip (margin 0.777 < 1); the stiffest hold it
    # with margin 3.53.
    m = re.search(r"safety margin from ([\d.]+) to ([\d.]+)", out)
    assert m and abs(float(m.group(1)) - 0.777) < 0.002 and abs(float(m.group(2)) - 3.527) < 0.002
    # The 25 MPa prongs: held from g_hold ≈ 7.46 N, bruised from ≈ 22.4 N (window ratio ≈ 3).
    w = re.search(r"E = 2.5e\+07 Pa: g_hold = ([\d.]+) N", out)
    assert w and abs(float(w.group(1)) - 7.459) < 0.01
    assert "held: peak grip force" in out
    rrd = tmp / "out" / "design-study" / "apple-E2.5e7.rrd"
    assert rrd.stat().st_size > 100_000
    assert "rerun out/design-study/apple-E2.5e7.rrd" in out
