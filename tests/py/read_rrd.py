#!/usr/bin/env python3
"""An independent reader of gripsim .rrd recordings (the `rerun-sdk` Python package).

Usage: read_rrd.py FILE.rrd

Reads every chunk of the recording with `rerun.experimental.RrdReader` and prints a JSON
report on stdout of what a reviewer relies on when looking at the file:

  iterates      {entity: [{iteration, step, phase, pass, newton_iteration, strips}]} for every
                row of a `scene/<rod>/iterate` entity (strips = number of line strips logged)
  reactions     {entity: [{step, iteration, vectors: [[x, y]], labels: [..]}]} for every row of
                a `scene/<rod>/reactions` entity
  series        {entity: {colors: [u32 rgba], names: [..]}} of every static SeriesLines
  bookmarks     [{text, level, step, sim_time_ns, iteration}] of `events/bookmarks`
  legend        the labels of `scene/legend/scale`
  zoom          [{step, vectors, labels}] of `zoom/contact/indentation` (the indentation arrow of
                the most pressed contact, mm)
  pressure      [{step, strips, colors}] of `scene/pressure` (the pressure along each compliant
                contact: strips = number of pieces, colors = their u32 rgba)
  overlay       {entity: [step, ...]} the steps of the rows of every entity of the replay
                overlays (`scene/flags/**`, `scene/run_b/**`, `scene/largest_difference/**`,
                `diff/**`), sorted
  flag_events   [{text, level, step}] of `events/flags` (the findings of `check --rrd` on 3D)

Columns are found by their component name (the part after the last ':'), so the report does
not depend on how the SDK spells archetype prefixes.
"""

import json
import sys

from rerun.experimental import RrdReader


def column(batch, name):
    """The column whose name ends with `name` (component name), or None."""
    for i, field in enumerate(batch.schema):
        short = field.name.split(":")[-1]
        if short == name or field.name == name:
            return batch.column(i).to_pylist()
    return None


def first(v):
    """The single value of a one-instance component cell (None stays None)."""
    if v is None:
        return None
    if isinstance(v, list):
        return v[0] if v else None
    return v


def main(path):
    rep = {"iterates": {}, "reactions": {}, "series": {}, "bookmarks": [], "legend": [], "zoom": [], "pressure": [], "overlay": {}, "flag_events": []}
    for chunk in RrdReader(path).stream():
        ent = chunk.entity_path
        batch = chunk.to_record_batch()
        n = batch.num_rows
        step = column(batch, "step") or [None] * n
        it = column(batch, "iteration") or [None] * n
        t = column(batch, "sim_time") or [None] * n
        if ent.endswith("/iterate") and ent.startswith("/scene/"):
            phase = column(batch, "phase")
            pas = column(batch, "pass")
            newton = column(batch, "newton_iteration")
            strips = column(batch, "strips")
            rows = rep["iterates"].setdefault(ent, [])
            for k in range(n):
                rows.append(
                    {
                        "iteration": it[k],
                        "step": step[k],
                        "phase": first(phase[k]) if phase else None,
                        "pass": first(pas[k]) if pas else None,
                        "newton_iteration": first(newton[k]) if newton else None,
                        "strips": None if strips is None or strips[k] is None else len(strips[k]),
                    }
                )
        elif ent.endswith("/reactions") and ent.startswith("/scene/") and "/run_b/" not in ent:
            vectors = column(batch, "vectors")
            labels = column(batch, "labels")
            rows = rep["reactions"].setdefault(ent, [])
            for k in range(n):
                if vectors is None or vectors[k] is None:
                    continue
                rows.append(
                    {
                        "step": step[k],
                        "iteration": it[k],
                        "vectors": vectors[k],
                        "labels": labels[k] if labels and labels[k] is not None else [],
                    }
                )
        elif ent.startswith("/events/bookmarks"):
            text = column(batch, "text")
            level = column(batch, "level")
            for k in range(n):
                if text is None or text[k] is None:
                    continue
                rep["bookmarks"].append(
                    {
                        "text": first(text[k]),
                        "level": first(level[k]) if level else None,
                        "step": step[k],
                        "sim_time_ns": t[k] if not hasattr(t[k], "total_seconds") else round(t[k].total_seconds() * 1e9),
                        "iteration": it[k],
                    }
                )
        elif ent == "/zoom/contact/indentation":
            vectors = column(batch, "vectors")
            labels = column(batch, "labels")
            for k in range(n):
                if vectors is None or vectors[k] is None:
                    continue
                rep["zoom"].append({"step": step[k], "vectors": vectors[k], "labels": labels[k] if labels else None})
        elif ent == "/scene/pressure":
            strips = column(batch, "strips")
            colors = column(batch, "colors")
            for k in range(n):
                if strips is None or strips[k] is None:
                    continue
                rep["pressure"].append({"step": step[k], "strips": len(strips[k]), "colors": colors[k] if colors else None})
        elif ent == "/scene/legend/scale":
            labels = column(batch, "labels")
            if labels:
                rep["legend"].extend(x for row in labels if row for x in row)
        if not chunk.is_static and ent.startswith(
            ("/scene/flags/", "/scene/run_b/", "/scene/largest_difference", "/diff/")
        ):
            rep["overlay"].setdefault(ent, []).extend(step)
        if ent == "/events/flags":
            text = column(batch, "text")
            level = column(batch, "level")
            for k in range(n):
                if text is None or text[k] is None:
                    continue
                rep["flag_events"].append({"text": first(text[k]), "level": first(level[k]) if level else None, "step": step[k]})
        if chunk.is_static:
            colors = column(batch, "colors")
            names = column(batch, "names")
            if names is not None and colors is not None and (ent.startswith("/plots/") or ent.startswith("/solver/")):
                rep["series"][ent] = {"colors": colors[-1], "names": names[-1]}
    # Rows of one entity may come in several chunks: order them on the iteration timeline.
    for rows in list(rep["iterates"].values()) + list(rep["reactions"].values()):
        rows.sort(key=lambda r: (r["iteration"] if r["iteration"] is not None else -1))
    rep["zoom"].sort(key=lambda r: r["step"])
    for rows in rep["overlay"].values():
        rows.sort()
    rep["flag_events"].sort(key=lambda r: r["step"])
    rep["pressure"].sort(key=lambda r: r["step"])
    rep["bookmarks"].sort(key=lambda r: (r["iteration"] if r["iteration"] is not None else -1))
    json.dump(rep, sys.stdout, default=str)


if __name__ == "__main__":
    main(sys.argv[1])
