//! `gripsim._gripsim`: the native half of the `gripsim` Python package (python/gripsim/).
//!
//! It reads scenarios through the library's one reader ([`gripsim::run::AnyScenario`]) and
//! runs them through the one run API ([`gripsim::run::run`]), keeping what Python asked for
//! from the one event stream ([`keep::Keep`]). The GIL is released during a run; Python's
//! signal handlers are run at most every [`SIGNAL_CHECK`] of wall time, and a raised one
//! (Ctrl-C: `KeyboardInterrupt`) stops the run between steps.

mod files;
mod keep;
mod read;
mod study;

use gripsim::run::{AnyScenario, Stop};
use gripsim::scenario::ScenarioError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often a run takes the GIL to let Python handle a signal.
const SIGNAL_CHECK: Duration = Duration::from_millis(50);

/// A `gripsim.ScenarioError` (python/gripsim/_errors.py) carrying the error's parts.
fn scenario_error(py: Python<'_>, e: &ScenarioError) -> PyErr {
    let made = (|| {
        let class = py.import("gripsim._errors")?.getattr("ScenarioError")?;
        let hint = e.hint.clone();
        let err = class.call1((
            e.to_string(),
            e.file.clone(),
            e.key.clone(),
            e.value.clone(),
            hint,
            e.message.clone(),
        ))?;
        Ok::<_, PyErr>(PyErr::from_value(err))
    })();
    made.unwrap_or_else(|err| err)
}

fn parse(
    py: Python<'_>,
    text: &str,
    file: &str,
    dir: &str,
    sets: Vec<String>,
) -> PyResult<AnyScenario> {
    AnyScenario::parse(text, file, Path::new(dir), &sets).map_err(|e| scenario_error(py, &e))
}

/// Parse a scenario's text (named `file` in messages; a 3D mesh's file is relative to `dir`)
/// with the `--set` overrides `sets`; returns its dimension, name and warnings, or raises
/// `gripsim.ScenarioError`.
#[pyfunction]
fn validate<'py>(
    py: Python<'py>,
    text: &str,
    file: &str,
    dir: &str,
    sets: Vec<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let sc = parse(py, text, file, dir, sets)?;
    let d = PyDict::new(py);
    d.set_item("dimension", sc.dimension())?;
    d.set_item("name", sc.name())?;
    d.set_item("warnings", sc.warnings())?;
    Ok(d)
}

/// The TOML text of a scenario given as JSON (Python's `json.dumps` of a dict).
#[pyfunction]
fn toml_from_json(json: &str) -> PyResult<String> {
    let value: toml::Value = serde_json::from_str(json)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("not a scenario: {e}")))?;
    if !value.is_table() {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "a scenario is a table (a dict of its sections)",
        ));
    }
    toml::to_string(&value)
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("not a scenario: {e}")))
}

/// The bytes of `v` in native order, copied once into a Python `bytes`.
fn f64_bytes<'py>(py: Python<'py>, v: &[f64]) -> PyResult<Bound<'py, PyBytes>> {
    PyBytes::new_with(py, std::mem::size_of_val(v), |out| {
        for (o, x) in out.chunks_exact_mut(8).zip(v) {
            o.copy_from_slice(&x.to_ne_bytes());
        }
        Ok(())
    })
}

fn i64_bytes<'py>(py: Python<'py>, v: &[i64]) -> PyResult<Bound<'py, PyBytes>> {
    PyBytes::new_with(py, std::mem::size_of_val(v), |out| {
        for (o, x) in out.chunks_exact_mut(8).zip(v) {
            o.copy_from_slice(&x.to_ne_bytes());
        }
        Ok(())
    })
}

/// The stop of a run: set when a Python signal handler raised (its error is kept to be
/// raised after the run), asked at most every [`SIGNAL_CHECK`].
fn signal_stop(raised: Arc<Mutex<Option<PyErr>>>) -> Stop {
    let stopped = Arc::new(AtomicBool::new(false));
    let last = Mutex::new(Instant::now());
    Arc::new(move || {
        if stopped.load(Ordering::Relaxed) {
            return true;
        }
        let mut last = last.lock().unwrap_or_else(|p| p.into_inner());
        if last.elapsed() < SIGNAL_CHECK {
            return false;
        }
        *last = Instant::now();
        if let Err(e) = Python::attach(|py| py.check_signals()) {
            *raised.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
            stopped.store(true, Ordering::Relaxed);
            return true;
        }
        false
    })
}

/// Run a scenario (its text, name, folder and `--set`s as for [`validate`]) to its end with
/// the GIL released. Keeps in memory what `keep` names (`positions`, `velocities`,
/// `contacts`, `bodies`, `events`) and writes the files named (`rrd`, `mcap`, `csv`, a
/// planar run's, at `detail` `auto`, `step` or `iteration`) as `gripsim run` does: under
/// their `.partial` names, renamed into place when the run completed. Returns a dict of the
/// summary's JSON, the error (None when it completed), `t` and the kept arrays as
/// native-order f64/i64 bytes.
#[pyfunction]
#[pyo3(signature = (text, file, dir, sets, keep, rrd=None, mcap=None, csv=None, detail="auto", check=false))]
#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    text: &str,
    file: &str,
    dir: &str,
    sets: Vec<String>,
    keep: Vec<String>,
    rrd: Option<String>,
    mcap: Option<String>,
    csv: Option<String>,
    detail: &str,
    check: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let sc = parse(py, text, file, dir, sets.clone())?;
    let mut kept = keep::Keep::new(&keep);
    let th = gripsim::replay::Thresholds::DEFAULT;
    if let (true, AnyScenario::Planar(psc)) = (check, &sc) {
        kept.check = Some(gripsim::replay::detect::DetectObserver::new(psc, &th));
    }
    // A 3D run's check: the library's live check ([`gripsim::run::run_with`]), its counts.
    let check3 = check && sc.dimension() == 3;
    let raised = Arc::new(Mutex::new(None));
    let stop = signal_stop(raised.clone());
    let files = files::Files::new(rrd, mcap, csv, detail);
    let outcome = if check3 && !files.is_empty() {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "rrd=, mcap= and csv= record planar runs; record a 3D run with `gripsim run`",
        ));
    } else if files.is_empty() {
        let th = check3.then_some(&th);
        py.detach(|| gripsim::run::run_with(&sc, text, &mut kept, Some(stop), th))
    } else {
        files.run(py, &sc, (text, file, &sets), &mut kept, stop)?
    };
    if let Some(e) = raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
        return Err(e);
    }
    let outcome = outcome.map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    let summary = serde_json::to_string(&outcome.summary)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    d.set_item("summary", summary)?;
    let completed = outcome.error.is_none();
    d.set_item("error", outcome.error.map(|e| e.to_string()))?;
    if let (Some(c), AnyScenario::Planar(psc)) = (kept.check.take(), &sc) {
        // As `gripsim run --check` reports it.
        let mode = match psc.solve.mode {
            gripsim::scenario::Mode::Dynamic => "dynamic",
            _ => "static",
        };
        let report = gripsim::replay::CheckReport::of(
            format!("(run of {file})"),
            &psc.name,
            mode,
            c.detector,
            None,
            Some(completed),
        );
        let json = serde_json::to_string(&report)
            .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
        d.set_item("check", json)?;
    }
    if let (true, Some(c)) = (check3, &outcome.check) {
        let flagged = c.spikes + c.sticking + c.slip + c.drop + c.held + c.bruise > 0;
        let json = serde_json::json!({ "dimension": 3, "flagged": flagged, "counts": c });
        d.set_item("check", json.to_string())?;
    }
    kept.to_python(py, &d)?;
    Ok(d)
}

#[pymodule]
#[pyo3(name = "_gripsim")]
fn gripsim_py(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(validate, m)?)?;
    m.add_function(wrap_pyfunction!(toml_from_json, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(read::read_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(read::check_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(read::diff_mcap, m)?)?;
    m.add_function(wrap_pyfunction!(study::sweep, m)?)?;
    m.add_function(wrap_pyfunction!(study::vary_values, m)?)?;
    m.add_function(wrap_pyfunction!(study::window_search, m)?)?;
    m.add_function(wrap_pyfunction!(study::merge, m)?)?;
    Ok(())
}
