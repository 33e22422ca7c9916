//! Replay: read recorded runs back (MCAP), check one for velocity spikes and sticking nodes,
//! diff two, and turn a recording into a Rerun `.rrd` (docs/replay.md).
//!
//! - [`read`]: the MCAP reader (also for files cut short by a kill).
//! - [`detect`]: the spike and sticking rules.
//! - [`diff`]: two runs aligned on simulated time.
//! - [`overlay`]: the Rerun views of `show`, `check --rrd` and `diff --rrd`.
//!
//! `gripsim replay` parses its arguments with [`ReplayArgs`] and calls [`main`]; the exit
//! status is 0 (clean / within tolerance), 1 (something flagged / out of tolerance) or 2
//! (an error, reported on stderr with the file it concerns).

pub mod detect;
pub mod diff;
pub mod overlay;
pub mod read;

pub use detect::{Findings, Thresholds};
pub use diff::{DiffReport, Tolerances};
pub use read::Run;

use serde::Serialize;
use std::path::{Path, PathBuf};

/// Version of the JSON reports (`--json`); bumped when a field changes meaning or is removed.
pub const REPORT_VERSION: u32 = 1;

/// Why a replay could not be done. Displayed as `FILE: message` when it concerns a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayError {
    pub file: Option<PathBuf>,
    pub message: String,
}

impl ReplayError {
    pub fn file(path: &Path, message: String) -> Self {
        Self {
            file: Some(path.to_path_buf()),
            message,
        }
    }

    pub fn new(message: String) -> Self {
        Self {
            file: None,
            message,
        }
    }
}

impl std::fmt::Display for ReplayError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.file {
            Some(p) => write!(f, "{}: {}", p.display(), self.message),
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for ReplayError {}

/// `gripsim replay …`
#[derive(Debug, clap::Args)]
pub struct ReplayArgs {
    #[command(subcommand)]
    pub command: ReplayCommand,
}

#[derive(Debug, clap::Subcommand)]
pub enum ReplayCommand {
    /// Scan one run for velocity spikes and sticking nodes; exit 1 if any is found.
    ///
    /// Reports every spike (impact, unexplained, alternating) and every sticking episode
    /// (toggling, oscillating, adhesive hold) with rod, node, step, time and the values that
    /// triggered it. The rules and thresholds are explained in docs/replay.md.
    #[command(
        after_help = "Exit status: 0 clean, 1 something flagged, 2 error.\n\nExamples:\n  gripsim replay check recordings/point-mass-plane-dt1e-4.mcap\n  gripsim replay check run.mcap --json out/check.json --rrd out/check.rrd\n  gripsim replay check run.mcap --spike-displacement 1e-6"
    )]
    Check {
        /// The run (the .mcap of `gripsim run --mcap`).
        run: PathBuf,
        /// Write the report as JSON to this file (fields: docs/replay.md).
        #[arg(long, value_name = "FILE.json")]
        json: Option<PathBuf>,
        /// Write the run with the flagged nodes marked, for the Rerun viewer.
        #[arg(long, value_name = "FILE.rrd")]
        rrd: Option<PathBuf>,
        #[command(flatten)]
        thresholds: Thresholds,
    },
    /// Compare two runs on simulated time; exit 1 if they differ beyond the tolerances.
    ///
    /// Lists scenario parameter differences first, then the first divergence, the per-node
    /// maxima of position, velocity and reaction differences, contact events found in one run
    /// only (or shifted in time), and spikes or sticking found in one run only. The runs may
    /// use different or adaptive time steps: the one is interpolated at the other's times.
    #[command(
        after_help = "Exit status: 0 within tolerance, 1 not, 2 error (including runs that cannot be compared).\n\nExamples:\n  gripsim replay diff recordings/golden/point-mass-plane-dt1e-4.mcap out/now.mcap\n  gripsim replay diff a.mcap b.mcap --tol-position 1e-6 --json out/diff.json --rrd out/diff.rrd"
    )]
    Diff {
        /// Run A (the reference).
        a: PathBuf,
        /// Run B (drawn ghosted in --rrd).
        b: PathBuf,
        /// Write the report as JSON to this file (fields: docs/replay.md).
        #[arg(long, value_name = "FILE.json")]
        json: Option<PathBuf>,
        /// Write A and B overlaid (B ghosted), flagged nodes and the first divergence marked.
        #[arg(long, value_name = "FILE.rrd")]
        rrd: Option<PathBuf>,
        #[command(flatten)]
        tolerances: Tolerances,
        #[command(flatten)]
        thresholds: Thresholds,
    },
    /// Turn a recorded run into a Rerun .rrd (the same entities and layout as a live run).
    #[command(
        after_help = "Example:\n  gripsim replay show recordings/seed-grasp-r5.mcap --rrd out/r5.rrd && rerun out/r5.rrd"
    )]
    Show {
        /// The run (the .mcap of `gripsim run --mcap`).
        run: PathBuf,
        /// The .rrd to write.
        #[arg(long, value_name = "FILE.rrd")]
        rrd: PathBuf,
    },
}

/// The report of `replay check`.
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    pub report_version: u32,
    pub file: String,
    pub scenario: String,
    pub mode: String,
    pub steps: usize,
    pub t_end: f64,
    /// Why the file was read only in part (null when whole).
    pub truncated: Option<String>,
    /// The run's own end: true, false (stopped early), null (the file stops before it).
    pub completed: Option<bool>,
    pub thresholds: Thresholds,
    pub counts: detect::Counts,
    pub flagged: bool,
    pub spikes: Vec<detect::Spike>,
    pub sticking: Vec<detect::Sticking>,
}

impl CheckReport {
    pub fn new(run: &Run, th: &Thresholds, found: Findings) -> Self {
        Self {
            report_version: REPORT_VERSION,
            file: run.path.display().to_string(),
            scenario: run.meta.scenario_name.clone(),
            mode: run.meta.mode.clone(),
            steps: run.steps.len(),
            t_end: run.t_end(),
            truncated: run.status.truncated.clone(),
            completed: run.completed(),
            thresholds: *th,
            counts: found.counts(),
            flagged: !found.is_empty(),
            spikes: found.spikes,
            sticking: found.sticking,
        }
    }
}

/// Load and check one run.
pub fn check(path: &Path, th: &Thresholds) -> Result<(Run, CheckReport), ReplayError> {
    th.validate().map_err(ReplayError::new)?;
    let run = Run::load(path)?;
    let found = detect::detect(&run, th);
    let report = CheckReport::new(&run, th, found);
    Ok((run, report))
}

/// At most this many rows per table in the human output (the JSON has them all).
const MAX_ROWS: usize = 40;

fn g(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&x.abs()) {
        let s = format!("{x:.4}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{x:.3e}")
    }
}

/// The human form of a check report.
pub fn format_check(rep: &CheckReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let c = &rep.counts;
    let _ = writeln!(
        s,
        "{}  ({}, {} steps to t = {} s{})",
        rep.file,
        rep.scenario,
        rep.steps,
        g(rep.t_end),
        if rep.truncated.is_some() {
            ", INCOMPLETE"
        } else {
            ""
        }
    );
    let _ = writeln!(
        s,
        "spikes    {:>5}  (impact {}, unexplained {}, alternating {})",
        c.spikes, c.impact, c.unexplained, c.alternating
    );
    let _ = writeln!(
        s,
        "sticking  {:>5}  (toggling {}, oscillating {}, adhesive hold {})",
        c.sticking, c.toggling, c.oscillating, c.adhesive_hold
    );
    if !rep.spikes.is_empty() {
        let _ = writeln!(s, "\nspikes");
        let _ = writeln!(
            s,
            "  {:<12} {:<10} {:>4} {:>9} {:>12} {:>9} {:>10} {:>10} {:>10} {:>10}",
            "kind",
            "rod",
            "node",
            "step",
            "t (s)",
            "dt (s)",
            "|dv| m/s",
            "jump m/s",
            "accel/ref",
            "jump*dt m"
        );
        for x in rep.spikes.iter().take(MAX_ROWS) {
            let step = if x.last_step != x.step {
                format!("{}-{}", x.step, x.last_step)
            } else {
                x.step.to_string()
            };
            let _ = writeln!(
                s,
                "  {:<12} {:<10} {:>4} {:>9} {:>12} {:>9} {:>10} {:>10} {:>10} {:>10}",
                x.kind,
                x.rod_name,
                x.node,
                step,
                g(x.t),
                g(x.dt),
                g(x.dv_norm),
                g(x.jump),
                g(x.accel_ratio),
                g(x.displacement)
            );
        }
        if rep.spikes.len() > MAX_ROWS {
            let _ = writeln!(
                s,
                "  … and {} more (all in --json)",
                rep.spikes.len() - MAX_ROWS
            );
        }
    }
    if !rep.sticking.is_empty() {
        let _ = writeln!(s, "\nsticking");
        let _ = writeln!(
            s,
            "  {:<14} {:<10} {:>4} {:>15} {:>12} {:>12} {:>6} {:>12}",
            "rule", "rod", "node", "steps", "t (s)", "to t (s)", "count", "value"
        );
        for x in rep.sticking.iter().take(MAX_ROWS) {
            let value = match x.rule {
                "oscillating" => format!("{} m", g(x.max_correction)),
                "adhesive_hold" => format!("{} N", g(x.min_normal_reaction)),
                _ => String::new(),
            };
            let _ = writeln!(
                s,
                "  {:<14} {:<10} {:>4} {:>15} {:>12} {:>12} {:>6} {:>12}",
                x.rule,
                x.rod_name,
                x.node,
                format!("{}-{}", x.step, x.last_step),
                g(x.t),
                g(x.last_t),
                x.count,
                value
            );
        }
        if rep.sticking.len() > MAX_ROWS {
            let _ = writeln!(
                s,
                "  … and {} more (all in --json)",
                rep.sticking.len() - MAX_ROWS
            );
        }
    }
    let _ = writeln!(
        s,
        "\n{}",
        if rep.flagged {
            "FLAGGED (exit 1)"
        } else {
            "clean (exit 0)"
        }
    );
    s
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), ReplayError> {
    let mut text = serde_json::to_string_pretty(value).expect("a report serialises");
    text.push('\n');
    crate::record::write_atomic(path, text.as_bytes())
        .map_err(|e| ReplayError::file(path, format!("cannot write the report: {e}")))
}

/// Run `gripsim replay`: print the human report on stdout, warnings and errors on stderr,
/// and return the exit status.
pub fn main(args: ReplayArgs) -> u8 {
    match run_command(args) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

/// Print on stdout; a closed stdout (`| head`) is not an error worth a panic.
fn say(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    let _ = out.write_all(text.as_bytes()).and_then(|_| out.flush());
}

fn run_command(args: ReplayArgs) -> Result<u8, ReplayError> {
    match args.command {
        ReplayCommand::Check {
            run,
            json,
            rrd,
            thresholds,
        } => {
            let (run, report) = check(&run, &thresholds)?;
            if let Some(w) = run.warning() {
                eprintln!("{w}");
            }
            say(&format_check(&report));
            if let Some(p) = &json {
                write_json(p, &report)?;
            }
            if let Some(p) = &rrd {
                overlay::write_check(p, &run, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            Ok(u8::from(report.flagged))
        }
        ReplayCommand::Diff {
            a,
            b,
            json,
            rrd,
            tolerances,
            thresholds,
        } => {
            thresholds.validate().map_err(ReplayError::new)?;
            tolerances.validate().map_err(ReplayError::new)?;
            let ra = Run::load(&a)?;
            let rb = Run::load(&b)?;
            for r in [&ra, &rb] {
                if let Some(w) = r.warning() {
                    eprintln!("{w}");
                }
            }
            let report = diff::diff(&ra, &rb, &tolerances, &thresholds)?;
            say(&diff::format_diff(&report));
            if let Some(p) = &json {
                write_json(p, &report)?;
            }
            if let Some(p) = &rrd {
                overlay::write_diff(p, &ra, &rb, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            Ok(u8::from(!report.within_tolerance))
        }
        ReplayCommand::Show { run, rrd } => {
            let shown = overlay::show(&run, &rrd)?;
            if let Some(w) = shown.warning {
                eprintln!("{w}");
            }
            say(&format!(
                "wrote {} ({} steps; open: rerun {})\n",
                rrd.display(),
                shown.steps,
                rrd.display()
            ));
            Ok(0)
        }
    }
}
