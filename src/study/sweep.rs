//! The sweep: build the grid, run the unfinished cases on a pool of threads, write each case's
//! result folder atomically, and the summary table and plots once every case is done.
//!
//! Layout of an output folder:
//!
//! ```text
//! DIR/sweep.json                the grid: keys, values, case ids and scenario hashes
//! DIR/cases/<id>/case.json      the done marker: parameters and metrics (written last)
//! DIR/cases/<id>/summary.json   what `gripsim run --summary` writes for this case
//! DIR/cases/<id>/scenario.toml  the case's scenario with every assignment applied
//! DIR/cases/<id>/forces.png|svg reaction, impulse-consistent force, bending stress per node
//! DIR/cases/<id>/shapes.png|svg prong snapshots, nodes coloured by force
//! DIR/summary.csv, summary.md   one row per case, in grid order
//! DIR/plots/vs-<key>.png|svg    every metric against every varied key
//! DIR/summary.shard-I-of-N.csv  a shard's own rows (`--shard`)
//! ```
//!
//! A case folder is filled under `cases/.tmp-<id>` and renamed into place in one step, so a
//! folder `cases/<id>` is always complete; a run stopped by a signal leaves only the temporary
//! folder, which the next run replaces.

use super::plots::{self, Trace};
use super::{case_id, io_err, Shard, StudyError, Vary};
use crate::record::summary::Summary;
use crate::run::AnyScenario;
use serde::{Deserialize, Serialize};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Instant;

/// Version of `sweep.json` and `case.json`.
pub const FORMAT: u32 = 1;

/// What `gripsim sweep` was asked to do.
#[derive(Clone)]
pub struct SweepOptions {
    pub scenario: PathBuf,
    pub vary: Vec<Vary>,
    /// Assignments applied to every case before the varied ones.
    pub sets: Vec<String>,
    /// Worker threads; 0 = one per core.
    pub jobs: usize,
    pub out: PathBuf,
    pub shard: Option<Shard>,
    /// The sweep's figures (`plots/`; `window.png` of a window map).
    pub plots: bool,
    /// Which cases get their own figures (forces, shapes).
    pub case_plots: CasePlots,
    /// A window map: each case (design) is a grasp-window search over the knob
    /// (`gripsim window --vary`), not one run.
    pub window: Option<super::window::Resolved>,
    /// No progress bar and no per-case lines.
    pub quiet: bool,
    /// Polled between steps and between cases; true stops the sweep (finished cases stay).
    pub stop: Option<Arc<dyn Fn() -> bool + Send + Sync>>,
}

/// Which cases of a sweep get their own figures (`forces`, `shapes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CasePlots {
    /// Every case.
    All,
    /// The cases a person will open: those [`flagged`] (an error, a warning, a spike, a
    /// sticking episode or a bruise).
    #[default]
    Flagged,
    /// None.
    None,
}

impl std::str::FromStr for CasePlots {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "all" => Ok(CasePlots::All),
            "flagged" => Ok(CasePlots::Flagged),
            "none" => Ok(CasePlots::None),
            _ => Err(format!("--case-plots {s:?}: expected all, flagged or none")),
        }
    }
}

/// What a sweep did.
#[derive(Debug, Clone, Default)]
pub struct SweepReport {
    /// Cases in the whole grid.
    pub cases: usize,
    /// Cases in this shard (the whole grid without `--shard`).
    pub in_shard: usize,
    pub ran: usize,
    pub skipped: usize,
    /// Cases whose run stopped with an error (they are results too: `completed` is false).
    pub failed: usize,
    /// Cases with a warning event (e.g. a driven node entered the fruit).
    pub warned: usize,
    pub interrupted: bool,
    /// The summary table written (None when interrupted).
    pub summary: Option<PathBuf>,
    pub wall_time_s: f64,
    /// Figures that could not be drawn (e.g. no font), one message per kind.
    pub plot_errors: Vec<String>,
}

/// One case of the grid, as recorded in `sweep.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseEntry {
    pub id: String,
    /// One value per varied key, in `vary` order.
    pub values: Vec<String>,
    /// FNV-1a of the case's effective scenario text (all assignments applied).
    pub scenario_hash: String,
}

/// `sweep.json`: the grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: u32,
    pub scenario: String,
    pub sets: Vec<String>,
    pub vary: Vec<Vary>,
    /// Rod names of the first case (the per-prong columns).
    pub rods: Vec<String>,
    pub cases: Vec<CaseEntry>,
    /// A window map's knob, range and tolerance (absent for a sweep).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<super::window::Resolved>,
}

impl Manifest {
    /// Same grid and same scenarios (the scenario path and `--set` text may differ).
    fn same_grid(&self, other: &Manifest) -> bool {
        self.vary == other.vary
            && self.rods == other.rods
            && self.cases == other.cases
            && self.window == other.window
    }
}

/// The numbers of one case (a row of `summary.csv`). Node numbers are 0-based.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub completed: bool,
    pub error: Option<String>,
    pub steps: u64,
    pub simulated_time_s: f64,
    /// Peak eq. 2 reaction magnitude (N), where and when.
    pub peak_reaction_n: f64,
    pub peak_reaction_rod: Option<String>,
    pub peak_reaction_node: Option<usize>,
    pub peak_reaction_time_s: Option<f64>,
    /// Peak impulse-consistent force (N): contact impulse over a sliding 1 ms window / window.
    pub peak_impulse_consistent_force_n: f64,
    pub peak_impulse_consistent_rod: Option<String>,
    pub peak_impulse_consistent_node: Option<usize>,
    /// Σ over nodes of Σ |R| dt, per rod (N·s).
    pub total_impulse_per_rod_ns: Vec<f64>,
    /// The rods the per-rod numbers belong to, in their order (a case may have other rods
    /// than the first, e.g. a sweep over a Fin Ray finger's `ribs`: its per-rod columns are
    /// matched by name). Empty in records written before it: matched by position.
    #[serde(default)]
    pub rod_names: Vec<String>,
    /// The node constrained at the end of the most steps (ties: the lowest rod, then node).
    pub most_contact_steps_rod: Option<String>,
    pub most_contact_steps_node: Option<usize>,
    pub most_contact_steps: u64,
    pub contact_onset_s: Option<f64>,
    /// The node that touched first (ties: the lowest rod, then node).
    pub first_contact_rod: Option<String>,
    pub first_contact_node: Option<usize>,
    pub max_bending_stress_pa: f64,
    pub max_bending_stress_rod: Option<String>,
    pub max_bending_stress_node: Option<usize>,
    /// Per rod: max over time of the tip's deflection from the rigidly driven shape (m).
    pub max_tip_deflection_per_rod_m: Vec<f64>,
    pub max_penetration_m: f64,
    /// Constraints released because their eq. 2 reaction turned adhesive (R·n < 0).
    pub releases: u64,
    /// Warning events of the run (a driven node entering an obstacle, …).
    pub warnings: usize,
    /// Velocity spikes and sticking episodes `gripsim replay check` would report on this
    /// case's recording (found while it ran, by the same detector, with its defaults).
    #[serde(default)]
    pub spikes: usize,
    #[serde(default)]
    pub sticking: usize,
    /// The grasp of the first free body (empty columns without one): held, dropped, peak grip
    /// force per prong (N), minimum safety margin μ_s ΣN/(m g) during the lift, largest slip
    /// relative to the gripper (m), first stick → slip of a prong contact (s).
    /// The grasp's verdict: `held`, `slipped`, `dropped` or `no_lift` (empty without a free
    /// body).
    #[serde(default)]
    pub verdict: Option<String>,
    #[serde(default)]
    pub held: Option<bool>,
    #[serde(default)]
    pub dropped: Option<bool>,
    #[serde(default)]
    pub peak_grip_force_n: Option<f64>,
    #[serde(default)]
    pub min_safety_margin: Option<f64>,
    #[serde(default)]
    pub max_slip_m: Option<f64>,
    #[serde(default)]
    pub first_slip_s: Option<f64>,
    /// A compliant fruit's contact (empty columns at a rigid one): the largest contact force
    /// of the law (N), peak Hertz pressure (Pa), deepest indentation (m), whether the pressure
    /// exceeded the bruise threshold, by how much (max p₀ / threshold), the widest part of a
    /// contact above it (m), and the stretches `replay check` flags as `bruise`.
    #[serde(default)]
    pub peak_contact_force_n: Option<f64>,
    #[serde(default)]
    pub max_pressure_pa: Option<f64>,
    #[serde(default)]
    pub max_indentation_m: Option<f64>,
    #[serde(default)]
    pub bruised: Option<bool>,
    #[serde(default)]
    pub bruise_ratio: Option<f64>,
    #[serde(default)]
    pub max_bruise_width_m: Option<f64>,
    #[serde(default)]
    pub bruise: usize,
    pub wall_time_s: f64,
    /// 2 or 3 (0 in records written before it: planar). A 3D run does not measure the
    /// impulse-consistent force, bending stress or first slip: their columns are empty.
    #[serde(default)]
    pub dimension: u8,
}

impl Metrics {
    pub fn from_summary(s: &Summary, releases: u64, warnings: usize) -> Metrics {
        let mut most: Option<(String, usize, u64)> = None;
        for r in &s.rods {
            for (i, c) in r.contact_steps_per_node.iter().enumerate() {
                if *c > 0 && most.as_ref().is_none_or(|m| *c > m.2) {
                    most = Some((r.name.clone(), i, *c));
                }
            }
        }
        let mut first: Option<(String, usize, f64)> = None;
        for r in &s.rods {
            for (i, t) in r.first_contact_time_s.iter().enumerate() {
                if let Some(t) = *t {
                    if first.as_ref().is_none_or(|f| t < f.2) {
                        first = Some((r.name.clone(), i, t));
                    }
                }
            }
        }
        Metrics {
            completed: s.completed,
            error: s.error.clone(),
            steps: s.steps,
            simulated_time_s: s.simulated_time_s,
            peak_reaction_n: s.peak_reaction_force_n,
            peak_reaction_rod: s.peak_reaction_node.as_ref().map(|n| n.rod.clone()),
            peak_reaction_node: s.peak_reaction_node.as_ref().map(|n| n.node),
            peak_reaction_time_s: s.peak_reaction_time_s,
            peak_impulse_consistent_force_n: s.peak_impulse_consistent_force_n,
            peak_impulse_consistent_rod: s
                .peak_impulse_consistent_node
                .as_ref()
                .map(|n| n.rod.clone()),
            peak_impulse_consistent_node: s.peak_impulse_consistent_node.as_ref().map(|n| n.node),
            total_impulse_per_rod_ns: s
                .rods
                .iter()
                .map(|r| r.total_impulse_per_node_ns.iter().sum())
                .collect(),
            rod_names: s.rods.iter().map(|r| r.name.clone()).collect(),
            most_contact_steps: most.as_ref().map(|m| m.2).unwrap_or(0),
            most_contact_steps_rod: most.as_ref().map(|m| m.0.clone()),
            most_contact_steps_node: most.as_ref().map(|m| m.1),
            contact_onset_s: s.contact_onset_time_s,
            first_contact_rod: first.as_ref().map(|f| f.0.clone()),
            first_contact_node: first.as_ref().map(|f| f.1),
            max_bending_stress_pa: s.max_bending_stress_pa,
            max_bending_stress_rod: s.max_bending_stress_node.as_ref().map(|n| n.rod.clone()),
            max_bending_stress_node: s.max_bending_stress_node.as_ref().map(|n| n.node),
            max_tip_deflection_per_rod_m: s.rods.iter().map(|r| r.max_tip_deflection_m).collect(),
            max_penetration_m: s.max_penetration_m,
            releases,
            warnings,
            spikes: 0,
            sticking: 0,
            verdict: s.grasp.as_ref().and_then(|g| {
                serde_json::to_value(g.verdict)
                    .ok()
                    .and_then(|v| v.as_str().map(String::from))
            }),
            held: s.grasp.as_ref().map(|g| g.held),
            dropped: s.grasp.as_ref().map(|g| g.dropped),
            peak_grip_force_n: s.grasp.as_ref().map(|g| g.peak_grip_force_n),
            min_safety_margin: s.grasp.as_ref().and_then(|g| g.min_safety_margin),
            max_slip_m: s.grasp.as_ref().map(|g| g.max_slip_m),
            first_slip_s: s.grasp.as_ref().and_then(|g| g.first_slip_time_s),
            peak_contact_force_n: s.contact_pressure.as_ref().map(|p| p.peak_contact_force_n),
            max_pressure_pa: s.contact_pressure.as_ref().map(|p| p.max_pressure_pa),
            max_indentation_m: s.contact_pressure.as_ref().map(|p| p.max_indentation_m),
            bruised: s.contact_pressure.as_ref().map(|p| p.bruised),
            bruise_ratio: s.contact_pressure.as_ref().map(|p| p.bruise_ratio),
            max_bruise_width_m: s.contact_pressure.as_ref().map(|p| p.max_bruise_width_m),
            bruise: 0,
            wall_time_s: s.wall_time_s,
            dimension: s.dimension,
        }
    }
}

/// `case.json`: the done marker of a case folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaseRecord {
    pub format: u32,
    pub id: String,
    /// (key, value) of every varied key.
    pub parameters: Vec<(String, String)>,
    /// Every assignment applied, base `--set` first.
    pub sets: Vec<String>,
    pub scenario_hash: String,
    pub gripsim_version: String,
    /// The same run by hand: `gripsim run SCENARIO --set … --summary FILE --no-record`.
    pub command: String,
    /// The run's numbers (a sweep's case).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<Metrics>,
    /// The design's grasp window (a window map's case).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<Box<super::window::WindowResult>>,
    pub warnings: Vec<String>,
    pub plot_error: Option<String>,
}

impl CaseRecord {
    /// The run's numbers of a sweep case (all zero and empty for a window map's design, which
    /// has none; [`finished`] never mixes the two kinds).
    pub fn run_metrics(&self) -> &Metrics {
        static NONE: std::sync::OnceLock<Metrics> = std::sync::OnceLock::new();
        self.metrics
            .as_ref()
            .unwrap_or_else(|| NONE.get_or_init(Metrics::default))
    }
}

/// A case ready to run.
struct Case {
    index: usize,
    id: String,
    values: Vec<String>,
    sets: Vec<String>,
    hash: String,
}

/// The largest grid a sweep takes (cases, counted before anything is built).
pub const MAX_CASES: usize = 100_000;

/// The scenario text every case starts from, and the first case's scenario (its rods name
/// the manifest's columns). Cases keep only their assignments and hash; each one's
/// scenario is read again when it runs.
struct Base {
    text: String,
    file: String,
    /// The folder a 3D scenario's mesh files are relative to.
    dir: PathBuf,
    /// The first case's rods (the manifest's per-prong columns).
    rods: Vec<String>,
}

/// A case's scenario of either dimension with the text it runs (every assignment applied:
/// what the case folder's `scenario.toml` holds and its hash is taken of).
pub struct Loaded {
    pub scenario: AnyScenario,
    pub text: String,
}

/// Read `text` (named `file`; a 3D mesh's `file` relative to `dir`) with `sets` applied.
pub fn load(
    text: &str,
    file: &str,
    dir: &Path,
    sets: &[String],
) -> Result<Loaded, crate::scenario::ScenarioError> {
    let scenario = AnyScenario::parse(text, file, dir, sets)?;
    let text = match &scenario {
        AnyScenario::Planar(s) => s.text.clone(),
        AnyScenario::Spatial(_) if sets.is_empty() => text.to_string(),
        AnyScenario::Spatial(_) => {
            // As the 3D reader applies them (it read this text, so it parses and serialises).
            let mut root: toml::Table = text.parse().unwrap_or_default();
            crate::scenario::apply_sets(&mut root, sets, file)?;
            toml::to_string(&root).unwrap_or_else(|_| text.to_string())
        }
    };
    Ok(Loaded { scenario, text })
}

/// The rods' names of a scenario (3D: of the world it builds).
pub(crate) fn rod_names(sc: &AnyScenario) -> Result<Vec<String>, String> {
    Ok(match sc {
        AnyScenario::Planar(s) => s.rods.iter().map(|r| r.name.clone()).collect(),
        AnyScenario::Spatial(s) => crate::rod3d::run3::build(s)?.0.rod_names,
    })
}

fn hash_text(text: &str) -> String {
    format!("{:016x}", super::fnv1a(text.as_bytes()))
}

/// The values of grid case `index` (the first `--vary` key varies slowest).
fn grid_values(vary: &[Vary], mut index: usize) -> Vec<String> {
    let mut values = vec![String::new(); vary.len()];
    for (k, v) in vary.iter().enumerate().rev() {
        let n = v.values.len();
        values[k] = v.values[index % n].clone();
        index /= n;
    }
    values
}

/// The number of cases of the grid, or an error when it is over [`MAX_CASES`] (counted
/// without building anything).
fn grid_size(vary: &[Vary]) -> Result<usize, StudyError> {
    let n = vary
        .iter()
        .try_fold(1usize, |acc, v| acc.checked_mul(v.values.len()))
        .filter(|&n| n <= MAX_CASES);
    n.ok_or_else(|| {
        let counts: Vec<String> = vary.iter().map(|v| v.values.len().to_string()).collect();
        let product = vary
            .iter()
            .fold(1f64, |acc, v| acc * v.values.len() as f64);
        StudyError::Usage(format!(
            "the grid has {} = {product:.3e} cases; a sweep takes at most {MAX_CASES}: vary fewer keys or fewer values (or split it with --shard and separate sweeps)",
            counts.join(" x ")
        ))
    })
}

/// Check every case of the grid (each is the scenario with its assignments) and hash it: on
/// `jobs` threads, with a progress line on stderr when it takes a while, stopping within one
/// case when `opts.stop` says so (then `Ok(None)`).
fn build_cases(
    opts: &SweepOptions,
    jobs: usize,
    text: String,
) -> Result<Option<(Base, Vec<Case>)>, StudyError> {
    if opts.vary.is_empty() {
        return Err(StudyError::Usage(
            "a sweep needs at least one --vary KEY=V1,V2,...".into(),
        ));
    }
    for (i, v) in opts.vary.iter().enumerate() {
        if opts.vary[..i].iter().any(|w| w.key == v.key) {
            return Err(StudyError::Usage(format!(
                "--vary {} is given twice: list all its values in one --vary",
                v.key
            )));
        }
    }
    let total = grid_size(&opts.vary)?;
    let keys: Vec<String> = opts.vary.iter().map(|v| v.key.clone()).collect();
    if let Some(w) = &opts.window {
        if keys.contains(&w.knob) {
            return Err(StudyError::Usage(format!(
                "--vary {}: that is the window's knob (the value each design's search varies); vary a design parameter",
                w.knob
            )));
        }
    }
    let file = opts.scenario.display().to_string();
    let dir = scenario_dir(&opts.scenario);
    let stopped = || opts.stop.as_ref().is_some_and(|s| s());
    let check = |index: usize| -> Result<(Case, AnyScenario), StudyError> {
        let values = grid_values(&opts.vary, index);
        let mut sets = opts.sets.clone();
        sets.extend(keys.iter().zip(&values).map(|(k, v)| format!("{k}={v}")));
        let loaded = load(&text, &file, &dir, &sets).map_err(|e| {
            let what: Vec<String> = keys
                .iter()
                .zip(&values)
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            StudyError::Scenario(format!("case {index} ({}): {e}", what.join(", ")))
        })?;
        let hash = match &opts.window {
            // The knob, range and tolerance are part of what a design's result depends on.
            Some(w) => {
                w.check_design(&loaded.text, &file)
                    .map_err(|e| StudyError::Scenario(format!("case {index}: {e}")))?;
                hash_text(&format!("{}\n# window {}", loaded.text, w.canonical()))
            }
            None => hash_text(&loaded.text),
        };
        let case = Case {
            index,
            id: case_id(&keys, &values),
            hash,
            values,
            sets,
        };
        Ok((case, loaded.scenario))
    };
    // The first case at once: a scenario that does not read fails before any waiting.
    let (first_case, first) = check(0)?;
    let mut cases: Vec<Option<Case>> = (0..total).map(|_| None).collect();
    cases[0] = Some(first_case);
    let next = AtomicUsize::new(1);
    let done = AtomicUsize::new(1);
    let halted = AtomicBool::new(false);
    let (tx, rx) = mpsc::channel::<Result<Case, StudyError>>();
    let mut first_error: Option<(usize, StudyError)> = None;
    let mut interrupted = false;
    std::thread::scope(|s| {
        for _ in 0..jobs.clamp(1, total) {
            let tx = tx.clone();
            let (next, done, halted, check, stopped) = (&next, &done, &halted, &check, &stopped);
            s.spawn(move || loop {
                if halted.load(Ordering::Relaxed) || stopped() {
                    break;
                }
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= total {
                    break;
                }
                let r = check(k).map(|(c, _)| c);
                if r.is_err() {
                    halted.store(true, Ordering::Relaxed);
                }
                done.fetch_add(1, Ordering::Relaxed);
                if tx.send(r).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        let started = Instant::now();
        let mut shown = Instant::now();
        loop {
            match rx.recv_timeout(std::time::Duration::from_millis(200)) {
                Ok(Ok(c)) => {
                    let i = c.index;
                    cases[i] = Some(c);
                }
                Ok(Err(e)) => {
                    // Report the lowest failing case, as a serial check would.
                    let idx = match &e {
                        StudyError::Scenario(m) => m
                            .strip_prefix("case ")
                            .and_then(|r| r.split(' ').next())
                            .and_then(|n| n.parse().ok())
                            .unwrap_or(usize::MAX),
                        _ => usize::MAX,
                    };
                    if first_error.as_ref().is_none_or(|(j, _)| idx < *j) {
                        first_error = Some((idx, e));
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if stopped() {
                interrupted = true;
                halted.store(true, Ordering::Relaxed);
            }
            if !opts.quiet
                && started.elapsed().as_secs_f64() > 2.0
                && shown.elapsed().as_secs_f64() >= 1.0
            {
                eprintln!(
                    "checking the grid: {} of {total} cases read",
                    done.load(Ordering::Relaxed)
                );
                shown = Instant::now();
            }
        }
    });
    if let Some((_, e)) = first_error {
        return Err(e);
    }
    if interrupted || stopped() {
        return Ok(None);
    }
    let cases: Vec<Case> = cases.into_iter().flatten().collect();
    if cases.len() != total {
        // Stopped between two cases.
        return Ok(None);
    }
    let mut seen: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for c in &cases {
        if let Some(o) = seen.insert(&c.id, c.index) {
            return Err(StudyError::Usage(format!(
                "cases {} and {} get the same folder name {}",
                o, c.index, c.id
            )));
        }
    }
    let rods =
        rod_names(&first).map_err(|e| StudyError::Scenario(format!("{file}: case 0: {e}")))?;
    Ok(Some((
        Base {
            text,
            file,
            dir,
            rods,
        },
        cases,
    )))
}

pub(crate) fn read_json<T: for<'de> Deserialize<'de>>(
    path: &Path,
) -> Result<Option<T>, StudyError> {
    match std::fs::read(path) {
        Ok(b) => serde_json::from_slice(&b)
            .map(Some)
            .map_err(|e| io_err(path, format!("unreadable: {e}"))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io_err(path, e)),
    }
}

/// Write through a temporary file of a name no other process or thread uses, then rename:
/// shards sharing a folder may write the same file at the same time.
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), StudyError> {
    static SEQ: AtomicUsize = AtomicUsize::new(0);
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| io_err(dir, e))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let host = std::env::var("HOSTNAME").unwrap_or_default();
    let tmp = dir.join(format!(
        ".{name}.{}.{}.{}.partial",
        super::sanitize(&host),
        std::process::id(),
        SEQ.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::write(&tmp, bytes).map_err(|e| io_err(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io_err(path, e)
    })
}

pub(crate) fn write_json<T: Serialize>(path: &Path, v: &T) -> Result<(), StudyError> {
    let mut text = serde_json::to_string_pretty(v).expect("serialises");
    text.push('\n');
    write_atomic(path, text.as_bytes())
}

/// Write `path` only when its content changes (so a sweep with nothing new touches nothing).
pub(crate) fn write_if_changed(path: &Path, bytes: &[u8]) -> Result<bool, StudyError> {
    if std::fs::read(path).ok().as_deref() == Some(bytes) {
        return Ok(false);
    }
    write_atomic(path, bytes)?;
    Ok(true)
}

/// The finished record of a case folder, if it is one of this scenario (and of this kind: a
/// window map's design when `window`, a sweep's run otherwise).
fn finished(
    cases_dir: &Path,
    id: &str,
    hash: &str,
    window: bool,
) -> Result<Option<CaseRecord>, StudyError> {
    let path = cases_dir.join(id).join("case.json");
    let rec: Option<CaseRecord> = match read_json(&path) {
        Ok(r) => r,
        // A damaged marker: the case runs again and replaces the folder.
        Err(_) => return Ok(None),
    };
    match rec {
        // A marker without the numbers of its kind is damaged: the case runs again.
        Some(r) if r.scenario_hash == hash => {
            Ok((r.window.is_some() == window && r.metrics.is_some() != window).then_some(r))
        }
        Some(_) => Err(StudyError::Mismatch(format!(
            "{} holds a result of a different scenario (the base scenario, --set, or a window's \
             knob, range or rtol changed since it ran); use another --out, or delete that folder to recompute it",
            cases_dir.join(id).display()
        ))),
        None => Ok(None),
    }
}

fn command_line(scenario: &str, sets: &[String]) -> String {
    let mut s = format!("gripsim run {}", shell_quote(scenario));
    for a in sets {
        s.push_str(" --set ");
        s.push_str(&shell_quote(a));
    }
    s.push_str(" --summary summary.json --no-record");
    s
}

pub(crate) fn shell_quote(s: &str) -> String {
    if s.chars()
        .all(|c| c.is_ascii_alphanumeric() || "._-=/+:,".contains(c))
    {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

enum Outcome {
    Done(Box<CaseRecord>),
    Interrupted,
}

/// One run of a scenario as a sweep runs a case (no recordings): its summary, the trace the
/// per-case figures are drawn from (time series only when `series`), and what the replay
/// detector found. None when `stop` interrupted it.
pub(crate) struct CaseRun {
    pub summary: Summary,
    pub trace: Trace,
    pub found: crate::replay::detect::Counts,
}

impl CaseRun {
    /// The case's row: the summary's numbers with the trace's and the detector's counts.
    pub fn metrics(&self) -> Metrics {
        Metrics {
            spikes: self.found.spikes,
            sticking: self.found.sticking,
            bruise: self.found.bruise,
            ..Metrics::from_summary(
                &self.summary,
                self.trace.releases,
                self.trace.warnings.len(),
            )
        }
    }
}

/// The folder a scenario's relative file names (a 3D mesh) are read from.
pub(crate) fn scenario_dir(path: &Path) -> PathBuf {
    path.parent().unwrap_or(Path::new(".")).to_path_buf()
}

/// Run `scenario` of either dimension (whose text, every assignment applied, is `text`) to
/// its end through [`crate::run::run_with`], with the replay check's default rules (or until
/// `stop` says so: then None). `Err`: a 3D world that cannot be built from the scenario.
pub(crate) fn run_scenario(
    scenario: &AnyScenario,
    text: &str,
    stop: Option<&Arc<dyn Fn() -> bool + Send + Sync>>,
    series: bool,
) -> Result<Option<CaseRun>, StudyError> {
    let mut trace = if series {
        Trace::of(scenario)
    } else {
        Trace::counts_of(scenario)
    };
    let th = crate::replay::detect::Thresholds::default();
    let out = crate::run::run_with(scenario, text, &mut trace, stop.cloned(), Some(&th));
    let out = out.map_err(|e| StudyError::Scenario(format!("{}: {e}", scenario.name())))?;
    if out.error.as_ref().is_some_and(|e| e.interrupted()) {
        return Ok(None);
    }
    Ok(Some(CaseRun {
        summary: out.summary,
        trace,
        found: out.check.unwrap_or_default(),
    }))
}

/// Whether a case carries something a person should look at: it stopped with an error, a
/// warning event, or a velocity spike, sticking episode or bruise the replay check flags.
pub fn flagged(m: &Metrics) -> bool {
    !m.completed || m.warnings > 0 || m.spikes > 0 || m.sticking > 0 || m.bruise > 0
}

/// The per-case figures of a case: drawn for every case, for flagged ones only, or none.
/// A flagged case is run a second time with its time series kept (the runs are
/// deterministic: the same numbers), so unflagged cases cost what `--no-plots` costs.
fn case_figures(
    case: &Case,
    scenario: &Loaded,
    run: &CaseRun,
    opts: &SweepOptions,
    keys: &[String],
    dir: &Path,
) -> Result<Option<String>, ()> {
    let draw = match opts.case_plots {
        CasePlots::None => return Ok(None),
        CasePlots::All => true,
        CasePlots::Flagged => flagged(&run.metrics()),
    };
    if !draw {
        return Ok(None);
    }
    let label: Vec<String> = keys
        .iter()
        .zip(&case.values)
        .map(|(k, v)| format!("{}={v}", k.rsplit('.').next().unwrap_or(k)))
        .collect();
    let again;
    let series = if opts.case_plots == CasePlots::All {
        run
    } else {
        again = match run_scenario(&scenario.scenario, &scenario.text, opts.stop.as_ref(), true) {
            Ok(Some(r)) => r,
            Ok(None) => return Err(()),
            Err(e) => return Ok(Some(e.to_string())),
        };
        &again
    };
    Ok(plots::draw_case(&series.trace, &series.summary, &label.join(", "), dir).err())
}

/// Run one case into `cases/.tmp-<id>` and rename it to `cases/<id>`.
fn run_case(
    case: &Case,
    base: &Base,
    opts: &SweepOptions,
    cases_dir: &Path,
    keys: &[String],
    inner_jobs: usize,
) -> Result<Outcome, StudyError> {
    // Read again (it was checked when the grid was built; only the hash was kept).
    let scenario = load(&base.text, &base.file, &base.dir, &case.sets)
        .map_err(|e| StudyError::Scenario(format!("case {}: {e}", case.index)))?;
    let tmp = cases_dir.join(format!(".tmp-{}", case.id));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| io_err(&tmp, e))?;
    let interrupted = || {
        let _ = std::fs::remove_dir_all(&tmp);
        Ok(Outcome::Interrupted)
    };
    let scenario_file = opts.scenario.display().to_string();
    let (metrics, window, warnings, plot_error, command) = match &opts.window {
        Some(w) => {
            let Some(result) = super::window::search(
                &base.text,
                &base.file,
                &base.dir,
                &case.sets,
                w,
                inner_jobs,
                opts.stop.as_ref(),
                None,
            )?
            else {
                return interrupted();
            };
            let command = super::window::command_line(&scenario_file, &case.sets, w);
            (None, Some(Box::new(result)), Vec::new(), None, command)
        }
        None => {
            let series = opts.case_plots == CasePlots::All;
            let Some(run) = run_scenario(
                &scenario.scenario,
                &scenario.text,
                opts.stop.as_ref(),
                series,
            )?
            else {
                return interrupted();
            };
            // On one line: the same JSON as `gripsim run --summary` writes, in a third less
            // space (one file-system block for a one-prong case).
            let mut text = serde_json::to_string(&run.summary).expect("serialises");
            text.push('\n');
            write_atomic(&tmp.join("summary.json"), text.as_bytes())?;
            let Ok(plot_error) = case_figures(case, &scenario, &run, opts, keys, &tmp) else {
                return interrupted();
            };
            let command = command_line(&scenario_file, &case.sets);
            (
                Some(run.metrics()),
                None,
                run.trace.warnings.clone(),
                plot_error,
                command,
            )
        }
    };
    let sc_path = tmp.join("scenario.toml");
    std::fs::write(&sc_path, scenario.text.as_bytes()).map_err(|e| io_err(&sc_path, e))?;
    let rec = CaseRecord {
        format: FORMAT,
        id: case.id.clone(),
        parameters: keys
            .iter()
            .cloned()
            .zip(case.values.iter().cloned())
            .collect(),
        sets: case.sets.clone(),
        scenario_hash: case.hash.clone(),
        gripsim_version: env!("CARGO_PKG_VERSION").to_string(),
        command,
        metrics,
        window,
        warnings,
        plot_error,
    };
    // The marker goes in last, then the folder appears in one rename.
    write_json(&tmp.join("case.json"), &rec)?;
    let dest = cases_dir.join(&case.id);
    if dest.exists() {
        std::fs::remove_dir_all(&dest).map_err(|e| io_err(&dest, e))?;
    }
    std::fs::rename(&tmp, &dest).map_err(|e| io_err(&dest, e))?;
    Ok(Outcome::Done(Box::new(rec)))
}

/// The scenario's text, read once (a pipe or FIFO too: `<(…)`), at most 16 MiB.
fn read_scenario(path: &Path) -> Result<String, StudyError> {
    let text = crate::scenario::read_capped(path)
        .map_err(|e| io_err(path, format!("cannot read the scenario: {e}")))?;
    if text.len() as u64 > crate::scenario::MAX_SCENARIO_BYTES {
        return Err(io_err(
            path,
            format!(
                "larger than {} MiB: not a scenario file",
                crate::scenario::MAX_SCENARIO_BYTES >> 20
            ),
        ));
    }
    String::from_utf8(text).map_err(|_| io_err(path, "not UTF-8 text"))
}

/// A folder a sweep (or a merge) may write its table into: one that holds no `summary.csv` or
/// `summary.md` of its own, i.e. either none or a sweep folder's (`sweep.json` beside them).
fn claim_folder(out: &Path) -> Result<(), StudyError> {
    if out.join("sweep.json").exists() {
        return Ok(());
    }
    for name in ["summary.csv", "summary.md"] {
        let p = out.join(name);
        if std::fs::symlink_metadata(&p).is_ok() {
            return Err(StudyError::Usage(format!(
                "--out {}: it holds a {name} that no sweep wrote (no sweep.json beside it), \
                 which the sweep would replace: give another folder, or move {} away",
                out.display(),
                p.display()
            )));
        }
    }
    Ok(())
}

/// The files and folders a sweep writes in `out`, checked against its inputs (the scenario
/// and the files it names) and each other before anything is written
/// ([`crate::record::OutputPlan`]).
fn check_outputs(opts: &SweepOptions, text: &str) -> Result<(), StudyError> {
    let out = &opts.out;
    let mut plan = crate::record::OutputPlan::new();
    plan.scenario(&opts.scenario, text, &opts.sets);
    for name in ["sweep.json", "summary.csv", "summary.md"] {
        plan.output("--out", &out.join(name));
    }
    if let Some(s) = opts.shard {
        plan.output(
            "--out",
            &out.join(format!("summary.shard-{}-of-{}.csv", s.index, s.count)),
        );
    }
    plan.folder("--out", &out.join("cases"))
        .folder("--out", &out.join("plots"));
    plan.check().map_err(StudyError::Usage)?;
    claim_folder(out)
}

/// The progress line of a finished case, and whether it is worth a line under the progress
/// bar (an error or a warning).
fn case_line(rec: &CaseRecord, ran: usize, total: usize) -> (String, bool) {
    if let Some(w) = &rec.window {
        return (
            format!("[{ran}/{total}] {}: {}", rec.id, w.one_line()),
            false,
        );
    }
    let Some(m) = &rec.metrics else {
        return (format!("[{ran}/{total}] {}", rec.id), false);
    };
    // A 3D run has a grasp verdict where a planar one has its impulse-consistent force.
    let second = if m.dimension == 3 {
        m.verdict
            .as_ref()
            .map(|v| format!(", grasp {v}"))
            .unwrap_or_default()
    } else {
        format!(
            ", impulse-consistent {:.4} N{}",
            m.peak_impulse_consistent_force_n,
            m.peak_impulse_consistent_node
                .map(|n| format!(" at node {n}"))
                .unwrap_or_default()
        )
    };
    let line = format!(
        "[{}/{}] {} {} in {:.2} s: peak eq. 2 (seed) {:.4} N{}{}{}{}",
        ran,
        total,
        rec.id,
        if m.completed { "done" } else { "FAILED" },
        m.wall_time_s,
        m.peak_reaction_n,
        m.peak_reaction_node
            .map(|n| format!(" at node {n}"))
            .unwrap_or_default(),
        second,
        if m.warnings > 0 {
            format!("; warning: {}", rec.warnings[0])
        } else {
            String::new()
        },
        m.error
            .as_ref()
            .map(|e| format!("; error: {e}"))
            .unwrap_or_default(),
    );
    (line, !m.completed || m.warnings > 0)
}

/// Run (or resume) a sweep. Without `--shard` the summary table and plots are written when
/// every case is done.
pub fn run_sweep(opts: &SweepOptions) -> Result<SweepReport, StudyError> {
    let start = Instant::now();
    let jobs = if opts.jobs == 0 {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    } else {
        opts.jobs
    };
    let text = read_scenario(&opts.scenario)?;
    check_outputs(opts, &text)?;
    let Some((base, cases)) = build_cases(opts, jobs, text)? else {
        // Stopped while the grid was checked: nothing was written.
        return Ok(SweepReport {
            cases: grid_size(&opts.vary)?,
            in_shard: 0,
            interrupted: true,
            wall_time_s: start.elapsed().as_secs_f64(),
            ..Default::default()
        });
    };
    let keys: Vec<String> = opts.vary.iter().map(|v| v.key.clone()).collect();
    let manifest = Manifest {
        format: FORMAT,
        scenario: opts.scenario.display().to_string(),
        sets: opts.sets.clone(),
        vary: opts.vary.clone(),
        rods: base.rods.clone(),
        cases: cases
            .iter()
            .map(|c| CaseEntry {
                id: c.id.clone(),
                values: c.values.clone(),
                scenario_hash: c.hash.clone(),
            })
            .collect(),
        window: opts.window.clone(),
    };
    let mpath = opts.out.join("sweep.json");
    let old: Option<Manifest> = read_json(&mpath).ok().flatten();
    if let Some(o) = &old {
        if o.window.is_some() != manifest.window.is_some() {
            let (has, wants) = if o.window.is_some() {
                ("a window map (gripsim window --vary)", "a sweep")
            } else {
                ("a sweep (gripsim sweep)", "a window map")
            };
            return Err(StudyError::Mismatch(format!(
                "{} holds {has}, not {wants}: use another --out",
                opts.out.display()
            )));
        }
    }
    let cases_dir = opts.out.join("cases");
    std::fs::create_dir_all(&cases_dir).map_err(|e| io_err(&cases_dir, e))?;

    // Which cases of this shard are finished already.
    let mut records: Vec<Option<CaseRecord>> = vec![None; cases.len()];
    let mut todo: Vec<&Case> = Vec::new();
    let mine: Vec<&Case> = cases
        .iter()
        .filter(|c| opts.shard.is_none_or(|s| s.contains(c.index)))
        .collect();
    for c in &mine {
        match finished(&cases_dir, &c.id, &c.hash, opts.window.is_some())? {
            Some(r) => records[c.index] = Some(r),
            None => todo.push(c),
        }
    }
    // Shards sharing a folder write the same manifest; only a changed grid rewrites it.
    if old.as_ref() != Some(&manifest) {
        write_json(&mpath, &manifest)?;
    }

    let mut report = SweepReport {
        cases: cases.len(),
        in_shard: mine.len(),
        skipped: mine.len() - todo.len(),
        ..Default::default()
    };
    let stopped = || opts.stop.as_ref().is_some_and(|s| s());
    if !todo.is_empty() {
        let all = jobs;
        let jobs = jobs.min(todo.len()).max(1);
        // A window map with fewer designs than cores runs each design's searches in parallel.
        let inner_jobs = (all / jobs).max(1);
        let bar = if opts.quiet {
            indicatif::ProgressBar::hidden()
        } else {
            let b = indicatif::ProgressBar::new(todo.len() as u64);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:32} {pos}/{len} cases  {elapsed_precise} (eta {eta})  {msg}",
                )
                .expect("valid template"),
            );
            b
        };
        let lines = !opts.quiet && (bar.is_hidden() || !std::io::stderr().is_terminal());
        let next = AtomicUsize::new(0);
        let halted = AtomicBool::new(false);
        let (tx, rx) = mpsc::channel::<(usize, Result<Outcome, StudyError>)>();
        let mut first_error: Option<StudyError> = None;
        std::thread::scope(|s| {
            for _ in 0..jobs {
                let tx = tx.clone();
                let (todo, next, halted, cases_dir, keys, base) =
                    (&todo, &next, &halted, &cases_dir, &keys, &base);
                s.spawn(move || loop {
                    if halted.load(Ordering::Relaxed) || stopped() {
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(case) = todo.get(k) else { break };
                    let r = run_case(case, base, opts, cases_dir, keys, inner_jobs);
                    if r.is_err() {
                        halted.store(true, Ordering::Relaxed);
                    }
                    if tx.send((case.index, r)).is_err() {
                        break;
                    }
                });
            }
            drop(tx);
            for (index, r) in rx {
                match r {
                    Ok(Outcome::Done(rec)) => {
                        report.ran += 1;
                        let (line, notable) = case_line(&rec, report.ran, todo.len());
                        if let Some(m) = &rec.metrics {
                            if !m.completed {
                                report.failed += 1;
                            }
                            if m.warnings > 0 {
                                report.warned += 1;
                            }
                        }
                        if let Some(e) = &rec.plot_error {
                            if !report.plot_errors.contains(e) {
                                bar.println(format!(
                                    "warning: case {}: figures not drawn: {e}",
                                    rec.id
                                ));
                                report.plot_errors.push(e.clone());
                            }
                        }
                        if lines {
                            eprintln!("{line}");
                        } else if notable {
                            bar.println(line);
                        }
                        bar.set_message(rec.id.clone());
                        bar.inc(1);
                        records[index] = Some(*rec);
                    }
                    Ok(Outcome::Interrupted) => report.interrupted = true,
                    Err(e) => {
                        if first_error.is_none() {
                            first_error = Some(e);
                        }
                    }
                }
            }
        });
        bar.finish_and_clear();
        if let Some(e) = first_error {
            return Err(e);
        }
        if report.ran + report.skipped < mine.len() {
            report.interrupted = true;
            report.wall_time_s = start.elapsed().as_secs_f64();
            return Ok(report);
        }
    }

    let rows: Vec<&CaseRecord> = mine
        .iter()
        .map(|c| {
            records[c.index]
                .as_ref()
                .expect("every case of the shard is done")
        })
        .collect();
    match opts.shard {
        Some(s) => {
            let stem = if manifest.window.is_some() {
                "window"
            } else {
                "summary"
            };
            let path = opts
                .out
                .join(format!("{stem}.shard-{}-of-{}.csv", s.index, s.count));
            let idx: Vec<usize> = mine.iter().map(|c| c.index).collect();
            let csv = match manifest.window {
                Some(_) => super::window::map_csv(&manifest, &idx, &rows),
                None => summary_csv(&manifest, &idx, &rows),
            };
            write_if_changed(&path, csv.as_bytes())?;
            report.summary = Some(path);
        }
        None => {
            let (path, errs) = finalize(&opts.out, &manifest, &rows, opts.plots)?;
            report.summary = Some(path);
            for e in errs {
                if !report.plot_errors.contains(&e) {
                    report.plot_errors.push(e);
                }
            }
        }
    }
    report.wall_time_s = start.elapsed().as_secs_f64();
    Ok(report)
}

/// `summary.csv`, `summary.md` and the sweep figures, for a complete grid (a window map:
/// `window.csv`, `window.json` and its picture).
fn finalize(
    out: &Path,
    manifest: &Manifest,
    records: &[&CaseRecord],
    plots: bool,
) -> Result<(PathBuf, Vec<String>), StudyError> {
    if manifest.window.is_some() {
        return super::window::finalize_map(out, manifest, records, plots);
    }
    let idx: Vec<usize> = (0..records.len()).collect();
    let csv = summary_csv(manifest, &idx, records);
    let path = out.join("summary.csv");
    let changed = write_if_changed(&path, csv.as_bytes())?;
    write_if_changed(
        &out.join("summary.md"),
        summary_md(manifest, records).as_bytes(),
    )?;
    let mut errors = Vec::new();
    if plots {
        let dir = out.join("plots");
        let missing = plots::sweep_figures(manifest)
            .iter()
            .any(|f| !dir.join(format!("{f}.png")).exists());
        if changed || missing {
            if let Err(e) = plots::draw_sweep(manifest, records, &dir) {
                errors.push(e);
            }
        }
    }
    Ok((path, errors))
}

pub(crate) fn opt<T: std::fmt::Display>(v: &Option<T>) -> String {
    v.as_ref().map(|x| x.to_string()).unwrap_or_default()
}

/// Floats as Rust's shortest round-trip text: parsing a cell gives back the exact f64.
pub(crate) fn num(v: f64) -> String {
    format!("{v:?}")
}

fn csv_header(manifest: &Manifest) -> Vec<String> {
    let multi = manifest.rods.len() > 1;
    let mut h: Vec<String> = vec!["case".into(), "id".into()];
    h.extend(manifest.vary.iter().map(|v| v.key.clone()));
    h.extend(["completed", "steps", "simulated_time_s", "peak_reaction_n"].map(String::from));
    if multi {
        h.push("peak_reaction_rod".into());
    }
    h.extend(
        [
            "peak_reaction_node",
            "peak_reaction_time_s",
            "peak_impulse_consistent_force_n",
        ]
        .map(String::from),
    );
    if multi {
        h.push("peak_impulse_consistent_rod".into());
    }
    h.push("peak_impulse_consistent_node".into());
    h.extend(
        manifest
            .rods
            .iter()
            .map(|r| format!("total_impulse_ns:{r}")),
    );
    if multi {
        h.push("most_contact_steps_rod".into());
    }
    h.extend(
        [
            "most_contact_steps_node",
            "most_contact_steps",
            "contact_onset_s",
        ]
        .map(String::from),
    );
    if multi {
        h.push("first_contact_rod".into());
    }
    h.extend(["first_contact_node", "max_bending_stress_pa"].map(String::from));
    if multi {
        h.push("max_bending_stress_rod".into());
    }
    h.push("max_bending_stress_node".into());
    h.extend(
        manifest
            .rods
            .iter()
            .map(|r| format!("max_tip_deflection_m:{r}")),
    );
    h.extend(
        [
            "max_penetration_m",
            "releases",
            "warnings",
            "spikes",
            "sticking",
            "verdict",
            "held",
            "dropped",
            "peak_grip_force_n",
            "min_safety_margin",
            "max_slip_m",
            "first_slip_s",
            "peak_contact_force_n",
            "max_pressure_pa",
            "max_indentation_m",
            "bruised",
            "bruise_ratio",
            "max_bruise_width_m",
            "bruise",
            "error",
            "wall_time_s",
        ]
        .map(String::from),
    );
    h
}

/// A case's number for the manifest's rod `k` (its column), matched by the rod's name (by
/// position in records without names); None when the case has no such rod.
fn per_rod(manifest: &Manifest, m: &Metrics, values: &[f64], k: usize) -> Option<f64> {
    if m.rod_names.is_empty() {
        return values.get(k).copied();
    }
    let name = manifest.rods.get(k)?;
    let at = m.rod_names.iter().position(|n| n == name)?;
    values.get(at).copied()
}

fn csv_row(manifest: &Manifest, index: usize, r: &CaseRecord) -> Vec<String> {
    let multi = manifest.rods.len() > 1;
    let m = r.run_metrics();
    // What a 3D run does not measure is an empty cell, not a 0.
    let measured = |v: f64| {
        if m.dimension == 3 {
            String::new()
        } else {
            num(v)
        }
    };
    let mut row = vec![index.to_string(), r.id.clone()];
    row.extend(r.parameters.iter().map(|p| p.1.clone()));
    row.extend([
        m.completed.to_string(),
        m.steps.to_string(),
        num(m.simulated_time_s),
        num(m.peak_reaction_n),
    ]);
    if multi {
        row.push(opt(&m.peak_reaction_rod));
    }
    row.extend([
        opt(&m.peak_reaction_node),
        m.peak_reaction_time_s.map(num).unwrap_or_default(),
        measured(m.peak_impulse_consistent_force_n),
    ]);
    if multi {
        row.push(opt(&m.peak_impulse_consistent_rod));
    }
    row.push(opt(&m.peak_impulse_consistent_node));
    row.extend((0..manifest.rods.len()).map(|k| {
        per_rod(manifest, m, &m.total_impulse_per_rod_ns, k)
            .map(num)
            .unwrap_or_default()
    }));
    if multi {
        row.push(opt(&m.most_contact_steps_rod));
    }
    row.extend([
        opt(&m.most_contact_steps_node),
        m.most_contact_steps.to_string(),
        m.contact_onset_s.map(num).unwrap_or_default(),
    ]);
    if multi {
        row.push(opt(&m.first_contact_rod));
    }
    row.extend([
        opt(&m.first_contact_node),
        measured(m.max_bending_stress_pa),
    ]);
    if multi {
        row.push(opt(&m.max_bending_stress_rod));
    }
    row.push(opt(&m.max_bending_stress_node));
    row.extend((0..manifest.rods.len()).map(|k| {
        per_rod(manifest, m, &m.max_tip_deflection_per_rod_m, k)
            .map(num)
            .unwrap_or_default()
    }));
    row.extend([
        num(m.max_penetration_m),
        m.releases.to_string(),
        m.warnings.to_string(),
        m.spikes.to_string(),
        m.sticking.to_string(),
        opt(&m.verdict),
        opt(&m.held),
        opt(&m.dropped),
        m.peak_grip_force_n.map(num).unwrap_or_default(),
        m.min_safety_margin.map(num).unwrap_or_default(),
        m.max_slip_m.map(num).unwrap_or_default(),
        m.first_slip_s.map(num).unwrap_or_default(),
        m.peak_contact_force_n.map(num).unwrap_or_default(),
        m.max_pressure_pa.map(num).unwrap_or_default(),
        m.max_indentation_m.map(num).unwrap_or_default(),
        opt(&m.bruised),
        m.bruise_ratio.map(num).unwrap_or_default(),
        m.max_bruise_width_m.map(num).unwrap_or_default(),
        m.bruise.to_string(),
        opt(&m.error),
        num(m.wall_time_s),
    ]);
    row
}

/// One row per case in grid order; `indices` are the cases' grid indices.
fn summary_csv(manifest: &Manifest, indices: &[usize], records: &[&CaseRecord]) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(csv_header(manifest)).expect("in memory");
    for (i, r) in indices.iter().zip(records) {
        w.write_record(csv_row(manifest, *i, r)).expect("in memory");
    }
    String::from_utf8(w.into_inner().expect("in memory")).expect("UTF-8")
}

fn fmt_g(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if (1e-2..1e5).contains(&v.abs()) {
        format!("{:.4}", v)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.3e}")
    }
}

/// A Markdown table of the main metrics (0-based nodes).
fn summary_md(manifest: &Manifest, records: &[&CaseRecord]) -> String {
    let multi = manifest.rods.len() > 1;
    let node = |rod: &Option<String>, n: &Option<usize>| match (rod, n) {
        (Some(r), Some(n)) if multi => format!("{r} {n}"),
        (_, Some(n)) => n.to_string(),
        _ => "–".into(),
    };
    let mut s = String::from("| case |");
    for v in &manifest.vary {
        s.push_str(&format!(" `{}` |", v.key));
    }
    s.push_str(
        " peak eq. 2 reaction (N) | node | peak impulse-consistent force (N) | node | most contact steps: node | \
         contact onset (s) | first node | max bending stress (Pa) | node | max tip deflection (mm) | max penetration (m) | releases | warnings | grasp |\n|---|",
    );
    for _ in &manifest.vary {
        s.push_str("---|");
    }
    s.push_str("---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (i, r) in records.iter().enumerate() {
        let m = r.run_metrics();
        s.push_str(&format!("| {i} |"));
        for p in &r.parameters {
            s.push_str(&format!(" {} |", p.1));
        }
        let tip = m
            .max_tip_deflection_per_rod_m
            .iter()
            .cloned()
            .fold(0.0, f64::max);
        // What a 3D run does not measure: "–", not 0.
        let measured = |v: f64| {
            if m.dimension == 3 {
                "–".to_string()
            } else {
                fmt_g(v)
            }
        };
        s.push_str(&format!(
            " {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            fmt_g(m.peak_reaction_n),
            node(&m.peak_reaction_rod, &m.peak_reaction_node),
            measured(m.peak_impulse_consistent_force_n),
            node(
                &m.peak_impulse_consistent_rod,
                &m.peak_impulse_consistent_node
            ),
            match m.most_contact_steps_node {
                Some(_) => format!(
                    "{} ({})",
                    node(&m.most_contact_steps_rod, &m.most_contact_steps_node),
                    m.most_contact_steps
                ),
                None => "–".into(),
            },
            m.contact_onset_s
                .map(|t| format!("{t:.5}"))
                .unwrap_or_else(|| "none".into()),
            node(&m.first_contact_rod, &m.first_contact_node),
            measured(m.max_bending_stress_pa),
            node(&m.max_bending_stress_rod, &m.max_bending_stress_node),
            fmt_g(tip * 1e3),
            fmt_g(m.max_penetration_m),
            m.releases,
            if m.completed {
                m.warnings.to_string()
            } else {
                format!("{} (stopped: {})", m.warnings, opt(&m.error))
            },
            m.verdict.as_deref().unwrap_or("–"),
        ));
    }
    s
}

/// What `gripsim sweep merge` was asked to do.
#[derive(Debug, Clone)]
pub struct MergeOptions {
    /// Sweep folders (shards) of one sweep.
    pub dirs: Vec<PathBuf>,
    /// Where the merged sweep goes [default: the first folder].
    pub out: Option<PathBuf>,
    pub plots: bool,
}

#[derive(Debug, Clone)]
pub struct MergeReport {
    pub cases: usize,
    /// Case folders copied into the output folder.
    pub copied: usize,
    pub out: PathBuf,
    pub summary: PathBuf,
    pub plot_errors: Vec<String>,
}

fn copy_dir(from: &Path, to: &Path) -> Result<(), StudyError> {
    std::fs::create_dir_all(to).map_err(|e| io_err(to, e))?;
    for e in std::fs::read_dir(from).map_err(|e| io_err(from, e))? {
        let e = e.map_err(|e| io_err(from, e))?;
        let p = e.path();
        let dest = to.join(e.file_name());
        if p.is_dir() {
            copy_dir(&p, &dest)?;
        } else {
            std::fs::copy(&p, &dest).map_err(|e| io_err(&p, e))?;
        }
    }
    Ok(())
}

/// Join the case folders of shards into one sweep folder and write its summary and plots.
pub fn merge(opts: &MergeOptions) -> Result<MergeReport, StudyError> {
    let Some(first) = opts.dirs.first() else {
        return Err(StudyError::Usage(
            "sweep merge needs at least one sweep folder".into(),
        ));
    };
    let out = opts.out.clone().unwrap_or_else(|| first.clone());
    let mut manifest: Option<Manifest> = None;
    for d in &opts.dirs {
        let path = d.join("sweep.json");
        let m: Manifest = read_json(&path)?.ok_or_else(|| {
            io_err(
                &path,
                "not found: is this a sweep folder (gripsim sweep --out)?",
            )
        })?;
        match &manifest {
            None => manifest = Some(m),
            Some(m0) if !m0.same_grid(&m) => {
                return Err(StudyError::Mismatch(format!(
                    "{} and {} hold different sweeps (other --vary values, scenario or --set)",
                    first.display(),
                    d.display()
                )));
            }
            Some(_) => {}
        }
    }
    let manifest = manifest.expect("at least one folder");
    claim_folder(&out)?;
    let windowed = manifest.window.is_some();
    let out_cases = out.join("cases");
    std::fs::create_dir_all(&out_cases).map_err(|e| io_err(&out_cases, e))?;
    let mut records = Vec::with_capacity(manifest.cases.len());
    let mut copied = 0;
    let mut missing = Vec::new();
    for c in &manifest.cases {
        if let Some(r) = finished(&out_cases, &c.id, &c.scenario_hash, windowed)? {
            records.push(r);
            continue;
        }
        let mut found = None;
        for d in &opts.dirs {
            let cd = d.join("cases");
            if cd == out_cases {
                continue;
            }
            if let Some(r) = finished(&cd, &c.id, &c.scenario_hash, windowed)? {
                found = Some((cd.join(&c.id), r));
                break;
            }
        }
        match found {
            Some((src, r)) => {
                let tmp = out_cases.join(format!(".tmp-{}", c.id));
                let _ = std::fs::remove_dir_all(&tmp);
                copy_dir(&src, &tmp)?;
                let dest = out_cases.join(&c.id);
                if dest.exists() {
                    std::fs::remove_dir_all(&dest).map_err(|e| io_err(&dest, e))?;
                }
                std::fs::rename(&tmp, &dest).map_err(|e| io_err(&dest, e))?;
                copied += 1;
                records.push(r);
            }
            None => missing.push(c.id.clone()),
        }
    }
    if !missing.is_empty() {
        let n = manifest.cases.len();
        let shown: Vec<&str> = missing.iter().take(5).map(String::as_str).collect();
        return Err(StudyError::Incomplete(format!(
            "{} of {n} cases are not finished in any folder ({}{}); run the missing shards (or the sweep without --shard on {}) first",
            missing.len(),
            shown.join(", "),
            if missing.len() > 5 { ", …" } else { "" },
            out.display()
        )));
    }
    let mpath = out.join("sweep.json");
    let old: Option<Manifest> = read_json(&mpath).ok().flatten();
    if old.as_ref() != Some(&manifest) {
        write_json(&mpath, &manifest)?;
    }
    let refs: Vec<&CaseRecord> = records.iter().collect();
    let (summary, plot_errors) = finalize(&out, &manifest, &refs, opts.plots)?;
    Ok(MergeReport {
        cases: manifest.cases.len(),
        copied,
        out,
        summary,
        plot_errors,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_order_is_row_major() {
        let v = vec![
            Vary {
                key: "a".into(),
                values: vec!["1".into(), "2".into()],
            },
            Vary {
                key: "b".into(),
                values: vec!["x".into(), "y".into(), "z".into()],
            },
        ];
        assert_eq!(grid_size(&v).unwrap(), 6);
        assert_eq!(grid_values(&v, 0), ["1", "x"]);
        assert_eq!(grid_values(&v, 1), ["1", "y"]);
        assert_eq!(grid_values(&v, 3), ["2", "x"]);
        assert_eq!(grid_values(&v, 5), ["2", "z"]);
    }

    #[test]
    fn a_grid_over_the_cap_is_refused_before_it_is_built() {
        let big = Vary {
            key: "a".into(),
            values: (0..1000).map(|i| i.to_string()).collect(),
        };
        let v = vec![big.clone(), big.clone(), big];
        let e = grid_size(&v).unwrap_err().to_string();
        assert!(e.contains("1000 x 1000 x 1000 = 1.000e9 cases"), "{e}");
        assert!(e.contains(&MAX_CASES.to_string()), "{e}");
    }

    #[test]
    fn shell_quoting() {
        assert_eq!(shell_quote("rod.0.E=1e9"), "rod.0.E=1e9");
        assert_eq!(
            shell_quote("rod.0.drive.acceleration=[-9.8, 0]"),
            "'rod.0.drive.acceleration=[-9.8, 0]'"
        );
    }
}
