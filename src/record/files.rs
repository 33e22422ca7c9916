//! The files of a planar run (`.rrd`, `.mcap`, `.csv`): made before the run, fed by its event
//! stream, closed after it. What `gripsim run` writes, and what the Python package's
//! `gripsim.run(…, rrd=, mcap=, csv=)` writes, made here for both.

use super::auto::{AutoDetail, AutoStats};
use super::background::Background;
use super::csv::CsvSink;
use super::mcap::{McapOptions, McapSink};
use super::rerun::RerunSink;
use super::{
    ArrowScale, AutoRule, Detail, Finished, RecordError, RecordOptions, Recording, Survey,
    ViewOptions,
};
use crate::events::{Fanout, Observer};
use crate::replay::Thresholds;
use crate::scenario::{Precision, Scenario};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The recording options of a planar run of `sc` at `detail` (`auto`: its numbers from the
/// scenario, or the step interval `auto_every` given) with the flush interval `flush_every`
/// (default: the scenario's). `Err`: `auto_every` given with another detail.
pub fn record_options(
    sc: &Scenario,
    detail: Detail,
    auto_every: Option<u64>,
    flush_every: Option<u64>,
) -> Result<RecordOptions, String> {
    let flush_every = flush_every.unwrap_or(sc.flush_every);
    let detail = match (detail, auto_every) {
        (Detail::Auto(_), None) => Detail::Auto(AutoRule::for_scenario(sc)),
        (Detail::Auto(_), Some(k)) => Detail::Auto(AutoRule {
            every: k,
            window: super::auto::WINDOW,
        }),
        (d, None) => d,
        (d, Some(_)) => {
            return Err(format!(
                "--auto-every applies to --detail auto only (got --detail {})",
                d.as_str()
            ))
        }
    };
    Ok(RecordOptions {
        detail,
        // `auto`: the files are made readable every `flush_every` sampled steps (a multiple of
        // k, so always a recorded step), as many recorded steps per chunk as at step detail.
        flush_every: match detail {
            Detail::Auto(a) => flush_every.saturating_mul(a.every),
            _ => flush_every,
        },
    })
}

/// Which files a planar run writes, and how.
#[derive(Debug, Clone, Copy)]
pub struct FileOptions<'a> {
    pub rrd: Option<&'a Path>,
    pub mcap: Option<&'a Path>,
    pub csv: Option<&'a Path>,
    pub opts: RecordOptions,
    /// The `.mcap`'s per-node numbers.
    pub precision: Precision,
    pub arrows: ArrowScale,
}

/// The open files of a planar run.
pub struct PlanarFiles {
    pub sinks: Vec<Box<dyn Recording>>,
    pub opts: RecordOptions,
}

impl PlanarFiles {
    /// Create the files (under their `.partial` names). The drawing sinks draw every frame
    /// with one force scale and one box, chosen from the whole run: an unrecorded first run of
    /// the physics (deterministic) surveys it, stopped early by `interrupt`. On an error the
    /// files created so far are dropped.
    pub fn create(
        sc: &Scenario,
        f: &FileOptions<'_>,
        interrupt: Option<Box<dyn Fn() -> bool + Send>>,
    ) -> Result<PlanarFiles, RecordError> {
        let opts = f.opts;
        // The `.rrd` sink (the Rerun SDK's stream and the blueprint: milliseconds) is made
        // beside the survey, which it does not need until the run starts.
        let (view, rrd) = std::thread::scope(|s| {
            let rrd = f.rrd.map(|p| {
                s.spawn(move || {
                    // The SDK's threads, started here, run as writers (as the sink's own
                    // thread will).
                    super::background::as_writer_thread();
                    RerunSink::create(p, opts, sc)
                })
            });
            let view = if f.rrd.is_some() || f.mcap.is_some() {
                ViewOptions {
                    survey: Some(Survey::of(sc, interrupt)),
                    arrows: f.arrows,
                }
            } else {
                ViewOptions::default()
            };
            let rrd = rrd.map(|h| h.join().expect("the .rrd setup does not panic"));
            (view, rrd)
        });
        let mut sinks: Vec<Box<dyn Recording>> = Vec::new();
        if let (Some(p), Some(rrd)) = (f.rrd, rrd) {
            // The `.rrd` sink runs on a thread of its own, beside the simulation.
            let rrd = rrd?.with_view(view);
            sinks.push(Box::new(Background::start(Box::new(rrd), p, "rrd-sink")?));
        }
        if let Some(p) = f.mcap {
            let mcap = McapOptions {
                precision: f.precision,
                ..Default::default()
            };
            sinks.push(Box::new(
                McapSink::create_with(p, opts, mcap)?.with_view(view),
            ));
        }
        if let Some(p) = f.csv {
            sinks.push(Box::new(CsvSink::create(p, opts)?));
        }
        Ok(PlanarFiles { sinks, opts })
    }

    /// The flags the sinks set when writing failed (disk full): a run polls them to stop.
    pub fn failures(&self) -> Vec<Arc<AtomicBool>> {
        self.sinks.iter().filter_map(|s| s.failure()).collect()
    }

    /// Call `run` with the observer that feeds the files. With `detail` auto, one layer in
    /// front of all of them chooses the steps they get, and the live spike detector (with the
    /// thresholds `th`) lets a spike open a window; its figures are returned.
    pub fn feed<R>(
        &mut self,
        sc: &Scenario,
        th: &Thresholds,
        run: impl FnOnce(&mut dyn Observer) -> R,
    ) -> (R, Option<AutoStats>) {
        let any_file = !self.sinks.is_empty();
        let mut files = Fanout::new();
        for s in self.sinks.iter_mut() {
            files.push(s.as_mut() as &mut dyn Observer);
        }
        match self.opts.detail.auto().filter(|_| any_file) {
            Some(rule) => {
                let spikes = crate::replay::detect::Detector::new(sc, th);
                let mut auto = AutoDetail::new(files, rule, Some(spikes));
                let r = run(&mut auto);
                (r, Some(auto.stats))
            }
            None => (run(&mut files), None),
        }
    }

    /// Close every file (after the run): those closed, and the errors of those that failed.
    pub fn finish(&mut self) -> (Vec<(&'static str, Finished)>, Vec<String>) {
        let mut files = Vec::new();
        let mut errors = Vec::new();
        for s in self.sinks.iter_mut() {
            match s.finish() {
                Ok(f) => files.push((s.format(), f)),
                Err(e) => errors.push(format!("the {} recording failed: {e}", s.format())),
            }
        }
        (files, errors)
    }
}
