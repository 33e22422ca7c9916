//! The `gripsim` command line: thin commands over the library.

use clap::{Parser, Subcommand, ValueEnum};
use gripsim::events::{Fanout, Observer};
use gripsim::record::auto::AutoStats;
use gripsim::record::files::PlanarFiles;
use gripsim::record::summary::SummaryCollector;
use gripsim::record::{Detail, Finished, RecordOptions};
use gripsim::run::AnyScenario;
use gripsim::{Scenario, Simulation};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// `println!` that ignores a closed stdout (`gripsim run ... | head`): by then the run is over
/// and its files are closed, and a "failed printing to stdout" panic would only hide that.
macro_rules! say {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// `print!` likewise.
macro_rules! say_part {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stdout(), $($t)*);
    }};
}

#[derive(Parser)]
#[command(
    name = "gripsim",
    version,
    about = "Simulate soft gripper prongs grasping fruit (discrete elastic rods, modified mass contact)",
    after_help = "Examples:\n  gripsim run scenarios/seed-grasp-r5.toml\n  gripsim run scenarios/seed-grasp-r5.toml --set obstacle.0.radius=0.04 --summary out/r4.json\n  gripsim validate scenarios/two-prong-grasp.toml\n  gripsim scenarios"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scenario, record it and print a short summary.
    ///
    /// With no --rrd/--mcap/--csv the run is recorded to recordings/<scenario-name>.rrd and
    /// .mcap (--no-record skips that). Files are written as NAME.partial.EXT and renamed when
    /// the run completes; Ctrl-C (SIGINT) or SIGTERM stops the run after the current step and
    /// closes the files properly (exit status 130 or 143).
    #[command(
        after_help = "Examples:\n  gripsim run scenarios/seed-grasp-r5.toml\n  gripsim run scenarios/seed-grasp-r5.toml --detail iteration --rrd out/r5.rrd --mcap out/r5.mcap\n  gripsim run scenarios/seed-grasp-r5.toml --csv out/r5.csv\n  gripsim run scenarios/seed-grasp-r5.toml --set rod.0.E=1e9 --summary out/e1gpa.json --no-record\n\nOpen a .rrd with `rerun FILE.rrd`; open a .mcap in Foxglove (see recordings/README.md)."
    )]
    Run {
        /// Scenario file (TOML).
        scenario: PathBuf,
        /// Write a Rerun recording to this file.
        #[arg(long, value_name = "FILE.rrd")]
        rrd: Option<PathBuf>,
        /// Write an MCAP recording (protobuf steps and Foxglove scene, JSON events) to this file.
        #[arg(long, value_name = "FILE.mcap")]
        mcap: Option<PathBuf>,
        /// Write one CSV row per step, rod and node to this file.
        #[arg(long, value_name = "FILE.csv")]
        csv: Option<PathBuf>,
        /// What the recordings hold: auto = every step with its Newton iterations in windows
        /// around each event (contact change, stick/slip, dt change, Newton trouble, spike),
        /// every k-th step elsewhere (k from the run's length, docs/recording-format.md);
        /// step = every step; iteration = every step and every Newton iteration [default:
        /// auto; a 3D scenario records every step and takes step only].
        #[arg(long, value_enum)]
        detail: Option<DetailArg>,
        /// With --detail auto: record every N-th step outside the windows [default: from the
        /// run's length and node count].
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        auto_every: Option<u64>,
        /// Make the recordings readable up to here every N steps [default: the scenario's
        /// [output] flush_every, else 100].
        #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
        flush_every: Option<u64>,
        /// How the .rrd and the MCAP scene scale force arrows: linear (one scale per recording,
        /// from the run's largest force, printed in the scene) or log [default: linear].
        #[arg(long, value_enum)]
        arrows: Option<ArrowsArg>,
        /// How the MCAP stores the per-node numbers of /sim/step and /sim/iteration: f32
        /// (with an exact fingerprint of each step) or f64 (exact) [default: the scenario's
        /// [output] precision, else f32].
        #[arg(long, value_enum)]
        precision: Option<PrecisionArg>,
        /// Do not write the default recordings (recordings/<name>.rrd and .mcap).
        #[arg(long, conflicts_with_all = ["rrd", "mcap", "csv"])]
        no_record: bool,
        /// Write the run summary as JSON to this file.
        #[arg(long, value_name = "FILE.json")]
        summary: Option<PathBuf>,
        /// Override a scenario value by dotted path, e.g. obstacle.0.radius=0.04 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
        /// Print nothing but errors.
        #[arg(long, short)]
        quiet: bool,
        /// Static mode: start from a small imperfection (solve.imperfection = 1e-3 of the rod
        /// length) so the load ramp follows the stable branch past a bifurcation.
        #[arg(long)]
        perturb: bool,
        /// Check the run for velocity spikes and sticking nodes while it runs (the detector of
        /// `gripsim replay check`, no recording needed); exit 1 if anything is flagged.
        #[arg(long)]
        check: bool,
        /// With --check: write the check report as JSON to this file.
        #[arg(long, value_name = "FILE.json", requires = "check")]
        check_json: Option<PathBuf>,
        #[command(flatten)]
        thresholds: gripsim::replay::Thresholds,
    },
    /// Check a scenario file without running it.
    #[command(
        after_help = "Example:\n  gripsim validate scenarios/seed-grasp-r5.toml --set solve.dt=1e-4"
    )]
    Validate {
        scenario: PathBuf,
        #[arg(long = "set", value_name = "KEY=VALUE")]
        sets: Vec<String>,
    },
    /// List the shipped scenarios with their descriptions.
    #[command(after_help = "Example:\n  gripsim scenarios --dir scenarios")]
    Scenarios {
        #[arg(long, default_value = "scenarios")]
        dir: PathBuf,
    },
    /// Benchmark run time against error (work-precision), cost per step against nodes, and
    /// numerical stability (--stress).
    #[command(
        after_help = "Examples:\n  gripsim bench --quick                 # a reduced ladder in seconds\n  gripsim bench --out out/bench         # the full work-precision and scaling bench\n  gripsim bench --stress --out out/bench  # the stability stress map"
    )]
    Bench {
        /// A reduced ladder (seconds); used in CI as a smoke test.
        #[arg(long)]
        quick: bool,
        /// Run the stability stress map instead of work-precision and scaling.
        #[arg(long)]
        stress: bool,
        /// Output folder for CSV tables and PNG/SVG figures.
        #[arg(long, default_value = "out/bench")]
        out: PathBuf,
        /// Timed runs per rung; the median is reported (default 5, 1 with --quick).
        #[arg(long)]
        repeats: Option<usize>,
    },
    /// Run a grid of scenario variants in parallel on all cores, resumable and shardable, with
    /// a summary table and plots (docs/studies.md).
    ///
    /// Each case is the scenario with the --set values and one value of every --vary key
    /// applied (as `gripsim run --set`); its result goes atomically into DIR/cases/<id>/, so a
    /// re-run skips finished cases and Ctrl-C (SIGINT) or SIGTERM leaves no half result.
    #[command(
        after_help = "Examples:\n  gripsim sweep scenarios/seed-grasp-r5.toml --vary obstacle.0.radius=0.05,0.04 --vary rod.0.E=1e6,1e9 --out out/study\n  gripsim sweep scenarios/seed-grasp-r5.toml --vary rod.0.E=1e6:1e9:7:log --set solve.t_end=0.08 --out out/e\n  gripsim sweep scenarios/seed-grasp-r5.toml --vary obstacle.0.radius=0.03:0.05:9 --shard $SLURM_ARRAY_TASK_ID/8 --out out/r\n  gripsim sweep merge out/r"
    )]
    Sweep(SweepCli),
    /// The grasp window: the smallest knob value (by default the grip target of the squeeze) at
    /// which the fruit is held through the lift, and the smallest at which it bruises, each
    /// to --rtol; with --vary, a map of the window over design parameters (docs/studies.md).
    ///
    /// Each evaluation is a normal run (no recordings) with the knob set; independent runs go
    /// in parallel. Exit 0 when it ran (whatever the window), 2 on bad input, 130/143 when a
    /// signal stopped it.
    #[command(
        after_help = "Examples:\n  gripsim window scenarios/jaw-grasp-hold.toml\n  gripsim window scenarios/jaw-grasp-hold.toml --range 0.5:4 --rtol 0.005 --json out/window.json\n  gripsim window scenarios/jaw-grasp-hold.toml --knob friction.pair.0.mu_s --range 0.2:1.2\n  gripsim window scenarios/jaw-grasp-hold.toml --vary obstacle.2.mass=0.05:0.2:7 --out out/window-mass\n  gripsim sweep merge out/window-mass   # after sharded runs (--shard I/N)"
    )]
    Window(WindowCli),
    /// Read recorded runs back: check one for velocity spikes and sticking nodes, diff two,
    /// or turn one into a Rerun .rrd (docs/replay.md).
    #[command(
        after_help = "Examples:\n  gripsim replay check recordings/point-mass-plane-dt1e-4.mcap\n  gripsim replay diff recordings/golden/point-mass-plane-dt1e-4.mcap out/now.mcap\n  gripsim replay show recordings/seed-grasp-r5.mcap --rrd out/r5.rrd"
    )]
    Replay(gripsim::replay::ReplayArgs),
}

/// `--precision`: the MCAP's per-node numbers.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum PrecisionArg {
    /// protobuf float, with an exact 64-bit fingerprint of every step's state.
    F32,
    /// protobuf double: the exact values.
    F64,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ArrowsArg {
    /// Length proportional to the force.
    Linear,
    /// Length proportional to log10(1 + f/f0), f0 = the run's largest force / 1000.
    Log,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum DetailArg {
    /// Full detail around events, every k-th step elsewhere, the first and last step.
    Auto,
    /// Every step's state, contact changes and solver events.
    Step,
    /// Also every Newton iteration of every predictor and corrector pass.
    Iteration,
}

/// `gripsim sweep` arguments (or `gripsim sweep merge DIR...`).
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
struct SweepCli {
    #[command(subcommand)]
    merge: Option<SweepMerge>,
    /// Scenario file (TOML).
    #[arg(required = true)]
    scenario: Option<PathBuf>,
    /// A varied key: KEY=V1,V2,... or KEY=START:STOP:COUNT[:log] (repeatable; the grid is every
    /// combination, the first --vary varying slowest).
    #[arg(long = "vary", value_name = "KEY=VALUES", required = true)]
    vary: Vec<gripsim::study::Vary>,
    /// Override a scenario value in every case, e.g. solve.t_end=0.08 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Cases run at once [default: one per core].
    #[arg(long, short, value_name = "N")]
    jobs: Option<usize>,
    /// Output folder; a re-run with the same folder resumes.
    #[arg(long, value_name = "DIR", required = true)]
    out: Option<PathBuf>,
    /// Run only the cases k with k mod N = I (I is 0-based), for batch arrays; join the shards
    /// with `gripsim sweep merge`.
    #[arg(long, value_name = "I/N")]
    shard: Option<gripsim::study::Shard>,
    /// No figures (per case and per sweep).
    #[arg(long)]
    no_plots: bool,
    /// Which cases get their own figures (forces, shapes): all, flagged (a case that stopped
    /// with an error, warned, or has a spike, sticking episode or bruise the replay check
    /// flags) or none. The sweep's figures are drawn in any case (unless --no-plots).
    #[arg(
        long,
        value_name = "WHICH",
        default_value = "flagged",
        conflicts_with = "no_plots"
    )]
    case_plots: gripsim::study::CasePlots,
    /// No progress bar or per-case lines.
    #[arg(long, short)]
    quiet: bool,
}

/// `gripsim window` arguments.
#[derive(clap::Args)]
struct WindowCli {
    /// Scenario file (TOML).
    scenario: PathBuf,
    /// The knob: a numeric scenario key in the --set grammar, e.g. friction.pair.0.mu_s
    /// [default: the grip target of the squeeze, the grip_force (or grip_torque) end of the
    /// first phase of an [[actuator]] that has one].
    #[arg(long, value_name = "KEY")]
    knob: Option<String>,
    /// The range searched, LO:HI with 0 < LO < HI (the search is in log knob) [default: the
    /// scenario's value / 8 to × 8].
    #[arg(long, value_name = "LO:HI", value_parser = gripsim::study::window::parse_range)]
    range: Option<(f64, f64)>,
    /// Relative width of each boundary's final bracket.
    #[arg(long, value_name = "R", default_value = "0.01", value_parser = gripsim::study::window::parse_rtol)]
    rtol: f64,
    /// Override a scenario value, e.g. solve.dt=1e-5 (repeatable; before the knob's value).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    sets: Vec<String>,
    /// Write the result (boundaries, ratio, every run) as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// Runs at once [default: one per core].
    #[arg(long, short, value_name = "N")]
    jobs: Option<usize>,
    /// A design parameter: KEY=V1,V2,... or KEY=START:STOP:COUNT[:log] (repeatable: a grid);
    /// one window search per design, into --out DIR.
    #[arg(long = "vary", value_name = "KEY=VALUES")]
    vary: Vec<gripsim::study::Vary>,
    /// With --vary: the output folder (window.csv, window.json, window.png|svg, a folder per
    /// design); a re-run resumes.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// With --vary: only the designs k with k mod N = I; join with `gripsim sweep merge`.
    #[arg(long, value_name = "I/N")]
    shard: Option<gripsim::study::Shard>,
    /// With --vary: no picture.
    #[arg(long)]
    no_plots: bool,
    /// No progress lines.
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Subcommand)]
enum SweepMerge {
    /// Join the case folders of a sweep's shards into one folder and write its summary.csv and
    /// plots.
    #[command(
        after_help = "Examples:\n  gripsim sweep merge out/study                     # shards that shared one folder\n  gripsim sweep merge out/s0 out/s1 --out out/study  # one folder per shard"
    )]
    Merge {
        /// Sweep folders of the same sweep.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// The merged sweep folder [default: the first folder].
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
        /// No sweep figures.
        #[arg(long)]
        no_plots: bool,
    },
}

/// What `run` writes.
struct Outputs {
    rrd: Option<PathBuf>,
    mcap: Option<PathBuf>,
    csv: Option<PathBuf>,
    summary: Option<PathBuf>,
    detail: Detail,
    /// `--auto-every`.
    auto_every: Option<u64>,
    flush_every: Option<u64>,
    /// `--precision`.
    precision: Option<gripsim::scenario::Precision>,
    /// `--check`: the thresholds and where to write the report.
    check: Option<(gripsim::replay::Thresholds, Option<PathBuf>)>,
    arrows: gripsim::record::ArrowScale,
    /// The recording options given that only a planar run honours (option, value): a 3D
    /// run records every step in f64, with fixed arrow scales, in its writers' own chunks.
    planar_only: Vec<(&'static str, String)>,
    /// `--perturb` (its imperfection is among the `--set`s): refused in 3D.
    perturb: bool,
}

/// The recording options of `run` given on the command line that a 3D run cannot honour
/// ([`Outputs::planar_only`]); those that say what a 3D run does anyway (`--detail step`,
/// `--precision f64`, `--arrows linear`) are not among them.
fn planar_only(
    detail: Option<DetailArg>,
    auto_every: Option<u64>,
    flush_every: Option<u64>,
    precision: Option<PrecisionArg>,
    arrows: Option<ArrowsArg>,
) -> Vec<(&'static str, String)> {
    fn name<T: ValueEnum>(v: &T) -> String {
        v.to_possible_value()
            .map_or_else(String::new, |p| p.get_name().to_string())
    }
    let mut given = Vec::new();
    if let Some(d) = detail.filter(|d| !matches!(d, DetailArg::Step)) {
        given.push(("--detail", name(&d)));
    }
    if let Some(n) = auto_every {
        given.push(("--auto-every", n.to_string()));
    }
    if let Some(n) = flush_every {
        given.push(("--flush-every", n.to_string()));
    }
    if let Some(p) = precision.filter(|p| matches!(p, PrecisionArg::F32)) {
        given.push(("--precision", name(&p)));
    }
    if let Some(a) = arrows.filter(|a| matches!(a, ArrowsArg::Log)) {
        given.push(("--arrows", name(&a)));
    }
    given
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Run {
            scenario,
            rrd,
            mcap,
            csv,
            detail,
            auto_every,
            flush_every,
            arrows,
            precision,
            no_record,
            summary,
            mut sets,
            quiet,
            perturb,
            check,
            check_json,
            thresholds,
        } => {
            if perturb {
                sets.push("solve.imperfection=1e-3".into());
            }
            let planar_only = planar_only(detail, auto_every, flush_every, precision, arrows);
            let out = Outputs {
                rrd,
                mcap,
                csv,
                summary,
                detail: match detail.unwrap_or(DetailArg::Auto) {
                    DetailArg::Auto => Detail::Auto(Default::default()),
                    DetailArg::Step => Detail::Step,
                    DetailArg::Iteration => Detail::Iteration,
                },
                auto_every,
                flush_every,
                precision: precision.map(|p| match p {
                    PrecisionArg::F32 => gripsim::scenario::Precision::F32,
                    PrecisionArg::F64 => gripsim::scenario::Precision::F64,
                }),
                check: check.then_some((thresholds, check_json)),
                arrows: match arrows.unwrap_or(ArrowsArg::Linear) {
                    ArrowsArg::Linear => gripsim::record::ArrowScale::Linear,
                    ArrowsArg::Log => gripsim::record::ArrowScale::Log,
                },
                planar_only,
                perturb,
            };
            run(&scenario, out, no_record, &sets, quiet)
        }
        Command::Validate { scenario, sets } => validate(&scenario, &sets),
        Command::Scenarios { dir } => list_scenarios(&dir),
        Command::Bench {
            quick,
            stress,
            out,
            repeats,
        } => bench(quick, stress, out, repeats),
        Command::Sweep(args) => sweep(args),
        Command::Window(args) => window(args),
        Command::Replay(args) => replay(args),
    }
}

/// Exit status asked for by a signal (128 + signal number), 0 while none arrived.
static STOP: AtomicUsize = AtomicUsize::new(0);
/// Set by the first signal; a second one then ends the process at once.
static STOPPING: AtomicBool = AtomicBool::new(false);

/// SIGINT, SIGTERM and SIGHUP (a closed terminal or dropped ssh session) stop the run after
/// the current step (the recordings are then closed properly); a second signal exits at once.
fn install_signal_handlers() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    use signal_hook::flag;
    for sig in [SIGINT, SIGTERM, SIGHUP] {
        let code = 128 + sig;
        let ok = flag::register_conditional_shutdown(sig, code, &STOPPING).is_ok()
            && flag::register_usize(sig, &STOP, code as usize).is_ok()
            && flag::register(sig, &STOPPING).is_ok();
        if !ok {
            eprintln!("warning: cannot handle signal {sig}; stopping the run may leave partial recordings");
        }
    }
}

/// The name of the signal behind exit status `stop` (128 + number).
fn signal_name(stop: usize) -> &'static str {
    match stop {
        129 => "SIGHUP",
        143 => "SIGTERM",
        _ => "SIGINT",
    }
}

fn file_name(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Read the scenario at `path` once (a pipe or FIFO too: process substitution) and parse it
/// as what its text says it is, with the `--set` overrides; also returns its text (the
/// recordings store it, and the plan of the outputs reads the files it names).
/// `perturb`: `run --perturb` (its `solve.imperfection` is in `sets`), planar only.
fn load(
    path: &Path,
    sets: &[String],
    perturb: bool,
) -> Result<(String, AnyScenario), gripsim::scenario::ScenarioError> {
    let text = gripsim::scenario::input::read_text(path)?;
    let file = path.display().to_string();
    if perturb && gripsim::scenario::three::is_3d(&text) {
        return Err(gripsim::scenario::ScenarioError {
            file,
            key: String::new(),
            value: String::new(),
            message: "--perturb (a static solve's imperfection) is not yet available in 3D \
                      (dimension = 3): drop the option"
                .into(),
            hint: None,
        });
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let sc = AnyScenario::parse(&text, &file, dir, sets)?;
    Ok((text, sc))
}

fn validate(path: &Path, sets: &[String]) -> ExitCode {
    match load(path, sets, false) {
        Ok((_, AnyScenario::Spatial(sc))) => {
            for w in sc.warnings() {
                eprintln!("warning: {}: {w}", path.display());
            }
            say!(
                "{}: ok ({:?}, 3D, {} finger(s) of {} node(s), {} obstacle(s), fruit: {})",
                path.display(),
                sc.name,
                sc.fingers,
                sc.prong.points.len(),
                sc.obstacles.len(),
                if sc.fruit.is_some() { "yes" } else { "no" }
            );
            ExitCode::SUCCESS
        }
        Ok((_, AnyScenario::Planar(sc))) => {
            for w in sc.warnings() {
                eprintln!("warning: {}: {w}", path.display());
            }
            let nodes: usize = sc.rods.iter().map(|r| r.nodes).sum();
            say!(
                "{}: ok ({:?}, {} rod(s), {} node(s), {} obstacle(s))",
                path.display(),
                sc.name,
                sc.rods.len(),
                nodes,
                sc.obstacles.len()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// The plan of a run's files: the scenario and the files it names as inputs, every output
/// named ([`gripsim::record::OutputPlan`]); checked before anything is written.
fn plan_outputs(
    path: &Path,
    text: &str,
    sets: &[String],
    out: &Outputs,
) -> Result<gripsim::record::OutputPlan, String> {
    let mut plan = gripsim::record::OutputPlan::new();
    plan.scenario(path, text, sets);
    let check_json = out.check.as_ref().and_then(|(_, j)| j.as_deref());
    for (what, p) in [
        ("--rrd", out.rrd.as_deref()),
        ("--mcap", out.mcap.as_deref()),
        ("--csv", out.csv.as_deref()),
        ("--summary", out.summary.as_deref()),
        ("--check-json", check_json),
    ] {
        if let Some(p) = p {
            plan.output(what, p);
        }
    }
    plan.check().map(|_| plan)
}

/// After a run whose outputs were not given their final names: the files as they are, under
/// their `.partial` names.
fn uncommitted(files: &mut [(&str, Finished)]) {
    for (_, f) in files.iter_mut().filter(|(_, f)| f.complete) {
        let o = gripsim::record::OutputFile::new(&f.path);
        if !o.is_through() {
            f.path = o.partial.clone();
            f.complete = false;
        }
    }
}

fn run(path: &Path, mut out: Outputs, no_record: bool, sets: &[String], quiet: bool) -> ExitCode {
    let (text, sc) = match load(path, sets, out.perturb) {
        Ok((text, AnyScenario::Planar(sc))) => (text, *sc),
        Ok((text, AnyScenario::Spatial(sc))) => {
            return run3(path, &text, *sc, out, no_record, sets, quiet)
        }
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    for w in sc.warnings() {
        eprintln!("warning: {}: {w}", path.display());
    }
    if !no_record && out.rrd.is_none() && out.mcap.is_none() && out.csv.is_none() {
        let base = Path::new("recordings").join(file_name(&sc.name));
        out.rrd = Some(base.with_extension("rrd"));
        out.mcap = Some(base.with_extension("mcap"));
    }
    let opts = match gripsim::record::files::record_options(
        &sc,
        out.detail,
        out.auto_every,
        out.flush_every,
    ) {
        Ok(opts) => opts,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    // Every output its own file, none of them an input, each one a path that can take a file:
    // checked before anything is created. The outputs are renamed into place together, when
    // the run completed and every one was written.
    if let Some((th, _)) = &out.check {
        if let Err(e) = th.validate() {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    }
    let held = match plan_outputs(path, &text, sets, &out) {
        Ok(plan) => plan.hold(),
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    // From here a signal stops the run and the files are closed properly.
    install_signal_handlers();
    // Wall time from here: the survey and the recording are part of what the command costs.
    let start = std::time::Instant::now();
    let files = gripsim::record::files::FileOptions {
        rrd: out.rrd.as_deref(),
        mcap: out.mcap.as_deref(),
        csv: out.csv.as_deref(),
        opts,
        precision: out.precision.unwrap_or(sc.precision),
        arrows: out.arrows,
    };
    let stopped = Box::new(|| STOP.load(Ordering::Relaxed) != 0);
    let mut recording = match PlanarFiles::create(&sc, &files, Some(stopped)) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot create a recording: {e}");
            // Nothing half made: the partial files created so far go.
            held.discard();
            return ExitCode::from(2);
        }
    };

    let mut sim = Simulation::new(&sc);
    // A recording that cannot be written (disk full) stops the run too: the other files are
    // then closed properly and the error is reported.
    let failures = recording.failures();
    let sink_failed = {
        let failures = failures.clone();
        move || failures.iter().any(|f| f.load(Ordering::Relaxed))
    };
    sim.interrupt = Some(Box::new(move || {
        STOP.load(Ordering::Relaxed) != 0 || sink_failed()
    }));
    let mut collector = SummaryCollector::new();
    let mut detector = out
        .check
        .as_ref()
        .map(|(th, _)| gripsim::replay::detect::DetectObserver::new(&sc, th));
    let th = out
        .check
        .as_ref()
        .map_or(gripsim::replay::Thresholds::DEFAULT, |(th, _)| *th);
    let (result, auto_stats) = recording.feed(&sc, &th, |files| {
        let mut fan = Fanout::new();
        fan.push(&mut collector as &mut dyn Observer);
        if let Some(d) = detector.as_mut() {
            fan.push(d as &mut dyn Observer);
        }
        fan.push(files);
        // Only accepted steps' contact changes reach the sinks.
        sim.run(&mut gripsim::record::accepted::AcceptedContacts::new(fan))
    });
    let mut failed = false;
    let (mut files, errors) = recording.finish();
    for e in errors {
        eprintln!("error: {e}");
        failed = true;
    }
    let wall = start.elapsed().as_secs_f64();
    let summary = collector.finish(&sim.stats, wall);
    if let Some(p) = &out.summary {
        let mut text = serde_json::to_string_pretty(&summary).expect("summary serialises");
        text.push('\n');
        if let Err(e) = gripsim::record::write_atomic(p, text.as_bytes()) {
            eprintln!("error: cannot write the summary to {}: {e}", p.display());
            failed = true;
        }
    }
    let report = match (detector, &out.check) {
        (Some(d), Some((_, json))) => {
            let report = gripsim::replay::CheckReport::of(
                format!("(run of {})", path.display()),
                &sc.name,
                if sc.solve.mode == gripsim::scenario::Mode::Dynamic {
                    "dynamic"
                } else {
                    "static"
                },
                d.detector,
                None,
                Some(result.is_ok()),
            );
            if let Some(p) = json {
                let mut text = serde_json::to_string_pretty(&report).expect("a report serialises");
                text.push('\n');
                if let Err(e) = gripsim::record::write_atomic(p, text.as_bytes()) {
                    eprintln!(
                        "error: cannot write the check report to {}: {e}",
                        p.display()
                    );
                    failed = true;
                }
            }
            Some(report)
        }
        _ => None,
    };
    // A completed run whose every output was written: all of them get their final names now;
    // else every one keeps its .partial name and the files of earlier runs stay.
    let committed = result.is_ok() && !failed && {
        let done = held.commit();
        if let Err(e) = &done {
            eprintln!("error: {e}");
            failed = true;
        }
        done.is_ok()
    };
    if !committed {
        uncommitted(&mut files);
    }
    if !quiet {
        say_part!("{}", summary.to_text());
        print_recordings(&files, opts, auto_stats);
    }
    let mut check_code = 0u8;
    if let Some(report) = report {
        if !quiet || report.flagged {
            say!(
                "\ncheck\n{}",
                gripsim::replay::format_check(&report).trim_end()
            );
        }
        check_code = u8::from(report.flagged);
    }
    let stop = STOP.load(Ordering::Relaxed);
    let sink_failed = failures.iter().any(|f| f.load(Ordering::Relaxed));
    match result {
        Err(gripsim::solver::SimError::Interrupted { .. }) if sink_failed && stop == 0 => {
            // The recording's error was printed above.
            ExitCode::from(2)
        }
        Err(e @ gripsim::solver::SimError::Interrupted { .. }) if stop != 0 => {
            let signal = signal_name(stop);
            eprintln!("{e} by {signal}; the recordings are closed and keep their .partial names");
            ExitCode::from(stop as u8)
        }
        Err(e) => {
            let hint = match e {
                gripsim::solver::SimError::Diverged { .. }
                    if sim.scenario.solve.mode == gripsim::scenario::Mode::Static =>
                {
                    " (hint: lower solve.load_step or raise solve.max_newton_iterations; the \
                     recordings end at the last converged load step)"
                }
                gripsim::solver::SimError::Diverged { .. } => {
                    " (hint: lower solve.dt, or raise solve.max_newton_iterations or \
                     solve.max_backoff; the recordings end at the last accepted step)"
                }
                _ => "",
            };
            eprintln!("error: {e}{hint}");
            ExitCode::from(2)
        }
        Ok(_) if failed => ExitCode::from(2),
        Ok(s) if s.unstable_equilibrium => {
            eprintln!(
                "unstable equilibrium: the smallest eigenvalue of the free-DOF Hessian is {:.3e} N/m \
                 (a saddle of the energy; rerun with --perturb to follow the stable branch)",
                s.min_eigenvalue.unwrap_or(f64::NAN)
            );
            ExitCode::from(3)
        }
        Ok(_) => ExitCode::from(check_code),
    }
}

/// Where the recordings are and how to open them.
fn print_recordings(files: &[(&str, Finished)], opts: RecordOptions, auto: Option<AutoStats>) {
    if files.is_empty() {
        return;
    }
    // The .rrd sends its columns at every RRD_FLUSH_POINTS-th flush, or sooner when they
    // reach RRD_CHUNK_BYTES (src/record/rerun.rs).
    let rrd = if files.iter().any(|(f, _)| *f == "rerun") {
        format!(
            "; the .rrd: every {} steps or 1 MiB, whichever first",
            opts.flush_every
                .saturating_mul(gripsim::record::rerun::RRD_FLUSH_POINTS as u64)
        )
    } else {
        String::new()
    };
    say!(
        "recordings      ({} detail, readable up to the last multiple of {} steps if the run dies{})",
        opts.detail.describe(),
        opts.flush_every,
        rrd
    );
    if let Some(a) = auto {
        say!(
            "                {} of {} steps recorded: {} in full around {} eventful step(s), {} sampled",
            a.full + a.sampled,
            a.full + a.sampled + a.dropped,
            a.full,
            a.eventful,
            a.sampled
        );
    }
    for (format, f) in files {
        let size = std::fs::metadata(&f.path).map(|m| m.len()).unwrap_or(0);
        let how = match *format {
            "rerun" => format!("open: rerun {}", f.path.display()),
            "mcap" => "open in Foxglove: Open local file; 3D panel on /scene and /scene/nodes, Plot panel on /sim/step.rods[0].reaction_norm[i]".to_string(),
            _ => "tidy table: one row per step, rod and node".to_string(),
        };
        say!(
            "  {:<5} {} ({:.1} MB{})  {how}",
            format,
            f.path.display(),
            size as f64 / 1e6,
            if f.complete {
                ""
            } else {
                ", INCOMPLETE: the run stopped early"
            }
        );
    }
}

/// `gripsim run` on a `dimension = 3` scenario (src/scenario/three.rs): CSV, summary, `.rrd`
/// and `.mcap` (src/record/rerun3.rs, mcap3.rs), with `--set` overrides.
fn run3(
    path: &Path,
    text: &str,
    sc: gripsim::scenario::three::Scenario3,
    mut out: Outputs,
    no_record: bool,
    sets: &[String],
    quiet: bool,
) -> ExitCode {
    for w in sc.warnings() {
        eprintln!("warning: {}: {w}", path.display());
    }
    // Refused before anything is written: an option the run would silently ignore.
    if let Some((option, value)) = out.planar_only.first() {
        eprintln!(
            "error: {}: {option} {value} applies to planar scenarios only; a 3D run records every step, in f64, with fixed arrow scales, in chunks of its writers' own sizes (drop the option)",
            path.display()
        );
        return ExitCode::from(2);
    }
    // As planar: with no output named, the run is recorded to recordings/<name>.rrd and .mcap.
    if !no_record && out.rrd.is_none() && out.mcap.is_none() && out.csv.is_none() {
        let base = Path::new("recordings").join(file_name(&sc.name));
        out.rrd = Some(base.with_extension("rrd"));
        out.mcap = Some(base.with_extension("mcap"));
    }
    let mut check = match &out.check {
        Some((th, _)) => {
            if let Err(e) = th.validate() {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
            match gripsim::replay::three::Detector3::new(&sc, th) {
                Ok(detector) => Some(gripsim::replay::three::Detect3Observer { detector }),
                Err(e) => {
                    eprintln!("error: {}: {e}", path.display());
                    return ExitCode::from(2);
                }
            }
        }
        None => None,
    };
    // As planar: checked before anything is created, renamed into place together.
    let held = match plan_outputs(path, text, sets, &out) {
        Ok(plan) => plan.hold(),
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let mut rrd = match &out.rrd {
        Some(p) => match gripsim::record::rerun3::Rrd3::create(p, &sc.name) {
            Ok(r) => Some(r),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        },
        None => None,
    };
    let mut mcap = match &out.mcap {
        Some(p) => match gripsim::record::mcap3::Mcap3::create(p, &sc.name, text, sets) {
            Ok(m) => Some(m),
            Err(e) => {
                if let Some(r) = rrd {
                    let _ = r.abandon();
                }
                eprintln!("error: {e}");
                return ExitCode::from(2);
            }
        },
        None => None,
    };
    let start = std::time::Instant::now();
    let mut sinks = gripsim::rod3d::events::Observers3::default();
    if let Some(c) = check.as_mut() {
        sinks.sinks.push(c);
    }
    if let Some(r) = rrd.as_mut() {
        sinks.sinks.push(r);
    }
    if let Some(m) = mcap.as_mut() {
        sinks.sinks.push(m);
    }
    // From here a signal stops the run after the current step and the files are closed.
    install_signal_handlers();
    let stop = || STOP.load(Ordering::Relaxed) != 0;
    // With --check, the bruise rule reads the contact pressures of the one event stream.
    let mut bruise = out
        .check
        .as_ref()
        .map(|_| gripsim::replay::bruise::BruiseObserver::new(sc.expect.bruised));
    let result = {
        let mut live = Fanout::new();
        if let Some(b) = bruise.as_mut() {
            live.push(b as &mut dyn Observer);
        }
        let mut events = gripsim::rod3d::run3::Events {
            text,
            obs: &mut live,
        };
        gripsim::rod3d::run3::run_both(&sc, out.csv.as_deref(), &mut sinks, &mut events, &stop)
    };
    drop(sinks);
    // The recordings are closed either way: moved into place, or (a failed run) kept under
    // their `.partial` names with the error as the run's end, as a planar run's.
    let s = match result {
        Ok(s) => s,
        Err(e) => return run3_failed(path, &e, rrd, mcap),
    };
    let mut closed = match rrd {
        Some(r) => r.finish(),
        None => Ok(()),
    };
    if let Some(m) = mcap {
        closed = closed.and(m.finish());
    }
    if let Err(e) = closed {
        eprintln!("error: {e}");
        return ExitCode::from(1);
    }
    let summary = s.to_summary(start.elapsed().as_secs_f64());
    if let Some(p) = &out.summary {
        let text = serde_json::to_string_pretty(&summary).expect("summary serialises");
        if let Err(e) = gripsim::record::write_atomic(p, (text + "\n").as_bytes()) {
            eprintln!("error: cannot write the summary to {}: {e}", p.display());
            return ExitCode::from(2);
        }
    }
    let report = check.map(|c| {
        let mut report = c
            .detector
            .finish(&format!("{} (live)", path.display()), &s.name);
        if let Some(b) = bruise {
            report.add_bruise(b);
        }
        report
    });
    if let (Some(report), Some((_, Some(p)))) = (&report, &out.check) {
        let text = serde_json::to_string_pretty(report).expect("a report serialises");
        if let Err(e) = gripsim::record::write_atomic(p, (text + "\n").as_bytes()) {
            eprintln!(
                "error: cannot write the check report to {}: {e}",
                p.display()
            );
            return ExitCode::from(2);
        }
    }
    // Every output was written: all of them get their final names now.
    if let Err(e) = held.commit() {
        eprintln!("error: {e}");
        return ExitCode::from(2);
    }
    if !quiet {
        say_part!("{}", summary.to_text());
        for (format, p, how) in [
            ("rerun", &out.rrd, "open: rerun FILE"),
            ("mcap", &out.mcap, "open in Foxglove: 3D panel on /scene"),
            ("csv", &out.csv, "one row per step, object and node"),
        ] {
            if let Some(p) = p {
                let size = std::fs::metadata(p).map_or(0, |m| m.len());
                let how = how.replace("FILE", &p.display().to_string());
                println!(
                    "  {format:<5} {} ({:.1} MB)  {how}",
                    p.display(),
                    size as f64 / 1e6
                );
            }
        }
    }
    if let Some(report) = report {
        print!("{}", gripsim::replay::three::format_check(&report));
        if report.flagged {
            return ExitCode::from(1);
        }
    }
    ExitCode::SUCCESS
}

/// A 3D run that stopped (an error or a signal): its recordings are closed under their
/// `.partial` names with the error as the run's end; the exit status says why.
fn run3_failed(
    path: &Path,
    e: &str,
    rrd: Option<gripsim::record::rerun3::Rrd3>,
    mcap: Option<gripsim::record::mcap3::Mcap3>,
) -> ExitCode {
    let mut kept = Vec::new();
    let closed = [
        rrd.map(|r| r.finish_failed()),
        mcap.map(|m| m.finish_failed()),
    ];
    for c in closed.into_iter().flatten() {
        match c {
            Ok(p) => kept.push(p.display().to_string()),
            Err(e) => eprintln!("error: {e}"),
        }
    }
    let signal = STOP.load(Ordering::Relaxed);
    if signal != 0 && e.starts_with(gripsim::rod3d::run3::INTERRUPTED) {
        eprintln!(
            "{e} by {}; the recordings are closed and keep their .partial names",
            signal_name(signal)
        );
        return ExitCode::from(signal as u8);
    }
    let hint = if e.contains("did not converge") {
        "hint: lower solve.dt or raise solve.max_newton_iterations; "
    } else {
        ""
    };
    eprintln!(
        "error: {}: {e} ({hint}the recordings end at the last accepted step and keep \
         their .partial names{}{})",
        path.display(),
        if kept.is_empty() { "" } else { ": " },
        kept.join(", ")
    );
    ExitCode::from(2)
}

fn list_scenarios(dir: &Path) -> ExitCode {
    let mut entries: Vec<PathBuf> = match std::fs::read_dir(dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect(),
        Err(e) => {
            eprintln!(
                "error: cannot list {}: {e} (run from the project root or pass --dir)",
                dir.display()
            );
            return ExitCode::from(2);
        }
    };
    entries.sort();
    for p in entries {
        if gripsim::scenario::three::file_is_3d(&p) {
            match gripsim::scenario::three::Scenario3::load(&p) {
                Ok(sc) => say!("{:<44} {} (3D)", p.display(), sc.description.trim()),
                Err(e) => say!("{:<44} INVALID: {e}", p.display()),
            }
            continue;
        }
        match Scenario::load(&p, &[]) {
            Ok(sc) => {
                let first = sc
                    .description
                    .lines()
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_string();
                say!("{:<44} {}", p.display(), first);
            }
            Err(e) => say!("{:<44} INVALID: {e}", p.display()),
        }
    }
    ExitCode::SUCCESS
}

fn bench(quick: bool, stress: bool, out: PathBuf, repeats: Option<usize>) -> ExitCode {
    use gripsim::bench;
    let opt = bench::BenchOptions {
        quick,
        out: out.clone(),
        repeats: repeats.unwrap_or(if quick { 1 } else { 5 }),
    };
    let mut log = |s: &str| println!("{s}");
    let result = if stress {
        bench::stress(&opt, &mut log).map(|cells| {
            let bad = cells.iter().filter(|c| c.non_finite).count();
            let pen = cells.iter().filter(|c| c.status == bench::CellStatus::Ok && c.max_penetration > 1e-9).count();
            println!("stress map: {} cells, {bad} with a non-finite value, {pen} ok cells with penetration > 1e-9 m", cells.len());
        })
    } else {
        bench::work_precision(&opt, &mut log)
            .and_then(|_| bench::scaling(&opt, &mut log))
            .map(|_| ())
    };
    match result {
        Ok(()) => {
            println!("wrote tables and figures to {}", out.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// `gripsim sweep` and `gripsim sweep merge`: the library does the work. Exit 0 when done
/// (cases that stopped with a solver error are results: see the error column), 2 on an error,
/// 130/143 when a signal stopped it (finished cases stay; run the same command to resume).
fn sweep(args: SweepCli) -> ExitCode {
    use gripsim::study;
    if let Some(SweepMerge::Merge {
        dirs,
        out,
        no_plots,
    }) = args.merge
    {
        let opts = study::MergeOptions {
            dirs,
            out,
            plots: !no_plots,
        };
        return match study::merge(&opts) {
            Ok(r) => {
                for e in &r.plot_errors {
                    eprintln!("warning: figures not drawn: {e}");
                }
                println!(
                    "merged {} cases into {} ({} case folders copied); wrote {}",
                    r.cases,
                    r.out.display(),
                    r.copied,
                    r.summary.display()
                );
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
        };
    }
    let (Some(scenario), Some(out)) = (args.scenario, args.out) else {
        eprintln!("error: sweep needs a SCENARIO and --out DIR");
        return ExitCode::from(2);
    };
    install_signal_handlers();
    let opts = study::SweepOptions {
        scenario,
        vary: args.vary,
        sets: args.sets,
        jobs: args.jobs.unwrap_or(0),
        out,
        shard: args.shard,
        plots: !args.no_plots,
        case_plots: if args.no_plots {
            study::CasePlots::None
        } else {
            args.case_plots
        },
        window: None,
        quiet: args.quiet,
        stop: Some(std::sync::Arc::new(|| STOP.load(Ordering::Relaxed) != 0)),
    };
    match study::run_sweep(&opts) {
        Ok(r) => {
            for e in &r.plot_errors {
                eprintln!("warning: figures not drawn: {e}");
            }
            let shard = opts
                .shard
                .map(|s| format!(" (shard {}/{}: {} of them)", s.index, s.count, r.in_shard))
                .unwrap_or_default();
            println!(
                "sweep: {} cases{shard}: {} run, {} skipped (finished before), {} stopped with an error, {} with warnings, {:.2} s",
                r.cases, r.ran, r.skipped, r.failed, r.warned, r.wall_time_s
            );
            if r.interrupted {
                let stop = STOP.load(Ordering::Relaxed);
                let signal = signal_name(stop);
                eprintln!(
                    "interrupted by {signal}: {} of {} cases are finished in {}; run the same command again to resume",
                    r.ran + r.skipped,
                    r.in_shard,
                    opts.out.join("cases").display()
                );
                return ExitCode::from(if stop == 0 { 130 } else { stop as u8 });
            }
            if let Some(p) = &r.summary {
                println!("wrote {}", p.display());
            }
            if opts.shard.is_some() {
                println!(
                    "when every shard is done: gripsim sweep merge {}",
                    opts.out.display()
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// `gripsim window`: one search (printed, `--json`), or with `--vary` a map of windows on the
/// sweep machinery. Exit 0 when it ran, 2 on bad input, 130/143 when a signal stopped it.
fn window(args: WindowCli) -> ExitCode {
    use gripsim::study::{self, window};
    let spec = window::WindowSpec {
        knob: args.knob,
        range: args.range,
        rtol: args.rtol,
    };
    let usage = |m: &str| {
        eprintln!("error: {m}");
        ExitCode::from(2)
    };
    if args.vary.is_empty() {
        if args.out.is_some() || args.shard.is_some() {
            return usage("--out and --shard go with --vary (a map of windows over design parameters); one search prints its result (--json FILE keeps it)");
        }
    } else if args.json.is_some() {
        return usage("--json goes with a single search; a map writes DIR/window.json (--out DIR)");
    }
    install_signal_handlers();
    let stop: window::Stop = std::sync::Arc::new(|| STOP.load(Ordering::Relaxed) != 0);
    let interrupted = |what: &str| {
        let code = STOP.load(Ordering::Relaxed);
        eprintln!("interrupted by {}: {what}", signal_name(code));
        ExitCode::from(if code == 0 { 130 } else { code as u8 })
    };
    if !args.vary.is_empty() {
        let Some(out) = args.out else {
            return usage(
                "window --vary needs --out DIR (where window.csv, window.json and window.png go)",
            );
        };
        let resolved = match window::resolve_file(&args.scenario, &args.sets, &spec) {
            Ok((_, r)) => r,
            Err(e) => return usage(&e.to_string()),
        };
        if !args.quiet {
            eprintln!(
                "knob {} ({}), range {}–{}, rtol {}",
                resolved.knob,
                resolved.what,
                window::fmt_g(resolved.lo),
                resolved.show(resolved.hi),
                resolved.rtol
            );
        }
        let opts = study::SweepOptions {
            scenario: args.scenario,
            vary: args.vary,
            sets: args.sets,
            jobs: args.jobs.unwrap_or(0),
            out,
            shard: args.shard,
            plots: !args.no_plots,
            case_plots: study::CasePlots::None,
            window: Some(resolved),
            quiet: args.quiet,
            stop: Some(stop),
        };
        return match study::run_sweep(&opts) {
            Ok(r) => {
                for e in &r.plot_errors {
                    eprintln!("warning: picture not drawn: {e}");
                }
                let shard = opts
                    .shard
                    .map(|s| format!(" (shard {}/{}: {} of them)", s.index, s.count, r.in_shard))
                    .unwrap_or_default();
                println!(
                    "window map: {} designs{shard}: {} searched, {} skipped (finished before), {:.2} s",
                    r.cases, r.ran, r.skipped, r.wall_time_s
                );
                if r.interrupted {
                    return interrupted(&format!(
                        "{} of {} designs are finished in {}; run the same command again to resume",
                        r.ran + r.skipped,
                        r.in_shard,
                        opts.out.join("cases").display()
                    ));
                }
                if let Some(p) = &r.summary {
                    println!("wrote {}", p.display());
                }
                if opts.shard.is_some() {
                    println!(
                        "when every shard is done: gripsim sweep merge {}",
                        opts.out.display()
                    );
                }
                ExitCode::SUCCESS
            }
            Err(e) => usage(&e.to_string()),
        };
    }
    let opts = window::WindowOptions {
        scenario: args.scenario,
        sets: args.sets,
        spec,
        jobs: args.jobs.unwrap_or(0),
        stop: Some(stop),
    };
    let count = AtomicUsize::new(0);
    let quiet = args.quiet;
    let progress = |e: &window::Eval| {
        if !quiet {
            let k = count.fetch_add(1, Ordering::Relaxed) + 1;
            eprintln!("run {k}: {} -> {}", window::fmt_g(e.value), e.outcome());
        }
    };
    match window::run_window(&opts, Some(&progress)) {
        Ok(Some(r)) => {
            if let Some(p) = &args.json {
                if let Err(e) = window::write_result(p, &r) {
                    return usage(&e.to_string());
                }
            }
            say_part!("{}", r.report());
            if let Some(p) = &args.json {
                say!("wrote {}", p.display());
            }
            ExitCode::SUCCESS
        }
        Ok(None) => interrupted("no result written; run the same command again"),
        Err(e) => usage(&e.to_string()),
    }
}

/// `gripsim replay`: the library does the work; exit 0 clean, 1 flagged/different, 2 error.
fn replay(args: gripsim::replay::ReplayArgs) -> ExitCode {
    ExitCode::from(gripsim::replay::main(args))
}
