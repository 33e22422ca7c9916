//! One way to read and run a scenario of either dimension: [`AnyScenario`] is a planar or a
//! 3D scenario as its text says (`dimension = 2 | 3`), and [`run`] runs it to its end, sending
//! the one event stream ([`crate::events`]) to an observer and returning the one summary
//! ([`crate::record::summary::Summary`]). The CLI's studies and the Python package run
//! scenarios through here; the mechanics below stay two (`solver::Simulation`,
//! `rod3d::World3`).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use crate::events::{Fanout, Observer};
use crate::record::summary::{Summary, SummaryCollector};
use crate::replay::detect::{Counts, Thresholds};
use crate::scenario::three::Scenario3;
use crate::scenario::{Scenario, ScenarioError};
use crate::solver::{SimError, Simulation};

/// A scenario of either dimension.
#[derive(Debug, Clone)]
pub enum AnyScenario {
    Planar(Box<Scenario>),
    Spatial(Box<Scenario3>),
}

/// Asked between steps: when it says true the run stops there ([`RunError::interrupted`]).
pub type Stop = Arc<dyn Fn() -> bool + Send + Sync>;

impl AnyScenario {
    /// Read the file at `path` once (a pipe or FIFO too) and parse it with the `--set`
    /// overrides `sets`; also returns its text (recordings keep it).
    pub fn read(path: &Path, sets: &[String]) -> Result<(String, AnyScenario), ScenarioError> {
        let text = crate::scenario::input::read_text(path)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let sc = AnyScenario::parse(&text, &path.display().to_string(), dir, sets)?;
        Ok((text, sc))
    }

    /// Parse `text` (named `file` in messages; a 3D mesh's `file` is relative to `dir`) with
    /// the overrides `sets`.
    pub fn parse(
        text: &str,
        file: &str,
        dir: &Path,
        sets: &[String],
    ) -> Result<AnyScenario, ScenarioError> {
        Ok(if crate::scenario::three::is_3d(text) {
            AnyScenario::Spatial(Box::new(Scenario3::from_str_with(text, file, dir, sets)?))
        } else {
            AnyScenario::Planar(Box::new(Scenario::from_str(text, file, sets)?))
        })
    }

    /// 2 or 3.
    pub fn dimension(&self) -> u8 {
        match self {
            AnyScenario::Planar(_) => 2,
            AnyScenario::Spatial(_) => 3,
        }
    }

    /// The scenario's `name`.
    pub fn name(&self) -> &str {
        match self {
            AnyScenario::Planar(s) => &s.name,
            AnyScenario::Spatial(s) => &s.name,
        }
    }

    /// What the reader accepted but a person should know.
    pub fn warnings(&self) -> Vec<String> {
        match self {
            AnyScenario::Planar(s) => s.warnings(),
            AnyScenario::Spatial(s) => s.warnings(),
        }
    }
}

/// Why a run stopped before its end.
#[derive(Debug, Clone, thiserror::Error)]
pub enum RunError {
    #[error("{0}")]
    Planar(#[from] SimError),
    #[error("{message}")]
    Spatial { message: String, interrupted: bool },
    /// The run could not start: its check's thresholds, or a 3D world from its scenario.
    #[error("{0}")]
    Setup(String),
}

impl RunError {
    /// The run was stopped by its [`Stop`] (a signal, a sink that failed, a study ending).
    pub fn interrupted(&self) -> bool {
        match self {
            RunError::Planar(e) => matches!(e, SimError::Interrupted { .. }),
            RunError::Spatial { interrupted, .. } => *interrupted,
            RunError::Setup(_) => false,
        }
    }
}

/// What a run gives: its summary (as far as it went, `completed` false when it stopped
/// early) and why it stopped early, if it did.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub summary: Summary,
    pub error: Option<RunError>,
    /// What `gripsim replay check` would find on the run's recording (spikes, sticking, grasp
    /// and bruise flags), found while it ran: [`run_with`] with thresholds gives it, [`run`]
    /// leaves it None.
    pub check: Option<Counts>,
}

/// Run `sc` (whose text is `text`: the `RunStart` event carries it) to its end, sending the
/// event stream to `obs` (only accepted steps' contact changes reach it) and asking `stop`
/// between steps. `Err` ([`RunError::Setup`]) only when the run cannot start.
pub fn run<O: Observer>(
    sc: &AnyScenario,
    text: &str,
    obs: &mut O,
    stop: Option<Stop>,
) -> Result<Outcome, RunError> {
    run_with(sc, text, obs, stop, None)
}

/// [`run`], and with `check` the replay check's rules (those thresholds; `Default` for
/// `replay check`'s own) run on the live run in either dimension: [`Outcome::check`] holds
/// what they found. `Err` also when the thresholds are not valid.
pub fn run_with<O: Observer>(
    sc: &AnyScenario,
    text: &str,
    obs: &mut O,
    stop: Option<Stop>,
    check: Option<&Thresholds>,
) -> Result<Outcome, RunError> {
    if let Some(th) = check {
        th.validate().map_err(RunError::Setup)?;
    }
    match sc {
        AnyScenario::Planar(sc) => Ok(run_planar(sc, obs, stop, check)),
        AnyScenario::Spatial(sc) => run_spatial(sc, text, obs, stop, check),
    }
}

fn run_planar<O: Observer>(
    sc: &Scenario,
    obs: &mut O,
    stop: Option<Stop>,
    check: Option<&Thresholds>,
) -> Outcome {
    let start = Instant::now();
    let mut sim = Simulation::new(sc);
    if let Some(stop) = stop {
        sim.interrupt = Some(Box::new(move || stop()));
    }
    let mut collector = SummaryCollector::new();
    let mut detector = check.map(|th| crate::replay::detect::DetectObserver::new(sc, th));
    let result = {
        let mut fan = Fanout::new();
        fan.push(&mut collector as &mut dyn Observer);
        if let Some(d) = detector.as_mut() {
            fan.push(d as &mut dyn Observer);
        }
        fan.push(obs as &mut dyn Observer);
        sim.run(&mut crate::record::accepted::AcceptedContacts::new(fan))
    };
    Outcome {
        summary: collector.finish(&sim.stats, start.elapsed().as_secs_f64()),
        error: result.err().map(RunError::Planar),
        check: detector.map(|d| d.detector.finish().counts()),
    }
}

fn run_spatial<O: Observer>(
    sc: &Scenario3,
    text: &str,
    obs: &mut O,
    stop: Option<Stop>,
    check: Option<&Thresholds>,
) -> Result<Outcome, RunError> {
    use crate::rod3d::run3;
    let start = Instant::now();
    let asked = || stop.as_ref().is_some_and(|s| s());
    let (s, result, found) = match check {
        None => {
            let mut events = run3::Events { text, obs };
            let (s, r) = run3::run_full(
                sc,
                None,
                &mut crate::rod3d::events::NullObserver3,
                &mut events,
                &asked,
            )
            .map_err(RunError::Setup)?;
            (s, r, None)
        }
        Some(th) => {
            let detector = crate::replay::three::Detector3::new(sc, th).map_err(RunError::Setup)?;
            let mut spikes = crate::replay::three::Detect3Observer { detector };
            let mut bruise = crate::replay::bruise::BruiseObserver::new(sc.expect.bruised);
            let (s, r) = {
                let mut fan = Fanout::new();
                fan.push(&mut bruise as &mut dyn Observer);
                fan.push(obs as &mut dyn Observer);
                let mut events = run3::Events {
                    text,
                    obs: &mut fan,
                };
                run3::run_full(sc, None, &mut spikes, &mut events, &asked)
                    .map_err(RunError::Setup)?
            };
            let rep = spikes.detector.finish("", &sc.name);
            (
                s,
                r,
                Some(crate::replay::three::counts(&rep, bruise.count())),
            )
        }
    };
    let mut summary = s.to_summary(start.elapsed().as_secs_f64());
    let error = result.err().map(|message| RunError::Spatial {
        interrupted: message.starts_with(run3::INTERRUPTED),
        message,
    });
    if let Some(e) = &error {
        summary.completed = false;
        summary.error = Some(e.to_string());
    }
    Ok(Outcome {
        summary,
        error,
        check: found,
    })
}
