//! The files of a Python run (`gripsim.run(…, rrd=, mcap=, csv=)`): the CLI's planar sinks
//! ([`gripsim::record::files::PlanarFiles`]) on the same event stream as what Python keeps,
//! checked and held as `gripsim run` holds its outputs ([`gripsim::record::plan`]).

use gripsim::events::{Fanout, Observer};
use gripsim::record::files::{record_options, FileOptions, PlanarFiles};
use gripsim::record::plan::OutputPlan;
use gripsim::record::{ArrowScale, Detail};
use gripsim::run::{AnyScenario, Outcome, RunError, Stop};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::Arc;

pub struct Files {
    rrd: Option<PathBuf>,
    mcap: Option<PathBuf>,
    csv: Option<PathBuf>,
    detail: String,
}

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

impl Files {
    pub fn new(
        rrd: Option<String>,
        mcap: Option<String>,
        csv: Option<String>,
        detail: &str,
    ) -> Self {
        Files {
            rrd: rrd.map(PathBuf::from),
            mcap: mcap.map(PathBuf::from),
            csv: csv.map(PathBuf::from),
            detail: detail.to_string(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.rrd.is_none() && self.mcap.is_none() && self.csv.is_none()
    }

    /// Run `sc` (its text, file name and `--set`s in `source`) with the GIL released, the
    /// files fed beside `kept`; the files get their final names when the run completed and
    /// every one was written, else they keep their `.partial` names (closed, readable).
    pub fn run<O: Observer + Send>(
        &self,
        py: Python<'_>,
        sc: &AnyScenario,
        source: (&str, &str, &[String]),
        kept: &mut O,
        stop: Stop,
    ) -> PyResult<Result<Outcome, RunError>> {
        let (text, file, sets) = source;
        let AnyScenario::Planar(psc) = sc else {
            return Err(value_error(
                "rrd=, mcap= and csv= record planar runs; record a 3D run with `gripsim run`",
            ));
        };
        let detail = match self.detail.as_str() {
            "auto" => Detail::Auto(Default::default()),
            "step" => Detail::Step,
            "iteration" => Detail::Iteration,
            other => {
                return Err(value_error(format!(
                    "detail={other:?}: choose 'auto', 'step' or 'iteration'"
                )))
            }
        };
        let opts = record_options(psc, detail, None, None).map_err(value_error)?;
        // Every output its own file, none of them the scenario or a file it reads.
        let mut plan = OutputPlan::new();
        if Path::new(file).is_file() {
            plan.scenario(Path::new(file), text, sets);
        }
        for (what, p) in [("rrd", &self.rrd), ("mcap", &self.mcap), ("csv", &self.csv)] {
            if let Some(p) = p {
                plan.output(what, p);
            }
        }
        plan.check().map_err(value_error)?;
        let held = plan.hold();
        let files = FileOptions {
            rrd: self.rrd.as_deref(),
            mcap: self.mcap.as_deref(),
            csv: self.csv.as_deref(),
            opts,
            precision: psc.precision,
            arrows: ArrowScale::Linear,
        };
        let ran = py.detach(|| {
            let asked = stop.clone();
            let mut recording = PlanarFiles::create(psc, &files, Some(Box::new(move || asked())))?;
            // A file that cannot be written (disk full) stops the run too.
            let failures = recording.failures();
            let stop: Stop =
                Arc::new(move || stop() || failures.iter().any(|f| f.load(Ordering::Relaxed)));
            let (outcome, _) = recording.feed(psc, &gripsim::replay::Thresholds::DEFAULT, |f| {
                let mut fan = Fanout::new();
                fan.push(kept as &mut dyn Observer);
                fan.push(f);
                gripsim::run::run(sc, text, &mut fan, Some(stop))
            });
            let (_, errors) = recording.finish();
            Ok::<_, gripsim::record::RecordError>((outcome, errors))
        });
        let (outcome, errors) = match ran {
            Ok(r) => r,
            Err(e) => {
                held.discard();
                return Err(value_error(format!("cannot create a recording: {e}")));
            }
        };
        if !errors.is_empty() {
            return Err(pyo3::exceptions::PyOSError::new_err(errors.join("; ")));
        }
        if matches!(&outcome, Ok(o) if o.error.is_none()) {
            held.commit()
                .map_err(pyo3::exceptions::PyOSError::new_err)?;
        }
        Ok(outcome)
    }
}
