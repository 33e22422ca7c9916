//! A recorded planar run read back (`gripsim.read`) through the replay's guarded reader
//! ([`gripsim::replay::read::Run`]), and a recording checked (`gripsim.check`) as
//! `gripsim replay check` does.

use super::{f64_bytes, i64_bytes};
use gripsim::replay::read::Run;
use gripsim::replay::three;
use gripsim::replay::ReplayError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::Path;

/// A `gripsim.RecordingError` (python/gripsim/_errors.py) naming the file.
fn recording_error(py: Python<'_>, e: &ReplayError) -> PyErr {
    let made = (|| {
        let class = py.import("gripsim._errors")?.getattr("RecordingError")?;
        let file = e.file.as_ref().map(|p| p.display().to_string());
        Ok::<_, PyErr>(PyErr::from_value(class.call1((
            e.to_string(),
            file,
            e.message.clone(),
        ))?))
    })();
    made.unwrap_or_else(|err| err)
}

/// The run recorded in the `.mcap` at `path` as `gripsim.run` gives it (no summary: the
/// recording's run end says whether it completed); a cut-short file is read up to its last
/// complete chunk and `warning` says so.
/// A 3D run's `.mcap` is read by [`read_mcap3`].
#[pyfunction]
pub fn read_mcap<'py>(py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyDict>> {
    if three::is_3d_mcap(Path::new(path)) {
        return read_mcap3(py, path);
    }
    let run = py
        .detach(|| Run::load(Path::new(path)))
        .map_err(|e| recording_error(py, &e))?;
    let d = PyDict::new(py);
    d.set_item("dimension", 2)?;
    d.set_item("scenario_text", &run.meta.scenario_text)?;
    d.set_item("precision", &run.meta.precision)?;
    d.set_item("completed", run.completed())?;
    d.set_item("warning", run.warning())?;
    let rods: Vec<(String, usize)> = run
        .meta
        .rods
        .iter()
        .map(|r| (r.name.clone(), r.nodes))
        .collect();
    d.set_item("rods", rods.clone())?;
    let steps: Vec<i64> = run.steps.iter().map(|s| s.step as i64).collect();
    let t: Vec<f64> = run.steps.iter().map(|s| s.t).collect();
    d.set_item("steps", i64_bytes(py, &steps)?)?;
    d.set_item("t", f64_bytes(py, &t)?)?;
    let per_rod = |f: fn(&gripsim::replay::read::RodState) -> &Vec<f64>| {
        (0..rods.len())
            .map(|i| {
                let v: Vec<f64> = run
                    .steps
                    .iter()
                    .flat_map(|s| f(&s.rods[i]).iter().copied())
                    .collect();
                f64_bytes(py, &v)
            })
            .collect::<PyResult<Vec<_>>>()
    };
    d.set_item("positions", per_rod(|r| &r.q)?)?;
    d.set_item("velocities", per_rod(|r| &r.u)?)?;
    d.set_item("contacts", contacts(py, &run)?)?;
    let events: Vec<(String, u64, f64, String)> = run
        .events
        .iter()
        .map(|e| (e.kind.clone(), e.step, e.t, e.message.clone()))
        .collect();
    d.set_item("events", events)?;
    Ok(d)
}

/// A 3D run's `.mcap` through the replay's guarded 3D reader ([`three::Run3`]): `t`, per-rod
/// positions and velocities (steps × nodes × 3, as recorded: f64) and the recorded contacts;
/// no events (a 3D recording's contact changes are in its steps).
fn read_mcap3<'py>(py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyDict>> {
    let run = py
        .detach(|| three::Run3::load(Path::new(path)))
        .map_err(|e| recording_error(py, &e))?;
    let d = PyDict::new(py);
    d.set_item("dimension", 3)?;
    d.set_item("scenario_text", &run.scenario_text)?;
    d.set_item("precision", "f64")?;
    d.set_item("completed", !run.incomplete())?;
    let warning = run.truncated.as_ref().map(|why| {
        format!("{path}: read up to its last complete chunk ({why}): the run's end is missing")
    });
    d.set_item("warning", warning)?;
    d.set_item("rods", run.rods.clone())?;
    let steps: Vec<i64> = run.steps.iter().map(|s| s.step as i64).collect();
    let t: Vec<f64> = run.steps.iter().map(|s| s.t).collect();
    d.set_item("steps", i64_bytes(py, &steps)?)?;
    d.set_item("t", f64_bytes(py, &t)?)?;
    let per_rod = |f: fn(&gripsim::record::mcap3::Rod3) -> &Vec<f64>| {
        (0..run.rods.len())
            .map(|i| {
                let v: Vec<f64> = run
                    .steps
                    .iter()
                    .flat_map(|s| f(&s.rods[i]).iter().copied())
                    .collect();
                f64_bytes(py, &v)
            })
            .collect::<PyResult<Vec<_>>>()
    };
    d.set_item("positions", per_rod(|r| &r.x)?)?;
    d.set_item("velocities", per_rod(|r| &r.v)?)?;
    d.set_item("contacts", contacts3(py, &run)?)?;
    Ok(d)
}

/// The recorded contacts of every step of a 3D run: one row per contact per step.
fn contacts3<'py>(py: Python<'py>, run: &three::Run3) -> PyResult<Bound<'py, PyList>> {
    let (mut step, mut rod, mut node, mut shape, mut stuck) =
        (vec![], vec![], vec![], vec![], vec![]);
    let mut f: [Vec<f64>; 6] = Default::default();
    for s in &run.steps {
        for c in &s.contacts {
            step.push(s.step as i64);
            rod.push(c.rod as i64);
            node.push(c.node as i64);
            shape.push(c.shape as i64);
            stuck.push(i64::from(c.stuck));
            let p = |k: usize| c.point.get(k).copied().unwrap_or(f64::NAN);
            for (col, v) in f
                .iter_mut()
                .zip([s.t, p(0), p(1), p(2), c.normal_force, c.gap])
            {
                col.push(v);
            }
        }
    }
    let cols = PyList::empty(py);
    for (name, v) in [
        ("step", step),
        ("rod", rod),
        ("node", node),
        ("shape", shape),
        ("stuck", stuck),
    ] {
        cols.append((name, "i8", i64_bytes(py, &v)?))?;
    }
    let names = ["t", "x", "y", "z", "normal_force", "gap"];
    for (name, v) in names.into_iter().zip(f) {
        cols.append((name, "f8", f64_bytes(py, &v)?))?;
    }
    Ok(cols)
}

/// The recorded contacts of every step: one row per contact per step.
fn contacts<'py>(py: Python<'py>, run: &Run) -> PyResult<Bound<'py, PyList>> {
    let (mut step, mut rod, mut node, mut obstacle) = (vec![], vec![], vec![], vec![]);
    let (mut t, mut x, mut y, mut pressure) = (vec![], vec![], vec![], vec![]);
    for s in &run.steps {
        for c in &s.contacts {
            step.push(s.step as i64);
            rod.push(c.rod.map_or(-1, |r| r as i64));
            node.push(c.node as i64);
            obstacle.push(c.obstacle as i64);
            t.push(s.t);
            x.push(c.point[0]);
            y.push(c.point[1]);
            pressure.push(c.peak_pressure);
        }
    }
    let cols = PyList::empty(py);
    for (name, v) in [
        ("step", step),
        ("rod", rod),
        ("node", node),
        ("obstacle", obstacle),
    ] {
        cols.append((name, "i8", i64_bytes(py, &v)?))?;
    }
    for (name, v) in [("t", t), ("x", x), ("y", y), ("peak_pressure", pressure)] {
        cols.append((name, "f8", f64_bytes(py, &v)?))?;
    }
    Ok(cols)
}

/// `gripsim replay check` of the recording at `path` with the default thresholds: its report
/// as JSON text, and the warning of a recording read only in part.
#[pyfunction]
pub fn check_mcap(py: Python<'_>, path: &str) -> PyResult<(String, Option<String>)> {
    let th = gripsim::replay::Thresholds::DEFAULT;
    if three::is_3d_mcap(Path::new(path)) {
        let report = py
            .detach(|| three::check(Path::new(path), &th))
            .map_err(|e| recording_error(py, &e))?;
        let warning = report.truncated.clone();
        let json = serde_json::to_string(&report)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        return Ok((json, warning));
    }
    let (report, warning) = py
        .detach(|| gripsim::replay::check(Path::new(path), &th))
        .map_err(|e| recording_error(py, &e))?;
    let json = serde_json::to_string(&report)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    Ok((json, warning))
}

/// `gripsim replay diff A B` of two recordings with the default tolerances and thresholds:
/// its report as JSON text (the CLI's `--json`).
#[pyfunction]
pub fn diff_mcap(py: Python<'_>, a: &str, b: &str) -> PyResult<String> {
    use gripsim::replay::diff::diff_files;
    let (tol, th) = (
        gripsim::replay::Tolerances::DEFAULT,
        gripsim::replay::Thresholds::DEFAULT,
    );
    let (pa, pb) = (Path::new(a), Path::new(b));
    let json = match (three::is_3d_mcap(pa), three::is_3d_mcap(pb)) {
        (false, false) => py
            .detach(|| diff_files(pa, pb, &tol, &th))
            .map(|r| serde_json::to_string(&r)),
        (true, true) => py
            .detach(|| gripsim::replay::diff3::diff(pa, pb, &tol, &th))
            .map(|r| serde_json::to_string(&r)),
        _ => Err(ReplayError::new(format!(
            "{a} and {b}: one is a 3D run, the other is not: not comparable"
        ))),
    }
    .map_err(|e| recording_error(py, &e))?;
    json.map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))
}
