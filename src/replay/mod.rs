//! Replay: read recorded runs back (MCAP), check one for velocity spikes and sticking nodes,
//! diff two, and turn a recording into a Rerun `.rrd` (docs/replay.md).
//!
//! - [`read`]: the MCAP reader (also for files cut short by a kill).
//! - [`detect`]: the spike and sticking rules.
//! - [`diff`]: two runs aligned on simulated time.
//! - [`overlay`]: the Rerun views of `show`, `check --rrd` and `diff --rrd`.
//!
//! `gripsim replay` parses its arguments with [`ReplayArgs`] and calls [`main`]; the exit
//! status is 0 (clean / within tolerance), 1 (something flagged / out of tolerance), 2
//! (an error, reported on stderr with the file it concerns) or 3 ([`EXIT_INCOMPLETE`]: a
//! recording that stops before its run's end, unless `--allow-partial`).

pub mod bruise;
pub mod detect;
pub mod diff;
pub mod diff3;
pub mod grasp;
pub mod overlay;
pub mod overlay3;
pub mod read;
pub mod read3;
pub mod three;

pub use detect::{Detector, Effective, Findings, Scales, Thresholds};
pub use diff::{DiffReport, Tolerances};
pub use read::Run;

use serde::Serialize;
use std::path::{Path, PathBuf};

/// Version of the JSON reports (`--json`); bumped when a field changes meaning or is removed.
/// 2: thresholds follow the scene (`scales`), windows are in seconds, `incomplete` added.
pub const REPORT_VERSION: u32 = 2;

/// Exit status of `replay check` and `diff` (and `run --check` on an interrupted run) for a
/// recording that stops before its run's end (a killed run's `.partial.mcap`, a damaged chunk,
/// an interrupted run), unless `--allow-partial`.
pub const EXIT_INCOMPLETE: u8 = 3;

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
    /// Reports every spike (impact, unexplained) and every sticking episode (toggling) with
    /// rod, node, step, time and the values that
    /// triggered it. The rules and thresholds are explained in docs/replay.md.
    #[command(
        after_help = "Exit status: 0 clean, 1 something flagged, 2 error, 3 the recording stops before the run's end (killed, damaged, interrupted; --allow-partial: 0 or 1).\n\nExamples:\n  gripsim replay check recordings/point-mass-plane-dt1e-4.mcap\n  gripsim replay check run.mcap --json out/check.json --rrd out/check.rrd\n  gripsim replay check run.mcap --spike-displacement 1e-6"
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
        /// Treat a recording that stops before its run's end like a whole one (exit 0 or 1
        /// instead of 3).
        #[arg(long)]
        allow_partial: bool,
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
        after_help = "Exit status: 0 within tolerance, 1 not, 2 error (including runs that cannot be compared), 3 a recording stops before its run's end (--allow-partial: 0 or 1).\n\nExamples:\n  gripsim replay diff recordings/golden/point-mass-plane-dt1e-4.mcap out/now.mcap\n  gripsim replay diff a.mcap b.mcap --tol-position 1e-6 --json out/diff.json --rrd out/diff.rrd"
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
        /// Compare recordings that stop before their run's end (exit 0 or 1 instead of 3).
        #[arg(long)]
        allow_partial: bool,
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

/// The report of `replay check` (and of `run --check`).
#[derive(Debug, Clone, Serialize)]
pub struct CheckReport {
    pub report_version: u32,
    pub file: String,
    pub scenario: String,
    pub mode: String,
    pub steps: u64,
    pub t_end: f64,
    /// Why the file was read only in part (null when whole).
    pub truncated: Option<String>,
    /// The run's own end: true, false (stopped early), null (the file stops before it).
    pub completed: Option<bool>,
    /// The recording stops before its run's end (truncated, or the run did not complete).
    pub incomplete: bool,
    /// The scene's scales the default thresholds follow.
    pub scales: Scales,
    /// The thresholds in force (windows in seconds).
    pub thresholds: Effective,
    pub counts: detect::Counts,
    pub flagged: bool,
    pub spikes: Vec<detect::Spike>,
    pub sticking: Vec<detect::Sticking>,
    /// A fruit that slipped in the gripper during the lift or was dropped (runs with a free
    /// body only).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub grasp: Vec<grasp::GraspFlag>,
    /// The slips and drops the scenario expects (`[expect] grasp`): not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub grasp_expected: Vec<grasp::GraspFlag>,
    /// Contacts on a compliant fruit above its bruise threshold.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub bruise: Vec<bruise::BruiseFlag>,
    /// The bruises the scenario expects (`[expect] bruised = true`): not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub bruise_expected: Vec<bruise::BruiseFlag>,
    /// The scenario expects a bruise and the run made none (flagged).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub bruise_missing: bool,
    /// Stretches of a `--detail auto` recording that hold only some steps: no spike is judged
    /// across their gaps.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub decimated: Vec<detect::Decimated>,
}

impl CheckReport {
    /// The report of a finished detector.
    pub fn of(
        file: String,
        scenario: &str,
        mode: &str,
        detector: Detector,
        truncated: Option<String>,
        completed: Option<bool>,
    ) -> Self {
        let (steps, t_end, scales, thresholds) =
            (detector.steps, detector.t_end, detector.scales, detector.th);
        let decimated = detector.decimated.clone();
        let found = detector.finish();
        Self {
            report_version: REPORT_VERSION,
            file,
            scenario: scenario.to_string(),
            mode: mode.to_string(),
            steps,
            t_end,
            incomplete: truncated.is_some() || completed != Some(true),
            truncated,
            completed,
            scales,
            thresholds,
            counts: found.counts(),
            flagged: !found.is_empty(),
            spikes: found.spikes,
            sticking: found.sticking,
            grasp: found.grasp,
            grasp_expected: found.grasp_expected,
            bruise: found.bruise,
            bruise_expected: found.bruise_expected,
            bruise_missing: found.bruise_missing,
            decimated,
        }
    }

    /// The exit status: 0 clean, 1 flagged, [`EXIT_INCOMPLETE`] for an incomplete recording
    /// unless `allow_partial`.
    pub fn exit_code(&self, allow_partial: bool) -> u8 {
        if self.incomplete && !allow_partial {
            EXIT_INCOMPLETE
        } else {
            u8::from(self.flagged)
        }
    }
}

/// Check one run, streaming: the file is read chunk by chunk and fed to the detector, so
/// memory is bounded by the detection windows and one chunk, not by the run. Returns the
/// report and the warning for a recording read only in part.
pub fn check(path: &Path, th: &Thresholds) -> Result<(CheckReport, Option<String>), ReplayError> {
    th.validate().map_err(ReplayError::new)?;
    let mut det: Option<(Detector, read::Meta)> = None;
    let mut completed = None;
    let mut last: Option<(u64, f64)> = None;
    let mut steps = 0u64;
    let status = read::read_messages(path, false, |m| {
        match m {
            read::Message::Meta(meta) => {
                let sc = read::parse_scenario(path, &meta)?;
                det = Some((Detector::for_recording(&sc, th, meta.f32()), *meta));
            }
            read::Message::Contact(c) => {
                if let Some((d, _)) = det.as_mut() {
                    d.contact(c.sample());
                }
            }
            read::Message::Step(st) => {
                if let Some((d, _)) = det.as_mut() {
                    let samples: Vec<detect::RodSample<'_>> =
                        st.rods.iter().map(|r| r.sample()).collect();
                    d.step(st.step, st.t, st.dt, &samples);
                    st.grasp(d);
                    st.pressure(d);
                }
                last = Some((st.step, st.t));
                steps += 1;
            }
            read::Message::Event(e) if e.kind == "run_end" => completed = e.completed,
            _ => {}
        }
        Ok(())
    })?;
    let (d, meta) = det.expect("read_messages checks /sim/meta");
    if completed.is_none() {
        completed = status
            .run_end
            .as_ref()
            .and_then(|m| m.get("completed"))
            .map(|c| c == "true");
    }
    let warning = status.truncated.as_ref().map(|why| {
        let (k, t) = last.unwrap_or((0, 0.0));
        format!(
            "warning: {} is incomplete ({why}); read {steps} steps up to step {k} (t = {t} s), \
             the last complete chunk",
            path.display()
        )
    });
    let report = CheckReport::of(
        path.display().to_string(),
        &meta.scenario_name,
        &meta.mode,
        d,
        status.truncated.clone(),
        completed,
    );
    Ok((report, warning))
}

/// At most this many rows per table in the human output (the JSON has them all).
const MAX_ROWS: usize = 40;

pub(crate) fn g(x: f64) -> String {
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

/// "decimated: steps 0..5960 recorded at most every 100th step (61 gaps); no spike is judged
/// across a gap" (a few stretches named, the rest counted).
pub fn describe_decimated(d: &[detect::Decimated]) -> String {
    const SHOWN: usize = 6;
    let parts: Vec<String> = d
        .iter()
        .take(SHOWN)
        .map(|x| {
            format!(
                "steps {}..{} recorded at most every {}{} step ({} gap{})",
                x.from,
                x.to,
                x.every,
                crate::record::ordinal_suffix(x.every),
                x.gaps,
                if x.gaps == 1 { "" } else { "s" }
            )
        })
        .collect();
    let more = if d.len() > SHOWN {
        format!(" and {} more stretches", d.len() - SHOWN)
    } else {
        String::new()
    };
    format!(
        "decimated {:>5}  stretches: {}{more}; no spike is judged across a gap",
        d.len(),
        parts.join(", ")
    )
}

/// The bruise rule's lines of a check report (both dimensions): the stretches above the
/// bruise pressure, a bruise the scenario expects and did not get, the ones it expects.
pub(crate) fn bruise_lines(
    count: usize,
    bruise: &[bruise::BruiseFlag],
    expected: &[bruise::BruiseFlag],
    missing: bool,
) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    if !bruise.is_empty() {
        let _ = writeln!(
            s,
            "bruise    {count:>5}  (contacts above the fruit's bruise pressure)"
        );
        for f in bruise.iter().take(MAX_ROWS) {
            let _ = writeln!(
                s,
                "  {} steps {}-{} (t = {:.6}-{:.6} s): peak pressure {:.4e} Pa at t = {:.6} s, {:.2}x the threshold {:.4e} Pa, up to {:.3e} m wide above it",
                f.place(), f.step, f.last_step, f.t, f.last_t, f.max_pressure_pa,
                f.max_pressure_t, f.ratio, f.bruise_pressure_pa, f.max_bruise_width_m
            );
        }
    }
    if missing {
        let _ = writeln!(
            s,
            "bruise    missing: the scenario expects its fruit to bruise ([expect] bruised = true) and no contact went above its bruise pressure"
        );
    }
    if !expected.is_empty() {
        let f = expected
            .iter()
            .max_by(|a, b| a.ratio.total_cmp(&b.ratio))
            .expect("not empty");
        let _ = writeln!(
            s,
            "expected  bruised as the scenario expects ([expect] bruised = true): {} stretch(es) above the bruise pressure, the highest {:.2}x at {} (t = {:.6} s)",
            expected.len(),
            f.ratio,
            f.place(),
            f.max_pressure_t
        );
    }
    s
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
        "spikes    {:>5}  (impact {}, unexplained {})",
        c.spikes, c.impact, c.unexplained
    );
    let _ = writeln!(s, "sticking  {:>5}  (toggling {})", c.sticking, c.toggling);
    if !rep.decimated.is_empty() {
        let _ = writeln!(s, "{}", describe_decimated(&rep.decimated));
    }
    if c.slip + c.drop + c.held > 0 || !rep.grasp_expected.is_empty() {
        let _ = writeln!(
            s,
            "grasp     {:>5}  (slip {}, drop {}, held though the scenario expects otherwise {})",
            c.slip + c.drop + c.held,
            c.slip,
            c.drop,
            c.held
        );
        let lines = rep.grasp.iter().map(|f| (f, "")).chain(
            rep.grasp_expected
                .iter()
                .map(|f| (f, " (expected by the scenario: not flagged)")),
        );
        for (f, note) in lines {
            let _ = writeln!(
                s,
                "  {:<5} step {} t = {:.6} s: the fruit moved {:.3e} m in the gripper (tolerance {:.3e} m){note}",
                f.kind, f.step, f.t, f.slip_m, f.hold_tolerance_m
            );
        }
    }
    s += &bruise_lines(
        c.bruise,
        &rep.bruise,
        &rep.bruise_expected,
        rep.bruise_missing,
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
            "  {:<14} {:<10} {:>4} {:>15} {:>12} {:>12} {:>6}",
            "rule", "rod", "node", "steps", "t (s)", "to t (s)", "count"
        );
        for x in rep.sticking.iter().take(MAX_ROWS) {
            let _ = writeln!(
                s,
                "  {:<14} {:<10} {:>4} {:>15} {:>12} {:>12} {:>6}",
                x.rule,
                x.rod_name,
                x.node,
                format!("{}-{}", x.step, x.last_step),
                g(x.t),
                g(x.last_t),
                x.count
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
    let _ = writeln!(s, "\n{}", if rep.flagged { "FLAGGED" } else { "clean" });
    if rep.incomplete {
        let _ = writeln!(
            s,
            "INCOMPLETE: the recording stops before the run's end{} (exit {EXIT_INCOMPLETE} \
             unless --allow-partial)",
            match (&rep.truncated, rep.completed) {
                (Some(why), _) => format!(" ({why})"),
                (None, Some(false)) => " (the run stopped early)".to_string(),
                _ => String::new(),
            }
        );
    }
    s
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), ReplayError> {
    let mut text = serde_json::to_string_pretty(value).expect("a report serialises");
    text.push('\n');
    crate::record::write_atomic(path, text.as_bytes())
        .map_err(|e| ReplayError::file(path, format!("cannot write the report: {e}")))
}

/// The files of a replay command: the runs it reads (and the files their recorded scenarios
/// name) and the reports it writes.
fn plan(cmd: &ReplayCommand) -> crate::record::OutputPlan {
    let mut plan = crate::record::OutputPlan::new();
    let run = |plan: &mut crate::record::OutputPlan, what: &str, path: &Path| {
        plan.input(what, path);
        for f in read::recorded_files(path) {
            plan.input("a file its recorded scenario names", &f);
        }
    };
    let (json, rrd) = match cmd {
        ReplayCommand::Check {
            run: r, json, rrd, ..
        } => {
            run(&mut plan, "the run", r);
            (json.as_deref(), rrd.as_deref())
        }
        ReplayCommand::Diff {
            a, b, json, rrd, ..
        } => {
            run(&mut plan, "run A", a);
            run(&mut plan, "run B", b);
            (json.as_deref(), rrd.as_deref())
        }
        ReplayCommand::Show { run: r, rrd } => {
            run(&mut plan, "the run", r);
            (None, Some(rrd.as_path()))
        }
    };
    if let Some(p) = json {
        plan.output("--json", p);
    }
    if let Some(p) = rrd {
        plan.output("--rrd", p);
    }
    plan
}

/// Run `gripsim replay`: print the human report on stdout, warnings and errors on stderr,
/// and return the exit status.
///
/// Its outputs are checked against its inputs and each other before anything is read or
/// written, and given their final names together once all were written; a replay that fails
/// leaves no output of its own (the files that were there before stay as they were).
pub fn main(args: ReplayArgs) -> u8 {
    let plan = plan(&args.command);
    if let Err(e) = plan.check() {
        eprintln!("error: {e}");
        return 2;
    }
    let held = plan.hold();
    match run_command(args) {
        Ok(code) => match held.commit() {
            Ok(()) => code,
            Err(e) => {
                eprintln!("error: {e}");
                2
            }
        },
        Err(e) => {
            held.discard();
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
    // Recordings of 3D runs (dimension = 3) have their own reader and rules.
    if let Some(code) = run_3d(&args.command)? {
        return Ok(code);
    }
    match args.command {
        ReplayCommand::Check {
            run,
            json,
            rrd,
            allow_partial,
            thresholds,
        } => {
            let (report, warning) = check(&run, &thresholds)?;
            if let Some(w) = warning {
                eprintln!("{w}");
            }
            say(&format_check(&report));
            if let Some(p) = &json {
                write_json(p, &report)?;
            }
            if let Some(p) = &rrd {
                // The Rerun view needs the whole run in memory.
                let run = Run::load(&run)?;
                overlay::write_check(p, &run, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            Ok(report.exit_code(allow_partial))
        }
        ReplayCommand::Diff {
            a,
            b,
            json,
            rrd,
            allow_partial,
            tolerances,
            thresholds,
        } => {
            thresholds.validate().map_err(ReplayError::new)?;
            tolerances.validate().map_err(ReplayError::new)?;
            let report = diff::diff_files(&a, &b, &tolerances, &thresholds)?;
            for r in [&report.a, &report.b] {
                if let Some(why) = &r.truncated {
                    eprintln!(
                        "warning: {} is incomplete ({why}); read {} steps up to t = {} s, the \
                         last complete chunk",
                        r.file, r.steps, r.t_end
                    );
                }
            }
            say(&diff::format_diff(&report));
            if let Some(p) = &json {
                write_json(p, &report)?;
            }
            if let Some(p) = &rrd {
                // The Rerun view needs both runs in memory.
                let (ra, rb) = (Run::load(&a)?, Run::load(&b)?);
                overlay::write_diff(p, &ra, &rb, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            let incomplete = report.a.incomplete || report.b.incomplete;
            if incomplete && !allow_partial {
                say(&format!(
                    "INCOMPLETE: a recording stops before its run's end (exit {EXIT_INCOMPLETE} \
                     unless --allow-partial)\n"
                ));
                return Ok(EXIT_INCOMPLETE);
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

/// `replay check|diff|show` on the MCAP of a 3D run ([`three`]); `None` for planar recordings.
fn run_3d(cmd: &ReplayCommand) -> Result<Option<u8>, ReplayError> {
    match cmd {
        ReplayCommand::Check {
            run,
            json,
            rrd,
            thresholds,
            allow_partial,
        } if three::is_3d_mcap(run) => {
            let report = three::check(run, thresholds)?;
            say(&three::format_check(&report));
            if let Some(p) = json {
                write_json(p, &report)?;
            }
            if let Some(p) = rrd {
                overlay3::write_check(run, p, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            if report.incomplete && !allow_partial {
                return Ok(Some(EXIT_INCOMPLETE));
            }
            Ok(Some(u8::from(report.flagged)))
        }
        ReplayCommand::Diff {
            a,
            b,
            json,
            rrd,
            tolerances,
            allow_partial,
            thresholds,
        } if three::is_3d_mcap(a) || three::is_3d_mcap(b) => {
            if !(three::is_3d_mcap(a) && three::is_3d_mcap(b)) {
                return Err(ReplayError::new(format!(
                    "{} and {}: one is a 3D run, the other is not: not comparable",
                    a.display(),
                    b.display()
                )));
            }
            tolerances.validate().map_err(ReplayError::new)?;
            thresholds.validate().map_err(ReplayError::new)?;
            let report = diff3::diff(a, b, tolerances, thresholds)?;
            say(&diff3::format_diff(&report));
            if let Some(p) = json {
                write_json(p, &report)?;
            }
            if let Some(p) = rrd {
                overlay3::write_diff(a, b, p, &report)?;
                say(&format!(
                    "wrote {} (open: rerun {})\n",
                    p.display(),
                    p.display()
                ));
            }
            if report.incomplete && !allow_partial {
                say(&format!(
                    "INCOMPLETE: a recording stops before its run's end (exit {EXIT_INCOMPLETE} \
                     unless --allow-partial)\n"
                ));
                return Ok(Some(EXIT_INCOMPLETE));
            }
            Ok(Some(u8::from(!report.within_tolerance)))
        }
        ReplayCommand::Show { run, rrd } if three::is_3d_mcap(run) => {
            let steps = three::show(run, rrd)?;
            say(&format!(
                "wrote {} ({steps} steps; open: rerun {})\n",
                rrd.display(),
                rrd.display()
            ));
            Ok(Some(0))
        }
        _ => Ok(None),
    }
}
