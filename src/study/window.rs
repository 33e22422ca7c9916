//! The grasp window (`gripsim window`, docs/studies.md "Grasp window"): along one knob g — by
//! default the grip target of the squeeze, the `grip_force` (or `grip_torque`) end of the first
//! phase that has one — the smallest g at which the fruit is held through the lift (g_hold,
//! the drop boundary, from the run summary's `grasp.held`) and the smallest g at which it
//! bruises (g_bruise, from `contact_pressure.bruised`), each to a relative tolerance.
//!
//! Each evaluation is a run of the scenario with `KNOB=g` (the sweep's run of a case, no
//! recordings); the same g is never run twice. The search:
//!
//! 1. a coarse grid, log-spaced over the range (which also shows outcomes that are not
//!    monotone: those are reported with where, never bisected across);
//! 2. per boundary, the bracket of the grid's one change of verdict is shrunk in log g by a
//!    regula falsi (Illinois) on a continuous indicator — ln of the safety margin at the lift
//!    against ln(1 + a/g), the margin a lift with peak acceleration a needs; ln(p₀/p_bruise)
//!    against 0 — while the verdict (held, bruised) alone decides which end moves. Once two
//!    estimates agree, two runs straddle the estimate by ±0.45 rtol, so that one round closes
//!    the bracket; a bracket that does not halve in two rounds is bisected. Both boundaries'
//!    runs of a round run in parallel.
//!
//! A 3D scenario's grip target is the first squeeze move's `force` (`move.<j>.force`); see
//! [`grip_target`]. Planar and 3D scenarios are read and run through [`crate::run`].
//!
//! A boundary is the verdict's side of its final bracket: g_hold is a value at which the fruit
//! was held, and a value 1 + rtol below it was not.

use super::sweep::{self, run_scenario, CaseRecord, Manifest};
use super::{io_err, StudyError};
use crate::actuation::{Movement, VectorLaw};
use crate::run::AnyScenario;
use crate::Scenario;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

/// Polled between steps; true stops the search (nothing is written).
pub type Stop = Arc<dyn Fn() -> bool + Send + Sync>;

/// What `gripsim window` was asked to search.
#[derive(Debug, Clone)]
pub struct WindowSpec {
    /// A numeric scenario key (the `--set` grammar); None: the squeeze's grip target.
    pub knob: Option<String>,
    /// `--range LO:HI`; None: the scenario's own value / 8 to × 8.
    pub range: Option<(f64, f64)>,
    pub rtol: f64,
}

/// The knob and the search settings, resolved against the scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resolved {
    /// The dotted key, e.g. `actuator.0.phase.0.end.grip_force`.
    pub knob: String,
    /// What it is, for people: "the grip_force end of phase 'close' of actuator 'gripper'".
    pub what: String,
    /// Its unit where known ("N", "N·m", "kg", …), else "".
    pub unit: String,
    /// Its value in the scenario (with the `--set` assignments applied).
    pub scenario_value: f64,
    pub lo: f64,
    pub hi: f64,
    /// False: the default range, the scenario's value / 8 to × 8.
    pub range_given: bool,
    pub rtol: f64,
}

impl Resolved {
    /// The settings a design's result depends on, as text (hashed with the design's scenario).
    pub fn canonical(&self) -> String {
        format!(
            "knob={} lo={:?} hi={:?} rtol={:?}",
            self.knob, self.lo, self.hi, self.rtol
        )
    }

    /// The knob in a design (its scenario `text`, every assignment applied, read from
    /// `file`): present and a number (a design may not drop it).
    pub fn check_design(&self, text: &str, file: &str) -> Result<(), StudyError> {
        knob_value(text, file, &self.knob).map(|_| ())
    }

    /// A value with the knob's unit: "1.8 N".
    pub fn show(&self, v: f64) -> String {
        if self.unit.is_empty() {
            fmt_g(v)
        } else {
            format!("{} {}", fmt_g(v), self.unit)
        }
    }

    fn range_text(&self) -> String {
        let u = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" {}", self.unit)
        };
        format!("{}–{}{u}", fmt_g(self.lo), fmt_g(self.hi))
    }
}

/// Four significant digits, no trailing zeros; scientific outside 1e-3..1e5.
pub fn fmt_g(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.3e}");
        return match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            _ => s,
        };
    }
    let digits = (3 - a.log10().floor() as i32).max(0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The knob's value as `--set` text: Rust's shortest round-trip form (a TOML float).
fn set_text(v: f64) -> String {
    format!("{v:?}")
}

/// `--range LO:HI`: two numbers, 0 < LO < HI (the search is in log knob).
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let hint = "expected LO:HI with 0 < LO < HI, e.g. --range 0.5:20";
    let Some((a, b)) = s.split_once(':') else {
        return Err(format!("--range {s:?}: {hint}"));
    };
    let (Ok(lo), Ok(hi)) = (a.trim().parse::<f64>(), b.trim().parse::<f64>()) else {
        return Err(format!("--range {s:?}: LO and HI must be numbers ({hint})"));
    };
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(format!("--range {s:?}: LO and HI must be finite ({hint})"));
    }
    if lo <= 0.0 {
        return Err(format!(
            "--range {s:?}: LO = {lo} but the search is in log(knob): LO must be > 0 ({hint})"
        ));
    }
    if lo >= hi {
        return Err(format!(
            "--range {s:?}: LO = {lo} is not below HI = {hi}: give LO < HI ({hint})"
        ));
    }
    Ok((lo, hi))
}

/// `--rtol`: a number in (0, 1).
pub fn parse_rtol(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(r) if r > 0.0 && r < 1.0 => Ok(r),
        Ok(r) => Err(format!(
            "--rtol {s:?}: {r} is not in (0, 1): the relative width of the final bracket, e.g. 0.01 for 1 %"
        )),
        Err(_) => Err(format!(
            "--rtol {s:?}: not a number (the relative width of the final bracket, e.g. 0.01 for 1 %)"
        )),
    }
}

/// The squeeze's grip target of a scenario of either dimension: (key, description, unit).
/// Planar: the first phase (actuators in order, then phases) whose end has `grip_force` or
/// `grip_torque`; 3D: the `force` of the first `[[move]] kind = "squeeze"`.
pub fn grip_target(sc: &AnyScenario) -> Option<(String, String, String)> {
    match sc {
        AnyScenario::Planar(sc) => grip_target2(sc),
        AnyScenario::Spatial(sc) => {
            let j = sc
                .moves
                .iter()
                .position(|m| matches!(m, crate::rod3d::gripper::Move3::Squeeze { .. }))?;
            Some((
                format!("move.{j}.force"),
                format!(
                    "the force of squeeze move {j}: the grip target each prong's sensor squeezes to"
                ),
                "N".to_string(),
            ))
        }
    }
}

fn grip_target2(sc: &Scenario) -> Option<(String, String, String)> {
    for (i, a) in sc.actuators.iter().enumerate() {
        for (j, ph) in a.program.phases.iter().enumerate() {
            let (name, unit) = if ph.end.grip_force.is_some() {
                ("grip_force", "N")
            } else if ph.end.grip_torque.is_some() {
                ("grip_torque", "N·m")
            } else {
                continue;
            };
            let key = format!("actuator.{i}.phase.{j}.end.{name}");
            let what = format!(
                "the {name} end of phase {} of actuator '{}': the grip target of the squeeze",
                ph.label(),
                a.name
            );
            return Some((key, what, unit.to_string()));
        }
    }
    None
}

/// The unit of a scenario key, where its last part says it.
pub fn unit_of(key: &str) -> String {
    let last = key.rsplit('.').next().unwrap_or(key);
    match last {
        "grip_force" => "N",
        "grip_torque" => "N·m",
        "mass" => "kg",
        "E" | "bruise_pressure" => "Pa",
        "radius" | "travel" | "width" | "distance" => "m",
        "duration" | "t_end" | "dt" => "s",
        "speed" | "max_speed" => "m/s",
        "acceleration" => "m/s²",
        _ => "",
    }
    .to_string()
}

/// The number at `key` in the scenario's text (its `--set` assignments applied), read from
/// `file`.
fn knob_value(text: &str, file: &str, key: &str) -> Result<f64, StudyError> {
    let not_in = |why: String| {
        StudyError::Usage(format!(
            "{file}: --knob {key}: {why} (the knob is a numeric key of the scenario, in the --set grammar, e.g. friction.pair.0.mu_s or actuator.0.phase.0.end.grip_force)"
        ))
    };
    let root: toml::Table = text
        .parse()
        .map_err(|e| not_in(format!("the scenario does not read back: {e}")))?;
    let mut cur = toml::Value::Table(root);
    let mut walked = String::new();
    for part in key.split('.') {
        let next = match &cur {
            toml::Value::Table(t) => t.get(part).cloned(),
            toml::Value::Array(a) => part.parse::<usize>().ok().and_then(|i| a.get(i).cloned()),
            _ => None,
        };
        let Some(next) = next else {
            let at = if walked.is_empty() {
                String::new()
            } else {
                format!(" (`{walked}` has no `{part}`)")
            };
            return Err(not_in(format!("not in the scenario{at}")));
        };
        if !walked.is_empty() {
            walked.push('.');
        }
        walked.push_str(part);
        cur = next;
    }
    match cur {
        toml::Value::Float(v) if v.is_finite() => Ok(v),
        toml::Value::Integer(v) => Ok(v as f64),
        other => Err(StudyError::Usage(format!(
            "{file}: --knob {key} = {}: not a number (the knob must be a numeric key)",
            crate::scenario::reader::show(&other)
        ))),
    }
}

/// Resolve `spec` against a scenario of either dimension (`sc.text` with every `--set`
/// assignment applied; its files relative to `dir`): the knob, its value, the range and the
/// tolerance, each checked; the scenario must read at both ends.
pub fn resolve(
    sc: &sweep::Loaded,
    file: &str,
    dir: &Path,
    spec: &WindowSpec,
) -> Result<Resolved, StudyError> {
    let (knob, what, unit) = match &spec.knob {
        Some(k) => (k.clone(), format!("--knob {k}"), unit_of(k)),
        None => grip_target(&sc.scenario).ok_or_else(|| {
            let none = match sc.scenario {
                AnyScenario::Planar(_) => "no phase of an [[actuator]] ends on grip_force or grip_torque",
                AnyScenario::Spatial(_) => "no [[move]] is a squeeze (kind = \"squeeze\", force = …)",
            };
            StudyError::Usage(format!(
                "{file}: {none}, so there is no grip target to vary: name the knob with --knob KEY (a numeric scenario key, e.g. --knob friction.pair.0.mu_s)"
            ))
        })?,
    };
    let value = knob_value(&sc.text, file, &knob)?;
    let (lo, hi, range_given) = match spec.range {
        Some((lo, hi)) => (lo, hi, true),
        None if value > 0.0 => (value / 8.0, value * 8.0, false),
        None => {
            return Err(StudyError::Usage(format!(
                "{file}: --knob {knob} is {value} in the scenario: the default range (value/8 to value*8) needs a value > 0; give --range LO:HI"
            )))
        }
    };
    parse_range(&format!("{lo:?}:{hi:?}")).map_err(StudyError::Usage)?;
    if !(spec.rtol > 0.0 && spec.rtol < 1.0) {
        parse_rtol(&spec.rtol.to_string()).map_err(StudyError::Usage)?;
    }
    for v in [lo, hi] {
        let set = format!("{knob}={}", set_text(v));
        sweep::load(&sc.text, file, dir, std::slice::from_ref(&set)).map_err(|e| {
            let range = if range_given {
                "--range".to_string()
            } else {
                format!(
                    "the default range {}:{} (the scenario's value / 8 to × 8; give --range LO:HI)",
                    fmt_g(lo),
                    fmt_g(hi)
                )
            };
            StudyError::Usage(format!(
                "{range}: the scenario does not read with {set}: {e}"
            ))
        })?;
    }
    Ok(Resolved {
        knob,
        what,
        unit,
        scenario_value: value,
        lo,
        hi,
        range_given,
        rtol: spec.rtol,
    })
}

/// The largest upward acceleration (m/s², against gravity) the hand imposes after its squeeze:
/// the lift's. 0 without gravity, and 0 in 3D (a 3D `lift` moves at constant speed).
pub fn lift_acceleration_any(sc: &AnyScenario) -> f64 {
    match sc {
        AnyScenario::Planar(sc) => lift_acceleration(sc),
        AnyScenario::Spatial(_) => 0.0,
    }
}

/// The largest upward acceleration (m/s², against gravity) the grippers' programs impose
/// after their squeeze (the phases after the first that ends on a grip target; every phase
/// of a program without one): the lift's. 0 without gravity.
pub fn lift_acceleration(sc: &Scenario) -> f64 {
    let g = sc.solve.gravity;
    let gn = g[0].hypot(g[1]);
    if gn == 0.0 {
        return 0.0;
    }
    let up = [-g[0] / gn, -g[1] / gn];
    let (programs, _) = crate::scenario::actuation::groups(sc);
    let mut a = 0.0f64;
    for p in &programs {
        let grip = p
            .phases
            .iter()
            .position(|ph| ph.end.grip_force.is_some() || ph.end.grip_torque.is_some());
        for ph in &p.phases[grip.map_or(0, |i| i + 1)..] {
            let up_a = match &ph.movement {
                Movement::Translate { direction, law } => {
                    let n = direction[0].hypot(direction[1]);
                    let along = if n > 0.0 {
                        (direction[0] * up[0] + direction[1] * up[1]) / n
                    } else {
                        0.0
                    };
                    law.peak_acceleration() * along.max(0.0)
                }
                Movement::TranslateVector {
                    law: VectorLaw::Acceleration(v),
                } => (v[0] * up[0] + v[1] * up[1]).max(0.0),
                _ => 0.0,
            };
            a = a.max(up_a);
        }
    }
    a
}

/// One run of the search: the knob's value and what the run summary says.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Eval {
    pub value: f64,
    pub completed: bool,
    pub error: Option<String>,
    /// The grasp of the first free body (null without one).
    pub held: Option<bool>,
    pub dropped: Option<bool>,
    pub lifted: Option<bool>,
    /// μ_s ΣN / (m g) when the lift began, and its minimum over the lift.
    pub safety_margin_at_lift: Option<f64>,
    pub min_safety_margin: Option<f64>,
    pub peak_grip_force_n: Option<f64>,
    pub max_slip_m: Option<f64>,
    /// A compliant fruit's contact (null when none was touched).
    pub bruised: Option<bool>,
    /// max p₀ / bruise pressure.
    pub bruise_ratio: Option<f64>,
    pub max_pressure_pa: Option<f64>,
    pub bruise_pressure_pa: Option<f64>,
    pub warnings: usize,
    pub steps: u64,
    pub wall_time_s: f64,
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

impl Eval {
    fn of(value: f64, run: &sweep::CaseRun) -> Eval {
        let s = &run.summary;
        let g = s.grasp.as_ref();
        let p = s.contact_pressure.as_ref();
        Eval {
            value,
            completed: s.completed,
            error: s.error.clone(),
            held: g.map(|g| g.held),
            dropped: g.map(|g| g.dropped),
            lifted: g.map(|g| g.lift_start_time_s.is_some()),
            safety_margin_at_lift: g.and_then(|g| g.safety_margin_at_lift).and_then(finite),
            min_safety_margin: g.and_then(|g| g.min_safety_margin).and_then(finite),
            peak_grip_force_n: g.map(|g| g.peak_grip_force_n).and_then(finite),
            max_slip_m: g.map(|g| g.max_slip_m).and_then(finite),
            bruised: p.map(|p| p.bruised),
            bruise_ratio: p.map(|p| p.bruise_ratio).and_then(finite),
            max_pressure_pa: p.map(|p| p.max_pressure_pa).and_then(finite),
            bruise_pressure_pa: p.map(|p| p.bruise_pressure_pa).and_then(finite),
            warnings: run.trace.warnings.len(),
            steps: s.steps,
            wall_time_s: s.wall_time_s,
        }
    }

    /// "held", "dropped", "slipped" (lifted, neither), "not lifted", "stopped: …"; ", bruised".
    pub fn outcome(&self) -> String {
        let grasp = match (self.held, self.dropped, self.lifted) {
            _ if !self.completed => format!(
                "stopped: {}",
                self.error.as_deref().unwrap_or("did not complete")
            ),
            (None, _, _) => String::new(),
            (Some(true), _, _) => "held".into(),
            (_, Some(true), _) => "dropped".into(),
            (_, _, Some(false)) => "not lifted".into(),
            _ => "slipped".into(),
        };
        let bruise = match self.bruised {
            Some(true) => "bruised",
            Some(false) => "not bruised",
            None => "",
        };
        match (grasp.is_empty(), bruise.is_empty()) {
            (false, false) => format!("{grasp}, {bruise}"),
            (false, true) => grasp,
            (true, false) => bruise.to_string(),
            (true, true) => "no grasp, no compliant contact".into(),
        }
    }
}

/// Which boundary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Which {
    /// The drop boundary: held or not.
    Hold,
    /// The bruise boundary: bruised or not.
    Bruise,
}

impl Which {
    fn verdict(self, e: &Eval) -> bool {
        match self {
            Which::Hold => e.held == Some(true),
            Which::Bruise => e.bruised == Some(true),
        }
    }

    /// The continuous indicator whose threshold the verdict follows (in logs).
    fn indicator(self, e: &Eval) -> Option<f64> {
        let v = match self {
            Which::Hold => e.safety_margin_at_lift,
            Which::Bruise => e.bruise_ratio,
        }?;
        (v > 0.0 && v.is_finite()).then(|| v.ln())
    }

    fn word(self) -> &'static str {
        match self {
            Which::Hold => "held",
            Which::Bruise => "bruised",
        }
    }
}

/// What became of one boundary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Bracketed to rtol: `value` has the outcome, `other` (rtol away) has not.
    Found,
    /// The outcome at every run (the boundary is below the range).
    Everywhere,
    /// The outcome at no run (the boundary is above the range, or there is none).
    Nowhere,
    /// The outcome changes more than once along the coarse grid: see `changes`.
    NotMonotone,
    /// No free body (no grasp verdict) or no compliant material (no bruise).
    NotApplicable,
}

/// One boundary of the window.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Boundary {
    pub which: Which,
    pub status: Status,
    /// The boundary: the knob value of the run at the outcome's side of the final bracket.
    pub value: Option<f64>,
    /// The bracket's other end (without the outcome).
    pub other: Option<f64>,
    /// True when the outcome holds above the boundary (the usual sense); false when below.
    pub rising: bool,
    /// Not monotone: each change of verdict along the coarse grid, (from value, to value,
    /// outcome at the second).
    pub changes: Vec<(f64, f64, bool)>,
    /// The run at `value`.
    pub at: Option<Eval>,
    /// The statement, e.g. "g_hold = 1.372 N" or "no bruise up to 14.4 N".
    pub note: String,
}

/// The result of one window search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WindowResult {
    pub scenario: String,
    pub knob: Resolved,
    /// The lift's peak upward acceleration (m/s²) and the margin μ_s ΣN/(m g) it needs, 1 + a/g.
    pub lift_acceleration_m_s2: f64,
    pub margin_needed: f64,
    pub hold: Boundary,
    pub bruise: Boundary,
    /// g_bruise / g_hold when both are found and rising (> 1: a safe window exists).
    pub window_ratio: Option<f64>,
    /// When a boundary lies outside the range: the ratio is at least this (e.g. held from
    /// g_hold and no bruise up to HI: HI / g_hold).
    pub window_ratio_at_least: Option<f64>,
    /// One sentence for people.
    pub headline: String,
    /// Every run, in the order run.
    pub runs: Vec<Eval>,
}

/// The coarse grid: log-spaced over [lo, hi], both ends included, about a factor 2.83 apart
/// (3 to 9 points); the scenario's own value is on it for the default range.
fn coarse_grid(r: &Resolved) -> Vec<f64> {
    let span = (r.hi / r.lo).ln();
    let n = ((span / 8f64.sqrt().ln()).round() as usize + 1).clamp(3, 9);
    (0..n)
        .map(|i| {
            if i == 0 {
                r.lo
            } else if i == n - 1 {
                r.hi
            } else {
                round_sig(r.lo * (span * i as f64 / (n - 1) as f64).exp(), r.rtol)
            }
        })
        .collect()
}

/// A knob value rounded to a few digits more than rtol needs (tables stay readable).
fn round_sig(v: f64, rtol: f64) -> f64 {
    let digits = ((-rtol.log10()).ceil() as usize + 4).max(6);
    format!("{v:.*e}", digits - 1).parse().unwrap_or(v)
}

/// The runs of one boundary's search and where its bracket stands.
struct Track {
    which: Which,
    /// ln of the indicator's threshold (ln(1 + a/g) for the hold; 0 for the bruise).
    threshold: f64,
    last_estimate: Option<f64>,
    /// How far the estimate moved at each round since the last bisection (ln).
    steps: Vec<f64>,
    /// Rounds in a row stepping in from an end that contradicts the threshold.
    reach: u32,
    /// The bracket's width (ln) at each round.
    widths: Vec<f64>,
    /// Per round: which end moved ('l', 'h', or 'b' for both / none).
    moved: Vec<char>,
    bracket: Option<(f64, f64)>,
}

/// Where a boundary stands on the sorted runs.
enum Bracket {
    Uniform(bool),
    /// Indices (i, i + 1) of the one change.
    At(usize, usize),
    /// Indices i of every change between i and i + 1.
    Changes(Vec<usize>),
}

fn bracket(which: Which, pts: &[&Eval]) -> Bracket {
    let changes = changes(which, pts);
    match changes.len() {
        0 => Bracket::Uniform(pts.first().is_some_and(|e| which.verdict(e))),
        1 => Bracket::At(changes[0], changes[0] + 1),
        // Not held (not bruised) at the low end, then held (bruised): the boundary is the
        // first change, the smallest value with the outcome; what comes above it (a fruit
        // squeezed out of the gripper, not held again) is reported, not bisected.
        _ if !which.verdict(pts[0]) => Bracket::At(changes[0], changes[0] + 1),
        _ => Bracket::Changes(changes),
    }
}

/// The runs a boundary is searched on (sorted). The bruise boundary that closes the window is
/// the least knob at which a fruit that can be held bruises: runs below the least held one (a
/// fruit that slips or drops and bruises as it lands on the table) cannot narrow a window they
/// lie outside of; `boundary` reports them.
fn scope<'a>(which: Which, pts: &[&'a Eval]) -> Vec<&'a Eval> {
    match pts.iter().position(|e| e.held == Some(true)) {
        Some(k) if which == Which::Bruise => pts[k..].to_vec(),
        _ => pts.to_vec(),
    }
}

/// Every i whose verdict differs from i + 1's, on the sorted runs.
fn changes(which: Which, pts: &[&Eval]) -> Vec<usize> {
    (0..pts.len().saturating_sub(1))
        .filter(|&i| which.verdict(pts[i]) != which.verdict(pts[i + 1]))
        .collect()
}

/// Where the next run of a boundary should go.
enum Guess {
    /// The indicator crosses its threshold here (ln knob).
    At(f64),
    /// A bracket's end whose run contradicts the threshold (a run not held with a margin
    /// above it, or held below it): the crossing lies just inside from that end (ln knob),
    /// in direction ±1.
    Past(f64, f64),
    /// Nothing to go by: bisect.
    Unknown,
}

impl Track {
    /// The next knob values (ln) to run for this boundary; empty when it is done.
    fn propose(&mut self, pts: &[&Eval], tau: f64) -> Vec<f64> {
        let pts = &scope(self.which, pts)[..];
        let Bracket::At(i, j) = bracket(self.which, pts) else {
            return Vec::new();
        };
        let (xl, xh) = (pts[i].value.ln(), pts[j].value.ln());
        let w = xh - xl;
        if w <= tau * (1.0 + 1e-9) {
            return Vec::new();
        }
        let mid = 0.5 * (xl + xh);
        if w <= 8.0 * tau {
            // Within 8 rtol bisection closes the bracket in at most three runs, one a round,
            // whatever the indicator does; a secant there may creep in from one side (an
            // indicator that jumps at the boundary, the squeeze ending on another contact
            // state) and a straddling pair costs two runs a round.
            return vec![mid];
        }
        let inside = |x: f64| x.clamp(xl + 0.9 * tau, xh - 0.9 * tau);
        // A bracket that has not halved in four rounds is stuck: bisect.
        let m = self.widths.len();
        let stuck = m >= 4 && w > 0.5 * self.widths[m - 4];
        self.widths.push(w);
        let guess = if stuck {
            Guess::Unknown
        } else {
            self.estimate(pts, i, j)
        };
        let e = match guess {
            Guess::At(e) => e,
            Guess::Past(end, dir) => {
                // From the contradicting end inwards by 0.9 rtol (which closes the bracket
                // if the crossing is that near), then 3 times further each round, at most to
                // the middle.
                self.last_estimate = None;
                self.steps.clear();
                self.reach += 1;
                let x = end + dir * 0.9 * tau * 3f64.powi(self.reach as i32 - 1);
                let x = if dir > 0.0 { x.min(mid) } else { x.max(mid) };
                return vec![inside(x)];
            }
            Guess::Unknown => {
                self.last_estimate = None;
                self.steps.clear();
                self.reach = 0;
                return vec![mid];
            }
        };
        self.reach = 0;
        // Brent's safeguard: an estimate that moves more than half as far as the one before
        // last is not converging: bisect.
        let step = self.last_estimate.map(|p| (e - p).abs());
        let n = self.steps.len();
        if step.is_some_and(|s| n >= 2 && s > 0.5 * self.steps[n - 2]) {
            self.last_estimate = None;
            self.steps.clear();
            return vec![mid];
        }
        self.steps.extend(step);
        let confident = step.is_some_and(|s| s <= 2.0 * tau);
        self.last_estimate = Some(e);
        if !confident {
            return vec![inside(e)];
        }
        // Straddle the estimate: if it is within 0.45 rtol, this round closes the bracket.
        let (a, b) = (e - 0.45 * tau, e + 0.45 * tau);
        if a <= xl + 0.05 * tau {
            vec![xl + 0.9 * tau]
        } else if b >= xh - 0.05 * tau {
            vec![xh - 0.9 * tau]
        } else {
            vec![a, b]
        }
    }

    /// Where the indicator crosses its threshold: the secant through the two runs nearest the
    /// crossing (the smallest |indicator − threshold| among the bracket's ends and their
    /// outer neighbours) when they lie on either side of it and it falls inside the bracket,
    /// else regula falsi between the ends with the stagnant end's value halved per repeat
    /// after the first (Illinois).
    fn estimate(&self, pts: &[&Eval], i: usize, j: usize) -> Guess {
        let (Some(yl), Some(yh)) = (self.which.indicator(pts[i]), self.which.indicator(pts[j]))
        else {
            return Guess::Unknown;
        };
        let (xl, xh) = (pts[i].value.ln(), pts[j].value.ln());
        let lo_true = self.which.verdict(pts[i]);
        let (yf, yt) = if lo_true { (yh, yl) } else { (yl, yh) };
        if yt <= yf {
            return Guess::Unknown;
        }
        let t = self.threshold;
        // The verdicts contradict the threshold: the crossing is just past the end that does.
        let (xf, xt) = if lo_true { (xh, xl) } else { (xl, xh) };
        if t <= yf {
            return Guess::Past(xf, (xt - xf).signum());
        }
        if t >= yt {
            return Guess::Past(xt, (xf - xt).signum());
        }
        let mut near: Vec<(f64, f64)> = [i.checked_sub(1), Some(i), Some(j), Some(j + 1)]
            .into_iter()
            .flatten()
            .filter_map(|k| pts.get(k))
            .filter_map(|e| Some((e.value.ln(), self.which.indicator(e)? - t)))
            .collect();
        near.sort_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
        if let [(x1, s1), (x2, s2), ..] = near[..] {
            // Only through two runs on either side of the threshold: two on one side
            // extrapolate, and where the indicator jumps at the boundary (the squeeze ending
            // on another contact state) each estimate creeps in from that side.
            if s1 != s2 && s1.signum() != s2.signum() {
                let r = x1 - s1 * (x2 - x1) / (s2 - s1);
                if r > xl && r < xh {
                    return Guess::At(r);
                }
            }
        }
        let (mut sl, mut sh) = (yl - t, yh - t);
        let last = self.moved.last().copied();
        let repeats = self
            .moved
            .iter()
            .rev()
            .take_while(|c| Some(**c) == last)
            .count();
        if repeats >= 2 {
            let f = 0.5f64.powi(repeats as i32 - 1);
            match last {
                Some('l') => sh *= f,
                Some('h') => sl *= f,
                _ => {}
            }
        }
        Guess::At(xl + (xh - xl) * sl / (sl - sh))
    }

    /// Record which end of the bracket the last round moved.
    fn update(&mut self, pts: &[&Eval]) {
        let pts = &scope(self.which, pts)[..];
        let now = match bracket(self.which, pts) {
            Bracket::At(i, j) => Some((pts[i].value, pts[j].value)),
            _ => None,
        };
        if let (Some(a), Some(b)) = (self.bracket, now) {
            self.moved.push(match (a.0 != b.0, a.1 != b.1) {
                (true, false) => 'l',
                (false, true) => 'h',
                _ => 'b',
            });
        }
        self.bracket = now;
    }
}

/// Runs the search has done, by value (never the same value twice).
struct Runs {
    order: Vec<Eval>,
}

impl Runs {
    fn has(&self, v: f64) -> bool {
        self.order.iter().any(|e| e.value.to_bits() == v.to_bits())
    }

    fn sorted(&self) -> Vec<&Eval> {
        let mut v: Vec<&Eval> = self.order.iter().collect();
        v.sort_by(|a, b| a.value.total_cmp(&b.value));
        v
    }
}

/// A run's result: its evaluation, None when stopped, or why it could not run.
type Outcome = Result<Option<Eval>, StudyError>;

/// What a search needs to run one value.
struct Ctx<'a> {
    text: &'a str,
    file: &'a str,
    dir: &'a Path,
    sets: &'a [String],
    knob: &'a str,
    stop: Option<&'a Stop>,
}

impl Ctx<'_> {
    fn run(&self, v: f64) -> Result<Option<Eval>, StudyError> {
        let mut sets = self.sets.to_vec();
        sets.push(format!("{}={}", self.knob, set_text(v)));
        let sc = sweep::load(self.text, self.file, self.dir, &sets)
            .map_err(|e| StudyError::Scenario(format!("{}={}: {e}", self.knob, set_text(v))))?;
        Ok(run_scenario(&sc.scenario, &sc.text, self.stop, false)?.map(|r| Eval::of(v, &r)))
    }

    /// Run the values on up to `jobs` threads; None when stopped.
    fn batch(
        &self,
        values: &[f64],
        jobs: usize,
        progress: Option<&Progress<'_>>,
    ) -> Result<Option<Vec<Eval>>, StudyError> {
        let n = values.len();
        let slots: Mutex<Vec<Option<Outcome>>> = Mutex::new((0..n).map(|_| None).collect());
        let next = AtomicUsize::new(0);
        let work = || loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            if k >= n || self.stop.is_some_and(|s| s()) {
                break;
            }
            let r = self.run(values[k]);
            if let (Some(p), Ok(Some(e))) = (progress, &r) {
                p(e);
            }
            slots.lock().unwrap_or_else(|e| e.into_inner())[k] = Some(r);
        };
        let workers = jobs.clamp(1, n.max(1));
        if workers == 1 {
            work();
        } else {
            std::thread::scope(|s| {
                for _ in 0..workers {
                    s.spawn(work);
                }
            });
        }
        let mut out = Vec::with_capacity(n);
        for slot in slots.into_inner().unwrap_or_else(|e| e.into_inner()) {
            match slot {
                Some(Ok(Some(e))) => out.push(e),
                Some(Err(e)) => return Err(e),
                _ => return Ok(None),
            }
        }
        Ok(Some(out))
    }
}

/// Called with each finished run (for progress lines).
pub type Progress<'a> = dyn Fn(&Eval) + Sync + 'a;

/// The most runs one search does (a safeguard; a search to rtol 1e-6 needs far fewer).
const MAX_RUNS: usize = 200;

/// What a window needs of a scenario of either dimension: whether it has a free fruit (a
/// hold boundary), a compliant one (a bruise boundary), and its gravity's magnitude.
fn fruit_of(sc: &AnyScenario) -> (bool, bool, f64) {
    match sc {
        AnyScenario::Planar(sc) => (
            !sc.bodies.is_empty(),
            sc.materials.iter().any(Option::is_some),
            sc.solve.gravity[0].hypot(sc.solve.gravity[1]),
        ),
        AnyScenario::Spatial(sc) => {
            let f = sc.fruit.as_ref();
            let g = sc.gravity;
            (
                f.is_some_and(|f| f.free),
                f.is_some_and(|f| f.material.is_some()),
                (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt(),
            )
        }
    }
}

/// Search the window of the scenario `text` (read from `file`; a 3D mesh relative to `dir`)
/// with `sets` applied. None when `stop` interrupted it.
#[allow(clippy::too_many_arguments)]
pub fn search(
    text: &str,
    file: &str,
    dir: &Path,
    sets: &[String],
    r: &Resolved,
    jobs: usize,
    stop: Option<&Stop>,
    progress: Option<&Progress<'_>>,
) -> Result<Option<WindowResult>, StudyError> {
    let sc = AnyScenario::parse(text, file, dir, sets)
        .map_err(|e| StudyError::Scenario(e.to_string()))?;
    let (free, compliant, g) = fruit_of(&sc);
    let lift = lift_acceleration_any(&sc);
    let margin_needed = if g > 0.0 { 1.0 + lift / g } else { 1.0 };
    let ctx = Ctx {
        text,
        file,
        dir,
        sets,
        knob: &r.knob,
        stop,
    };
    let tau = (1.0 + r.rtol).ln();
    let mut runs = Runs { order: Vec::new() };
    let mut tracks = Vec::new();
    if free {
        tracks.push(new_track(Which::Hold, margin_needed.ln()));
    }
    if compliant {
        tracks.push(new_track(Which::Bruise, 0.0));
    }
    let mut next = coarse_grid(r);
    while !next.is_empty() && runs.order.len() < MAX_RUNS {
        let Some(done) = ctx.batch(&next, jobs, progress)? else {
            return Ok(None);
        };
        runs.order.extend(done);
        let pts = runs.sorted();
        next.clear();
        for t in &mut tracks {
            t.update(&pts);
            for x in t.propose(&pts, tau) {
                let v = round_sig(x.exp(), r.rtol);
                if !runs.has(v) && !next.iter().any(|u: &f64| u.to_bits() == v.to_bits()) {
                    next.push(v);
                }
            }
        }
        next.sort_by(f64::total_cmp);
    }
    let fruit = (file, free, compliant);
    Ok(Some(result(fruit, r, lift, margin_needed, runs.order, tau)))
}

fn new_track(which: Which, threshold: f64) -> Track {
    Track {
        which,
        threshold,
        last_estimate: None,
        steps: Vec::new(),
        reach: 0,
        widths: Vec::new(),
        moved: Vec::new(),
        bracket: None,
    }
}

/// The boundary of `which` on the sorted runs.
fn boundary(which: Which, applicable: bool, pts: &[&Eval], r: &Resolved, tau: f64) -> Boundary {
    let mut b = Boundary {
        which,
        status: Status::NotApplicable,
        value: None,
        other: None,
        rising: true,
        changes: Vec::new(),
        at: None,
        note: String::new(),
    };
    let name = match which {
        Which::Hold => "g_hold",
        Which::Bruise => "g_bruise",
    };
    let all = pts;
    let pts = &scope(which, pts)[..];
    let below: Vec<f64> = all[..all.len() - pts.len()]
        .iter()
        .filter(|e| which.verdict(e))
        .map(|e| e.value)
        .collect();
    let below =
        match (below.first(), below.last()) {
            (Some(a), Some(z)) => format!(
            "; bruised where not held, at {}{} (a fruit that slips or drops bruises as it lands: \
             outside the window)",
            r.show(*a),
            if a < z { format!("–{}", r.show(*z)) } else { String::new() }
        ),
            _ => String::new(),
        };
    if !applicable {
        b.note = match which {
            Which::Hold => {
                "no free body in the scenario: no grasp verdict, no drop boundary".into()
            }
            Which::Bruise => "no compliant material in the scenario: no bruise boundary".into(),
        };
        return b;
    }
    match bracket(which, pts) {
        Bracket::Uniform(true) => {
            b.status = Status::Everywhere;
            b.note = format!(
                "{} at both ends of {}: {name} < {}",
                which.word(),
                r.range_text(),
                r.show(r.lo)
            );
        }
        Bracket::Uniform(false) => {
            b.status = Status::Nowhere;
            b.note = match which {
                Which::Hold if pts.iter().all(|e| e.dropped == Some(true)) => {
                    format!("dropped at both ends of {}", r.range_text())
                }
                Which::Hold => format!("not held anywhere in {}", r.range_text()),
                Which::Bruise => format!("no bruise up to {}", r.show(r.hi)),
            };
        }
        Bracket::Changes(ix) => {
            b.status = Status::NotMonotone;
            b.changes = ix
                .iter()
                .map(|&i| (pts[i].value, pts[i + 1].value, which.verdict(pts[i + 1])))
                .collect();
            let mut s = format!(
                "not monotone: {} at {}",
                word(which, which.verdict(pts[0])),
                r.show(pts[0].value)
            );
            for (k, c) in b.changes.iter().enumerate() {
                let again = if k > 0 { " again" } else { "" };
                s.push_str(&format!(", {}{again} at {}", word(which, c.2), r.show(c.1)));
            }
            s.push_str(": not bisected across");
            b.note = s;
        }
        Bracket::At(i, j) => {
            let rising = which.verdict(pts[j]);
            let (yes, no) = if rising { (j, i) } else { (i, j) };
            b.status = Status::Found;
            b.rising = rising;
            b.value = Some(pts[yes].value);
            b.other = Some(pts[no].value);
            b.at = Some(pts[yes].clone());
            let closed = (pts[j].value / pts[i].value).ln() <= tau * (1.0 + 1e-9);
            // Changes above the boundary (the outcome lost again higher up).
            b.changes = changes(which, pts)
                .into_iter()
                .filter(|&k| k > i)
                .map(|k| (pts[k].value, pts[k + 1].value, which.verdict(pts[k + 1])))
                .collect();
            let above: String = b
                .changes
                .iter()
                .map(|c| {
                    format!(
                        "; {} again at {} ({} at {}: not bisected)",
                        word(which, c.2),
                        r.show(c.1),
                        word(which, !c.2),
                        r.show(c.0)
                    )
                })
                .collect();
            b.note = format!(
                "{name} = {} ({} there, {} at {}){}{}{above}",
                r.show(pts[yes].value),
                which.word(),
                word(which, false),
                r.show(pts[no].value),
                if rising {
                    String::new()
                } else {
                    format!("; {} below it, not above", which.word())
                },
                if closed {
                    ""
                } else {
                    "; the search stopped before rtol"
                }
            );
        }
    }
    if b.status != Status::NotApplicable {
        b.note.push_str(&below);
    }
    b
}

fn word(which: Which, yes: bool) -> &'static str {
    match (which, yes) {
        (Which::Hold, true) => "held",
        (Which::Hold, false) => "not held",
        (Which::Bruise, true) => "bruised",
        (Which::Bruise, false) => "not bruised",
    }
}

/// `(file, free, compliant)`: the scenario's file, and whether its fruit is free and compliant.
fn result(
    (file, free, compliant): (&str, bool, bool),
    r: &Resolved,
    lift: f64,
    margin_needed: f64,
    order: Vec<Eval>,
    tau: f64,
) -> WindowResult {
    let runs = Runs { order };
    let pts = runs.sorted();
    let hold = boundary(Which::Hold, free, &pts, r, tau);
    let bruise = boundary(Which::Bruise, compliant, &pts, r, tau);
    let (ratio, at_least) = ratio(&hold, &bruise, r);
    let headline = headline(&hold, &bruise, ratio, at_least, r);
    WindowResult {
        scenario: file.to_string(),
        knob: r.clone(),
        lift_acceleration_m_s2: lift,
        margin_needed,
        hold,
        bruise,
        window_ratio: ratio,
        window_ratio_at_least: at_least,
        headline,
        runs: runs.order,
    }
}

/// The window ratio g_bruise / g_hold, or a lower bound when a boundary lies outside the range.
fn ratio(hold: &Boundary, bruise: &Boundary, r: &Resolved) -> (Option<f64>, Option<f64>) {
    let h = match (hold.status, hold.rising) {
        (Status::Found, true) => hold.value.map(|v| (v, true)),
        (Status::Everywhere, _) => Some((r.lo, false)),
        _ => None,
    };
    let b = match (bruise.status, bruise.rising) {
        (Status::Found, true) => bruise.value.map(|v| (v, true)),
        (Status::Nowhere, _) => Some((r.hi, false)),
        _ => None,
    };
    match (h, b) {
        (Some((h, true)), Some((b, true))) => (Some(b / h), None),
        (Some((h, _)), Some((b, _))) => (None, Some(b / h)),
        _ => (None, None),
    }
}

fn headline(
    hold: &Boundary,
    bruise: &Boundary,
    ratio: Option<f64>,
    at_least: Option<f64>,
    r: &Resolved,
) -> String {
    if hold.status == Status::Everywhere && bruise.status == Status::Nowhere {
        return format!(
            "held and unbruised at both ends of {}: the window is wider than the range",
            r.range_text()
        );
    }
    let mut s = format!("{}; {}", hold.note, bruise.note);
    if let Some(q) = ratio {
        s.push_str(&format!(
            "; window ratio g_bruise/g_hold = {}{}",
            fmt_g(q),
            if q > 1.0 {
                ": a safe window exists"
            } else {
                ": no safe window (it bruises before it holds)"
            }
        ));
    } else if let Some(q) = at_least {
        s.push_str(&format!("; window ratio > {}", fmt_g(q)));
    }
    s
}

impl WindowResult {
    /// A one-line summary (a window map's progress line).
    pub fn one_line(&self) -> String {
        let v = |b: &Boundary| match b.value {
            Some(v) if b.status == Status::Found => self.knob.show(v),
            _ => match b.status {
                Status::Everywhere => format!("< {}", self.knob.show(self.knob.lo)),
                Status::Nowhere => format!("> {}", self.knob.show(self.knob.hi)),
                Status::NotMonotone => "not monotone".into(),
                _ => "n/a".into(),
            },
        };
        format!(
            "g_hold {}, g_bruise {}{}, {} runs",
            v(&self.hold),
            v(&self.bruise),
            self.window_ratio
                .map(|q| format!(", ratio {}", fmt_g(q)))
                .unwrap_or_default(),
            self.runs.len()
        )
    }

    /// The printed report: both boundaries, the ratio, the runs.
    pub fn report(&self) -> String {
        let k = &self.knob;
        let mut s = format!("grasp window of {}\n", self.scenario);
        s.push_str(&format!(
            "knob: {} ({}), {} in the scenario\n",
            k.knob,
            k.what,
            k.show(k.scenario_value)
        ));
        s.push_str(&format!(
            "range: {}{}, rtol {} %\n",
            k.range_text(),
            if k.range_given {
                String::new()
            } else {
                " (the scenario's value / 8 to × 8; --range LO:HI to change)".into()
            },
            fmt_g(k.rtol * 100.0)
        ));
        for b in [&self.hold, &self.bruise] {
            s.push_str(&format!(
                "{}: {}\n",
                match b.which {
                    Which::Hold => "drop boundary  ",
                    Which::Bruise => "bruise boundary",
                },
                b.note
            ));
            if let Some(e) = &b.at {
                s.push_str(&format!("    there: {}\n", self.at_boundary(e)));
            }
        }
        s.push_str(&format!("window: {}\n", self.window_line()));
        s.push_str(&format!("runs: {}\n", self.runs.len()));
        s.push_str(&self.table());
        s
    }

    fn window_line(&self) -> String {
        match (self.window_ratio, self.window_ratio_at_least) {
            (Some(q), _) if q > 1.0 => format!(
                "g_bruise / g_hold = {}: a safe window exists (held, not bruised) from {} to {}",
                fmt_g(q),
                self.knob.show(self.hold.value.unwrap_or(f64::NAN)),
                self.knob.show(self.bruise.value.unwrap_or(f64::NAN))
            ),
            (Some(q), _) => format!(
                "g_bruise / g_hold = {}: no safe window (it bruises before it holds)",
                fmt_g(q)
            ),
            (None, Some(q)) => format!(
                "g_bruise / g_hold > {} (a boundary lies outside the range)",
                fmt_g(q)
            ),
            _ => "no ratio g_bruise / g_hold: it needs both boundaries".into(),
        }
    }

    /// The margin and the pressure of a boundary's run.
    fn at_boundary(&self, e: &Eval) -> String {
        let mut parts = Vec::new();
        if let Some(m) = e.safety_margin_at_lift {
            parts.push(format!(
                "safety margin at the lift μ_s ΣN/(m g) = {} (the lift's {} m/s² needs {}: μ_s ΣN/(m (g + a)) = {})",
                fmt_g(m),
                fmt_g(self.lift_acceleration_m_s2),
                fmt_g(self.margin_needed),
                fmt_g(m / self.margin_needed)
            ));
        }
        match (e.max_pressure_pa, e.bruise_ratio) {
            (Some(p), Some(q)) => parts.push(format!(
                "peak pressure p₀ = {} Pa, p₀/p_bruise = {}",
                fmt_g(p),
                fmt_g(q)
            )),
            _ if self.bruise.status != Status::NotApplicable => {
                parts.push("no compliant contact".into())
            }
            _ => {}
        }
        if parts.is_empty() {
            e.outcome()
        } else {
            parts.join("; ")
        }
    }

    /// The runs sorted by knob value: value → outcome, margin, p₀/p_bruise.
    pub fn table(&self) -> String {
        let unit = if self.knob.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.knob.unit)
        };
        let mut s = format!(
            "    {:>12}  {:<28} {:>8} {:>8}  {:>3}\n",
            format!("knob{unit}"),
            "outcome",
            "margin",
            "p0/pb",
            "run"
        );
        let mut rows: Vec<(usize, &Eval)> = self.runs.iter().enumerate().collect();
        rows.sort_by(|a, b| a.1.value.total_cmp(&b.1.value));
        let opt = |v: Option<f64>| v.map(fmt_g).unwrap_or_else(|| "–".into());
        for (k, e) in rows {
            s.push_str(&format!(
                "    {:>12}  {:<28} {:>8} {:>8}  {:>3}\n",
                fmt_g(e.value),
                e.outcome(),
                opt(e.safety_margin_at_lift),
                opt(e.bruise_ratio),
                k + 1
            ));
        }
        s
    }
}

/// `gripsim window SCENARIO` without `--vary`: one search.
pub struct WindowOptions {
    pub scenario: PathBuf,
    pub sets: Vec<String>,
    pub spec: WindowSpec,
    /// Runs at once; 0 = one per core.
    pub jobs: usize,
    pub stop: Option<Stop>,
}

/// Read the scenario of either dimension (with `sets`) and resolve the spec against it.
pub fn resolve_file(
    path: &Path,
    sets: &[String],
    spec: &WindowSpec,
) -> Result<(AnyScenario, Resolved), StudyError> {
    let text =
        crate::scenario::input::read_text(path).map_err(|e| StudyError::Scenario(e.to_string()))?;
    let file = path.display().to_string();
    let dir = sweep::scenario_dir(path);
    let sc =
        sweep::load(&text, &file, &dir, sets).map_err(|e| StudyError::Scenario(e.to_string()))?;
    let r = resolve(&sc, &file, &dir, spec)?;
    Ok((sc.scenario, r))
}

/// One window search of a scenario file (None when stopped).
pub fn run_window(
    opts: &WindowOptions,
    progress: Option<&Progress<'_>>,
) -> Result<Option<WindowResult>, StudyError> {
    let (_, r) = resolve_file(&opts.scenario, &opts.sets, &opts.spec)?;
    let text = crate::scenario::read_capped(&opts.scenario)
        .map_err(|e| io_err(&opts.scenario, format!("cannot read the scenario: {e}")))?;
    let text = String::from_utf8(text).map_err(|_| io_err(&opts.scenario, "not UTF-8 text"))?;
    let jobs = if opts.jobs == 0 {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    } else {
        opts.jobs
    };
    search(
        &text,
        &opts.scenario.display().to_string(),
        &sweep::scenario_dir(&opts.scenario),
        &opts.sets,
        &r,
        jobs,
        opts.stop.as_ref(),
        progress,
    )
}

/// Write a result as JSON (through a temporary file: nothing half written).
pub fn write_result(path: &Path, result: &WindowResult) -> Result<(), StudyError> {
    sweep::write_json(path, result)
}

/// The command that repeats a design's search on its own.
pub fn command_line(scenario: &str, sets: &[String], r: &Resolved) -> String {
    let q = sweep::shell_quote;
    let mut s = format!("gripsim window {}", q(scenario));
    for a in sets {
        s.push_str(" --set ");
        s.push_str(&q(a));
    }
    s.push_str(&format!(
        " --knob {} --range {:?}:{:?} --rtol {:?}",
        q(&r.knob),
        r.lo,
        r.hi,
        r.rtol
    ));
    s
}

/// `window.csv` of a window map: one row per design.
pub fn map_csv(manifest: &Manifest, indices: &[usize], records: &[&CaseRecord]) -> String {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut h: Vec<String> = vec!["design".into(), "id".into()];
    h.extend(manifest.vary.iter().map(|v| v.key.clone()));
    h.extend(
        [
            "g_hold",
            "g_hold_other",
            "hold_status",
            "g_bruise",
            "g_bruise_other",
            "bruise_status",
            "window_ratio",
            "window_ratio_at_least",
            "margin_at_hold",
            "margin_needed",
            "p0_at_hold_pa",
            "p0_ratio_at_hold",
            "margin_at_bruise",
            "p0_at_bruise_pa",
            "p0_ratio_at_bruise",
            "runs",
            "notes",
        ]
        .map(String::from),
    );
    w.write_record(&h).expect("in memory");
    let n = |v: Option<f64>| v.map(sweep::num).unwrap_or_default();
    let status = |b: &Boundary| {
        serde_json::to_value(b.status)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default()
    };
    for (i, r) in indices.iter().zip(records) {
        let mut row = vec![i.to_string(), r.id.clone()];
        row.extend(r.parameters.iter().map(|p| p.1.clone()));
        let Some(x) = &r.window else {
            w.write_record(&row).expect("in memory");
            continue;
        };
        let (h, b) = (&x.hold, &x.bruise);
        let at = |b: &Boundary, f: fn(&Eval) -> Option<f64>| b.at.as_ref().and_then(f);
        row.extend([
            n(h.value),
            n(h.other),
            status(h),
            n(b.value),
            n(b.other),
            status(b),
            n(x.window_ratio),
            n(x.window_ratio_at_least),
            n(at(h, |e| e.safety_margin_at_lift)),
            sweep::num(x.margin_needed),
            n(at(h, |e| e.max_pressure_pa)),
            n(at(h, |e| e.bruise_ratio)),
            n(at(b, |e| e.safety_margin_at_lift)),
            n(at(b, |e| e.max_pressure_pa)),
            n(at(b, |e| e.bruise_ratio)),
            x.runs.len().to_string(),
            x.headline.clone(),
        ]);
        w.write_record(&row).expect("in memory");
    }
    String::from_utf8(w.into_inner().expect("in memory")).expect("UTF-8")
}

/// `window.json` of a window map.
#[derive(Debug, Serialize)]
struct MapJson<'a> {
    format: u32,
    scenario: &'a str,
    sets: &'a [String],
    window: Option<&'a Resolved>,
    vary: &'a [super::Vary],
    designs: Vec<DesignJson<'a>>,
}

#[derive(Debug, Serialize)]
struct DesignJson<'a> {
    design: usize,
    id: &'a str,
    parameters: &'a [(String, String)],
    command: &'a str,
    window: Option<&'a WindowResult>,
}

/// `window.csv`, `window.json` and the picture, for a complete map.
pub(crate) fn finalize_map(
    out: &Path,
    manifest: &Manifest,
    records: &[&CaseRecord],
    plots: bool,
) -> Result<(PathBuf, Vec<String>), StudyError> {
    let idx: Vec<usize> = (0..records.len()).collect();
    let path = out.join("window.csv");
    let changed = sweep::write_if_changed(&path, map_csv(manifest, &idx, records).as_bytes())?;
    let json = MapJson {
        format: sweep::FORMAT,
        scenario: &manifest.scenario,
        sets: &manifest.sets,
        window: manifest.window.as_ref(),
        vary: &manifest.vary,
        designs: records
            .iter()
            .enumerate()
            .map(|(i, r)| DesignJson {
                design: i,
                id: &r.id,
                parameters: &r.parameters,
                command: &r.command,
                window: r.window.as_deref(),
            })
            .collect(),
    };
    let mut text = serde_json::to_string_pretty(&json).expect("serialises");
    text.push('\n');
    sweep::write_if_changed(&out.join("window.json"), text.as_bytes())?;
    let mut errors = Vec::new();
    if plots && (changed || !out.join("window.png").exists()) {
        if let Err(e) = super::window_plot::draw_map(manifest, records, &out.join("window")) {
            errors.push(e);
        }
    }
    Ok((path, errors))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_and_tolerances_are_checked() {
        assert_eq!(parse_range("0.5:20").unwrap(), (0.5, 20.0));
        assert!(parse_range("5:1").unwrap_err().contains("not below HI"));
        assert!(parse_range("0:1").unwrap_err().contains("must be > 0"));
        assert!(parse_range("-1:1").unwrap_err().contains("must be > 0"));
        assert!(parse_range("1").is_err());
        assert!(parse_range("a:2").unwrap_err().contains("numbers"));
        assert_eq!(parse_rtol("0.01").unwrap(), 0.01);
        assert!(parse_rtol("0").is_err());
        assert!(parse_rtol("-0.1").is_err());
        assert!(parse_rtol("x").unwrap_err().contains("not a number"));
    }

    #[test]
    fn numbers_read_well() {
        assert_eq!(fmt_g(1.8), "1.8");
        assert_eq!(fmt_g(0.225), "0.225");
        assert_eq!(fmt_g(14.4), "14.4");
        assert_eq!(fmt_g(1.37246), "1.372");
        assert_eq!(fmt_g(123456.0), "1.235e5");
        assert_eq!(fmt_g(1.5e7), "1.5e7");
        assert_eq!(fmt_g(1e8), "1e8");
        assert_eq!(fmt_g(-2.5e-4), "-2.5e-4");
        assert_eq!(round_sig(1.234_567_89, 0.01), 1.234_57);
    }

    fn resolved(lo: f64, hi: f64) -> Resolved {
        Resolved {
            knob: "k".into(),
            what: String::new(),
            unit: "N".into(),
            scenario_value: (lo * hi).sqrt(),
            lo,
            hi,
            range_given: false,
            rtol: 0.01,
        }
    }

    #[test]
    fn the_default_grid_holds_the_scenario_value() {
        let g = coarse_grid(&resolved(1.8 / 8.0, 1.8 * 8.0));
        assert_eq!(g.len(), 5);
        assert_eq!(g[2], 1.8);
        assert_eq!((g[0], g[4]), (0.225, 14.4));
    }

    /// A synthetic boundary: held iff v ≥ root, margin ∝ v (threshold 1.1 at the root).
    fn eval(v: f64, root: f64) -> Eval {
        Eval {
            value: v,
            completed: true,
            error: None,
            held: Some(v >= root),
            dropped: Some(v < root),
            lifted: Some(true),
            safety_margin_at_lift: Some(1.1 * (v / root).powf(0.9)),
            min_safety_margin: None,
            peak_grip_force_n: None,
            max_slip_m: None,
            bruised: None,
            bruise_ratio: None,
            max_pressure_pa: None,
            bruise_pressure_pa: None,
            warnings: 0,
            steps: 0,
            wall_time_s: 0.0,
        }
    }

    /// The search's loop on a synthetic boundary (held iff the margin ≥ 1.1) whose threshold
    /// the search takes to be `threshold`.
    fn count_runs(root: f64, threshold: f64) -> (usize, f64) {
        let r = resolved(1.8 / 8.0, 1.8 * 8.0);
        let tau = (1.0 + r.rtol).ln();
        let mut t = new_track(Which::Hold, threshold.ln());
        let mut runs = Runs { order: Vec::new() };
        let mut next = coarse_grid(&r);
        while !next.is_empty() && runs.order.len() < MAX_RUNS {
            runs.order.extend(next.iter().map(|v| eval(*v, root)));
            let pts = runs.sorted();
            t.update(&pts);
            next = t
                .propose(&pts, tau)
                .into_iter()
                .map(|x| round_sig(x.exp(), r.rtol))
                .filter(|v| !runs.has(*v))
                .collect();
        }
        let pts = runs.sorted();
        let b = boundary(Which::Hold, true, &pts, &r, tau);
        assert_eq!(b.status, Status::Found);
        let (v, o) = (b.value.unwrap(), b.other.unwrap());
        assert!(
            v >= root && o < root && v / o <= 1.01 + 1e-12,
            "{v} {o} {root}"
        );
        (runs.order.len(), v)
    }

    #[test]
    fn outcomes_that_are_not_monotone_are_reported_not_bisected() {
        let r = resolved(0.225, 14.4);
        let tau = (1.0 + r.rtol).ln();
        let at = |v: f64, held: bool| Eval {
            held: Some(held),
            ..eval(v, 1.0)
        };
        // Held at the low end, dropped, held again: no smallest value that holds to find.
        let runs = [
            at(0.225, true),
            at(0.64, false),
            at(1.8, true),
            at(14.4, true),
        ];
        let pts: Vec<&Eval> = runs.iter().collect();
        let mut t = new_track(Which::Hold, 0.0);
        assert!(t.propose(&pts, tau).is_empty());
        let b = boundary(Which::Hold, true, &pts, &r, tau);
        assert_eq!(b.status, Status::NotMonotone);
        assert_eq!(b.changes, [(0.225, 0.64, false), (0.64, 1.8, true)]);
        assert_eq!(
            b.note,
            "not monotone: held at 0.225 N, not held at 0.64 N, held again at 1.8 N: not bisected across"
        );
        assert!(b.value.is_none());
        // Not held at the low end, held, not held again higher up (a fruit squeezed out):
        // the smallest value that holds is the first change, bisected there alone; what comes
        // above is reported.
        let runs = [
            at(0.225, false),
            at(0.64, true),
            at(1.8, false),
            at(5.1, true),
            at(14.4, true),
        ];
        let pts: Vec<&Eval> = runs.iter().collect();
        let mut t = new_track(Which::Hold, 0.0);
        let next = t.propose(&pts, tau);
        assert!(!next.is_empty());
        assert!(next.iter().all(|x| *x > 0.225f64.ln() && *x < 0.64f64.ln()));
        let b = boundary(Which::Hold, true, &pts, &r, tau);
        assert_eq!(b.status, Status::Found);
        assert_eq!(b.value, Some(0.64));
        assert_eq!(b.changes, [(0.64, 1.8, false), (1.8, 5.1, true)]);
        assert!(
            b.note.ends_with(
                "; not held again at 1.8 N (held at 0.64 N: not bisected); held again at 5.1 N (not held at 1.8 N: not bisected)"
            ),
            "{}",
            b.note
        );
    }

    #[test]
    fn a_smooth_boundary_takes_few_runs() {
        for root in [0.3, 0.77, 1.2345, 1.37, 2.9, 6.1, 13.0] {
            // The threshold right: the coarse grid (5) and 2 or 3 more.
            let (n, _) = count_runs(root, 1.1);
            assert!(n <= 8, "root {root}: {n} runs");
            // The threshold 3 % off (margins just past it contradict it): steps in from the
            // contradicting end, then bisection.
            let (n, _) = count_runs(root, 1.067);
            assert!(n <= 12, "root {root}, threshold off: {n} runs");
        }
    }

    #[test]
    fn a_bruise_where_the_fruit_is_not_held_does_not_close_the_window() {
        // Soft prongs: the fruit slips at low grips and bruises as it lands; from 7 N it is
        // held unbruised, from 16 N squeezed to a bruise. The window is 7–16 N, not "none".
        let r = resolved(1.25, 80.0);
        let tau = (1.0 + r.rtol).ln();
        let at = |v: f64, held: bool, bruised: bool| Eval {
            held: Some(held),
            bruised: Some(bruised),
            bruise_ratio: Some(if bruised { 1.1 } else { 0.9 }),
            ..eval(v, 7.0)
        };
        let runs = [
            at(1.25, false, false),
            at(3.5, false, false),
            at(6.5, false, true),
            at(7.0, true, false),
            at(10.0, true, false),
            at(16.0, true, true),
            at(28.0, true, true),
        ];
        let pts: Vec<&Eval> = runs.iter().collect();
        let b = boundary(Which::Bruise, true, &pts, &r, tau);
        assert_eq!(b.status, Status::Found);
        assert_eq!((b.value, b.other), (Some(16.0), Some(10.0)));
        assert!(
            b.note.contains("bruised where not held, at 6.5 N"),
            "{}",
            b.note
        );
        let mut t = new_track(Which::Bruise, 0.0);
        let next = t.propose(&pts, tau);
        assert!(!next.is_empty() && next.iter().all(|x| *x > 10f64.ln() && *x < 16f64.ln()));
        // Never held: the bruise boundary is searched over every run.
        let never: Vec<Eval> = runs
            .iter()
            .map(|e| Eval {
                held: Some(false),
                ..e.clone()
            })
            .collect();
        let pts: Vec<&Eval> = never.iter().collect();
        assert_eq!(
            boundary(Which::Bruise, true, &pts, &r, tau).value,
            Some(6.5)
        );
    }
}
