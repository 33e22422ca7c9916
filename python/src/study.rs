//! `gripsim.sweep`: the CLI's sweep ([`gripsim::study::sweep::run_sweep`]) on local cores with
//! the GIL released, stopped between steps by a Python signal (Ctrl-C).

use gripsim::study::sweep::{
    merge as merge_shards, run_sweep, CasePlots, MergeOptions, SweepOptions,
};
use gripsim::study::window::{
    parse_range, parse_rtol, resolve_file, run_window, Resolved, WindowOptions, WindowSpec,
};
use gripsim::study::Shard;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Sweep the scenario file `scenario` (with `sets` in every case) over the `--vary` specs
/// `vary` into the folder `out` (a re-run resumes) on `jobs` threads (0: one per core), with
/// no figures. Returns the report: `summary` (the path of summary.csv; None when
/// interrupted), `cases`, `ran`, `skipped`, `failed`, `warned`.
/// `shard` (I, N): only the cases k with k mod N = I (`--shard I/N`), whose rows go to
/// `summary.shard-I-of-N.csv` for [`merge`].
/// `window` (knob or None, range (LO, HI) or None, rtol): a window map instead (`gripsim
/// window --vary`): each case is a grasp-window search, and `summary` is window.csv.
#[pyfunction]
#[pyo3(signature = (scenario, sets, vary, out, jobs, shard=None, window=None))]
#[allow(clippy::too_many_arguments)]
pub fn sweep<'py>(
    py: Python<'py>,
    scenario: String,
    sets: Vec<String>,
    vary: Vec<String>,
    out: String,
    jobs: usize,
    shard: Option<(usize, usize)>,
    window: Option<WindowArgs>,
) -> PyResult<Bound<'py, PyDict>> {
    let shard = match shard {
        Some((index, count)) if index < count => Some(Shard { index, count }),
        Some((i, n)) => return Err(PyValueError::new_err(format!("shard {i}/{n}: I < N"))),
        None => None,
    };
    let vary = vary
        .iter()
        .map(|v| gripsim::study::parse_vary(v))
        .collect::<Result<Vec<_>, _>>()
        .map_err(PyValueError::new_err)?;
    let window = match window {
        Some(w) => Some(resolve_window(&scenario, &sets, w)?),
        None => None,
    };
    let raised = Arc::new(Mutex::new(None));
    let opts = SweepOptions {
        scenario: PathBuf::from(scenario),
        vary,
        sets,
        jobs,
        out: PathBuf::from(out),
        shard,
        plots: false,
        case_plots: CasePlots::None,
        window,
        quiet: true,
        stop: Some(super::signal_stop(raised.clone())),
    };
    let report = py.detach(|| run_sweep(&opts));
    if let Some(e) = raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
        return Err(e);
    }
    let report = report.map_err(|e| PyValueError::new_err(e.to_string()))?;
    let d = PyDict::new(py);
    d.set_item("summary", report.summary)?;
    d.set_item("cases", report.cases)?;
    d.set_item("ran", report.ran)?;
    d.set_item("skipped", report.skipped)?;
    d.set_item("failed", report.failed)?;
    d.set_item("warned", report.warned)?;
    Ok(d)
}

/// `gripsim window`'s `--knob`, `--range LO:HI` and `--rtol`.
type WindowArgs = (Option<String>, Option<(f64, f64)>, f64);

/// The window's knob, range and tolerance resolved against the scenario file with `sets`, as
/// `gripsim window` does (the same checks and messages).
fn resolve_window(scenario: &str, sets: &[String], w: WindowArgs) -> PyResult<Resolved> {
    let (knob, range, rtol) = w;
    let bad = |m: String| PyValueError::new_err(m);
    let range = range
        .map(|(lo, hi)| parse_range(&format!("{lo:?}:{hi:?}")))
        .transpose()
        .map_err(bad)?;
    let rtol = parse_rtol(&format!("{rtol:?}")).map_err(bad)?;
    let spec = WindowSpec { knob, range, rtol };
    resolve_file(Path::new(scenario), sets, &spec)
        .map(|(_, r)| r)
        .map_err(|e| bad(e.to_string()))
}

/// `gripsim window SCENARIO` without `--vary`: one grasp-window search of the scenario file
/// with `sets`, on `jobs` threads (0: one per core), the GIL released; its result as the JSON
/// `--json FILE` writes, each run with its `outcome` in words. Ctrl-C stops it (nothing is kept) and raises `KeyboardInterrupt`.
#[pyfunction]
pub fn window_search(
    py: Python<'_>,
    scenario: String,
    sets: Vec<String>,
    window: WindowArgs,
    jobs: usize,
) -> PyResult<String> {
    let (knob, range, rtol) = window;
    let range = range
        .map(|(lo, hi)| parse_range(&format!("{lo:?}:{hi:?}")))
        .transpose()
        .map_err(PyValueError::new_err)?;
    let rtol = parse_rtol(&format!("{rtol:?}")).map_err(PyValueError::new_err)?;
    let raised = Arc::new(Mutex::new(None));
    let opts = WindowOptions {
        scenario: PathBuf::from(scenario),
        sets,
        spec: WindowSpec { knob, range, rtol },
        jobs,
        stop: Some(super::signal_stop(raised.clone())),
    };
    let result = py.detach(|| run_window(&opts, None));
    if let Some(e) = raised.lock().unwrap_or_else(|p| p.into_inner()).take() {
        return Err(e);
    }
    match result.map_err(|e| PyValueError::new_err(e.to_string()))? {
        Some(r) => {
            // Each run with its outcome in words, as the CLI's table says it.
            let mut v = serde_json::to_value(&r)
                .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
            if let Some(runs) = v.get_mut("runs").and_then(|x| x.as_array_mut()) {
                for (j, e) in runs.iter_mut().zip(&r.runs) {
                    j["outcome"] = e.outcome().into();
                }
            }
            Ok(v.to_string())
        }
        None => Err(pyo3::exceptions::PyKeyboardInterrupt::new_err(
            "window search stopped",
        )),
    }
}

/// The values of one `--vary` spec (`KEY=V1,V2` or `KEY=START:STOP:COUNT[:log]`), as `--set`
/// text.
#[pyfunction]
pub fn vary_values(spec: &str) -> PyResult<Vec<String>> {
    gripsim::study::parse_vary(spec)
        .map(|v| v.values)
        .map_err(PyValueError::new_err)
}

/// `gripsim sweep merge DIRS… --out OUT --no-plots`: the path of the merged summary.csv.
#[pyfunction]
pub fn merge(py: Python<'_>, dirs: Vec<String>, out: String) -> PyResult<String> {
    let opts = MergeOptions {
        dirs: dirs.into_iter().map(PathBuf::from).collect(),
        out: Some(PathBuf::from(out)),
        plots: false,
    };
    let report = py
        .detach(|| merge_shards(&opts))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(report.summary.display().to_string())
}
