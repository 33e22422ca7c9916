//! Two runs compared on simulated time.
//!
//! The runs may use different, proximity-switched or adaptive step sizes, so they are compared
//! at the union of their step times: at each such time the run without a step there is
//! interpolated linearly between its two neighbouring steps. Positions, velocities and eq. 2
//! reactions are compared node by node (Euclidean norm of the difference vector); contact
//! events are paired by rod, node, change and obstacle; spikes and sticking episodes found by
//! [`super::detect`] are paired the same way.

use super::detect::{Counts, Detector, Effective, Findings, Thresholds};
use super::read::{Contact, Message, Meta, ReadStatus, Run, Step};
use super::{ReplayError, REPORT_VERSION};
use crate::scenario::{Mode, Scenario};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// When two runs count as the same (each one a `gripsim replay diff` flag).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, clap::Args)]
pub struct Tolerances {
    /// Largest position difference |q_A - q_B| per node (m).
    #[arg(long, value_name = "M", default_value = "1e-9")]
    pub tol_position: f64,
    /// Largest velocity difference per node (m/s).
    #[arg(long, value_name = "M/S", default_value = "1e-6")]
    pub tol_velocity: f64,
    /// Largest eq. 2 reaction difference per node (N).
    #[arg(long, value_name = "N", default_value = "1e-6")]
    pub tol_reaction: f64,
    /// Largest time shift of a contact event, and of the runs' ends (s) [default: one step,
    /// the larger step of the two runs at that time].
    #[arg(long, value_name = "S")]
    pub tol_time: Option<f64>,
    /// Contact events and findings further apart than this (s) are not paired: each is then
    /// reported as found in one run only.
    #[arg(long, value_name = "S", default_value = "5e-3")]
    pub event_window: f64,
}

impl Tolerances {
    pub const DEFAULT: Tolerances = Tolerances {
        tol_position: 1e-9,
        tol_velocity: 1e-6,
        tol_reaction: 1e-6,
        tol_time: None,
        event_window: 5e-3,
    };

    pub fn validate(&self) -> Result<(), String> {
        let all = [
            ("--tol-position", self.tol_position),
            ("--tol-velocity", self.tol_velocity),
            ("--tol-reaction", self.tol_reaction),
            ("--tol-time", self.tol_time.unwrap_or(0.0)),
            ("--event-window", self.event_window),
        ];
        for (name, v) in all {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("{name} must be a finite number >= 0, got {v}"));
            }
        }
        Ok(())
    }
}

impl Default for Tolerances {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// One run as the report names it.
#[derive(Debug, Clone, Serialize)]
pub struct RunRef {
    pub file: String,
    pub scenario: String,
    pub gripsim_version: String,
    pub steps: u64,
    pub t_end: f64,
    pub truncated: Option<String>,
    pub completed: Option<bool>,
    /// The recording stops before its run's end (truncated, or the run did not complete).
    pub incomplete: bool,
}

/// A scenario value that differs, by dotted path (`rod.0.E`); null where a run lacks it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamDiff {
    pub key: String,
    pub a: Option<serde_json::Value>,
    pub b: Option<serde_json::Value>,
}

/// The time spans of the two runs.
#[derive(Debug, Clone, Serialize)]
pub struct Span {
    pub a_t_end: f64,
    pub b_t_end: f64,
    /// Both runs are compared up to here.
    pub compared_to: f64,
    /// The ends differ by more than the time tolerance.
    pub differs: bool,
}

/// The first time a node's quantity differs beyond its tolerance.
#[derive(Debug, Clone, Serialize)]
pub struct Divergence {
    pub t: f64,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// `position`, `velocity` or `reaction`.
    pub quantity: &'static str,
    pub a: [f64; 2],
    pub b: [f64; 2],
    pub difference: f64,
    pub tolerance: f64,
    /// The step of each run at or just after `t`.
    pub step_a: u64,
    pub step_b: u64,
    /// What the f32 rounding of the recorded values can account for (0 when both runs are
    /// recorded in f64): a difference counts only beyond `tolerance + resolution`.
    pub resolution: f64,
}

/// The largest difference of one quantity at one node, and when.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Max {
    pub max: f64,
    pub t: f64,
}

impl Max {
    fn add(&mut self, d: f64, t: f64) {
        if d > self.max {
            self.max = d;
            self.t = t;
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct NodeDiff {
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    pub position: Max,
    pub velocity: Max,
    pub reaction: Max,
    /// The quantities over their tolerance.
    pub exceeds: Vec<&'static str>,
    /// Per quantity: over `tolerance + resolution` at some time.
    #[serde(skip)]
    over: [bool; 3],
}

/// The first step both runs hold that differs bit for bit (format 4 fingerprints).
#[derive(Debug, Clone, Serialize)]
pub struct BitwiseDivergence {
    pub step: u64,
    /// The step's end in run A.
    pub t: f64,
    /// `state`: the fingerprints of the exact f64 state differ; `time`: the step ends at
    /// another time in each run.
    pub what: &'static str,
    /// Every recorded value of the step (positions, velocities, reactions) agrees within one
    /// f32 unit at its rod's largest magnitude of that quantity: the runs differ below the
    /// recording's f32 resolution.
    pub below_f32_resolution: bool,
}

/// A contact event found in one run only, or in both at different times.
#[derive(Debug, Clone, Serialize)]
pub struct EventDiff {
    /// `only_a`, `only_b` or `shifted`.
    pub status: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// `added` or `released`.
    pub change: String,
    pub obstacle: usize,
    pub t_a: Option<f64>,
    pub t_b: Option<f64>,
    pub step_a: Option<u64>,
    pub step_b: Option<u64>,
    /// t_b − t_a for a shifted pair.
    pub shift: Option<f64>,
}

#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct EventCounts {
    pub a: usize,
    pub b: usize,
    pub matched: usize,
    pub shifted: usize,
    pub only_a: usize,
    pub only_b: usize,
}

/// A spike or sticking episode found in one run only.
#[derive(Debug, Clone, Serialize)]
pub struct FindingDiff {
    /// `only_a` or `only_b`.
    pub status: &'static str,
    /// `spike` or `sticking`.
    pub category: &'static str,
    /// The spike kind or sticking rule.
    pub kind: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    pub step: u64,
    pub t: f64,
}

/// The report of `replay diff`.
#[derive(Debug, Clone, Serialize)]
pub struct DiffReport {
    pub report_version: u32,
    pub a: RunRef,
    pub b: RunRef,
    pub tolerances: Tolerances,
    /// The thresholds in force for run A and run B (they follow each run's scene).
    pub thresholds_a: Effective,
    pub thresholds_b: Effective,
    pub within_tolerance: bool,
    pub parameters: Vec<ParamDiff>,
    pub span: Span,
    /// Times compared (the union of both runs' step times up to `span.compared_to`, less those
    /// inside a gap of a decimated recording).
    pub samples: usize,
    /// Step times not compared because they fall in a gap of a `--detail auto` recording
    /// (between two recorded steps more than one step apart): only the steps both runs
    /// hold, or can interpolate between neighbouring steps, are compared.
    #[serde(skip_serializing_if = "is_zero")]
    pub skipped_in_gaps: usize,
    pub first_divergence: Option<Divergence>,
    /// Both runs carry a fingerprint on every step (format 4): the bitwise comparison ran.
    pub fingerprints: bool,
    /// The first step where the runs differ bit for bit (None: identical at every step both
    /// hold, or no fingerprints).
    pub first_bitwise_divergence: Option<BitwiseDivergence>,
    pub nodes: Vec<NodeDiff>,
    pub contact_event_counts: EventCounts,
    pub contact_events: Vec<EventDiff>,
    pub counts_a: Counts,
    pub counts_b: Counts,
    pub findings: Vec<FindingDiff>,
    /// What each run found, for the overlay (not serialised: `replay check` reports it).
    #[serde(skip)]
    pub findings_a: Findings,
    #[serde(skip)]
    pub findings_b: Findings,
}

/// Every leaf of a TOML table by dotted path; arrays of tables are indexed (`rod.0.E`), other
/// arrays are one value.
pub fn flatten(prefix: &str, v: &toml::Value, out: &mut BTreeMap<String, toml::Value>) {
    let key = |k: &str| {
        if prefix.is_empty() {
            k.to_string()
        } else {
            format!("{prefix}.{k}")
        }
    };
    match v {
        toml::Value::Table(t) => {
            for (k, x) in t {
                flatten(&key(k), x, out);
            }
        }
        toml::Value::Array(a) if !a.is_empty() && a.iter().all(|x| x.is_table()) => {
            for (i, x) in a.iter().enumerate() {
                flatten(&key(&i.to_string()), x, out);
            }
        }
        other => {
            out.insert(prefix.to_string(), other.clone());
        }
    }
}

/// Where a time falls in a run: the steps around it and the blend weight of the later one.
#[derive(Debug, Clone, Copy)]
pub struct At {
    pub k0: usize,
    pub k1: usize,
    pub w: f64,
}

impl At {
    /// Linear interpolation of node `i`'s vector in `field` of rod `r`.
    pub fn vec2(&self, run: &Run, r: usize, i: usize, field: Field) -> [f64; 2] {
        let a = field(&run.steps[self.k0].rods[r]);
        if self.w == 0.0 {
            return [a[2 * i], a[2 * i + 1]];
        }
        let b = field(&run.steps[self.k1].rods[r]);
        let w = self.w;
        [
            a[2 * i] + w * (b[2 * i] - a[2 * i]),
            a[2 * i + 1] + w * (b[2 * i + 1] - a[2 * i + 1]),
        ]
    }

    /// The step at or just after the time.
    pub fn step(&self, run: &Run) -> u64 {
        if self.w == 0.0 {
            run.steps[self.k0].step
        } else {
            run.steps[self.k1].step
        }
    }
}

/// Locate `t` in `run` (clamped to its span).
pub fn locate(run: &Run, t: f64) -> At {
    let s = &run.steps;
    let k1 = s.partition_point(|x| x.t < t);
    if k1 >= s.len() {
        return At {
            k0: s.len() - 1,
            k1: s.len() - 1,
            w: 0.0,
        };
    }
    if s[k1].t == t || k1 == 0 {
        return At { k0: k1, k1, w: 0.0 };
    }
    let k0 = k1 - 1;
    let w = (t - s[k0].t) / (s[k1].t - s[k0].t);
    At { k0, k1, w }
}

/// One per-node vector field of a recorded step.
pub type Field = fn(&super::read::RodState) -> &[f64];

pub fn pos(v: &super::read::RodState) -> &[f64] {
    &v.q
}
pub fn vel(v: &super::read::RodState) -> &[f64] {
    &v.u
}
pub fn reac(v: &super::read::RodState) -> &[f64] {
    &v.reaction
}

/// What a diff knows of a run before its steps.
#[derive(Debug, Clone)]
pub struct Head {
    pub path: PathBuf,
    pub meta: Meta,
    pub scenario: Scenario,
}

impl Head {
    fn of(run: &Run) -> Head {
        Head {
            path: run.path.clone(),
            meta: run.meta.clone(),
            scenario: run.scenario.clone(),
        }
    }

    fn dynamic(&self) -> bool {
        self.scenario.solve.mode == Mode::Dynamic
    }
}

/// Why two runs cannot be compared node by node, if they cannot.
pub fn comparable(a: &Head, b: &Head) -> Result<(), ReplayError> {
    let desc = |r: &Head| {
        let rods: Vec<String> = r
            .meta
            .rods
            .iter()
            .map(|x| format!("{:?} with {} node(s)", x.name, x.nodes))
            .collect();
        format!(
            "{} ({} rod(s): {})",
            r.path.display(),
            r.meta.rods.len(),
            rods.join(", ")
        )
    };
    let same = a.meta.rods.len() == b.meta.rods.len()
        && a.meta
            .rods
            .iter()
            .zip(&b.meta.rods)
            .all(|(x, y)| x.nodes == y.nodes);
    if !same {
        return Err(ReplayError::new(format!(
            "cannot compare the runs node by node: A is {} and B is {}. A diff pairs rod i node j \
             of A with rod i node j of B, so both runs need the same rods in the same order with \
             the same node counts (compare their summaries instead)",
            desc(a),
            desc(b)
        )));
    }
    if a.dynamic() != b.dynamic() {
        return Err(ReplayError::new(format!(
            "cannot compare a {} run ({}) with a {} run ({}): one is timed by simulated time, the \
             other by load factor",
            a.meta.mode,
            a.path.display(),
            b.meta.mode,
            b.path.display()
        )));
    }
    Ok(())
}

/// Scenario values that differ between the runs, by dotted path.
pub fn parameter_diff(a: &Head, b: &Head) -> Vec<ParamDiff> {
    let parse = |r: &Head| {
        let mut m = BTreeMap::new();
        if let Ok(t) = r.meta.scenario_text.parse::<toml::Table>() {
            flatten("", &toml::Value::Table(t), &mut m);
        }
        m
    };
    differing_values(&parse(a), &parse(b))
}

/// The dotted paths whose values differ between two flattened scenarios.
pub(crate) fn differing_values(
    pa: &BTreeMap<String, toml::Value>,
    pb: &BTreeMap<String, toml::Value>,
) -> Vec<ParamDiff> {
    let json = |v: &toml::Value| serde_json::to_value(v).ok();
    let mut keys: Vec<&String> = pa.keys().chain(pb.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.into_iter()
        .filter(|k| pa.get(*k) != pb.get(*k))
        .map(|k| ParamDiff {
            key: k.clone(),
            a: pa.get(k).and_then(json),
            b: pb.get(k).and_then(json),
        })
        .collect()
}

/// What a reader thread sends: the messages in file order, then how the read ended.
enum Feed {
    Msg(Message),
    Done(Result<ReadStatus, ReplayError>),
}

/// Where a run's steps come from: a file read on its own thread (a bounded queue of messages,
/// so memory does not grow with the run), or a run already in memory.
enum Source<'a> {
    File(std::sync::mpsc::Receiver<Feed>),
    Memory { run: &'a Run, k: usize, c: usize },
}

/// One item of a run, in file order.
enum Item {
    Contact(Contact),
    Step(Step),
}

/// A contact change of an accepted step, as the diff pairs it.
#[derive(Debug, Clone)]
pub(crate) struct Ev {
    pub rod: usize,
    pub node: usize,
    pub change: String,
    pub obstacle: usize,
    pub t: f64,
    pub step: u64,
}

/// One run being read: the step before and the step after the current sample time, its
/// detector, its accepted contact changes and its step sizes (run-length coded).
struct Side<'a> {
    head: Head,
    src: Source<'a>,
    det: Detector,
    pending: Vec<Contact>,
    events: Vec<Ev>,
    /// (first step end time, last step end time, dt) of each stretch of equal steps.
    dts: Vec<(f64, f64, f64)>,
    cur: Option<Step>,
    next: Option<Step>,
    steps: u64,
    t_end: f64,
    status: ReadStatus,
    completed: Option<bool>,
}

impl<'a> Side<'a> {
    fn new(head: Head, src: Source<'a>, th: &Thresholds) -> Self {
        Side {
            det: Detector::for_recording(&head.scenario, th, head.meta.f32()),
            head,
            src,
            pending: Vec::new(),
            events: Vec::new(),
            dts: Vec::new(),
            cur: None,
            next: None,
            steps: 0,
            t_end: 0.0,
            status: ReadStatus::default(),
            completed: None,
        }
    }

    /// A file, read on its own thread; returns once `/sim/meta` is read.
    fn file(path: &Path, th: &Thresholds) -> Result<Side<'static>, ReplayError> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Feed>(64);
        let p = path.to_path_buf();
        std::thread::spawn(move || {
            let tx2 = tx.clone();
            let res = super::read::read_messages(&p, false, |m| {
                tx2.send(Feed::Msg(m))
                    .map_err(|_| ReplayError::new("the diff stopped reading".into()))
            });
            let _ = tx.send(Feed::Done(res));
        });
        let meta = loop {
            match rx.recv() {
                Ok(Feed::Msg(Message::Meta(m))) => break *m,
                Ok(Feed::Msg(_)) => continue,
                Ok(Feed::Done(Err(e))) => return Err(e),
                Ok(Feed::Done(Ok(_))) | Err(_) => {
                    return Err(ReplayError::file(path, "no /sim/meta message".into()))
                }
            }
        };
        let scenario = super::read::parse_scenario(path, &meta)?;
        let head = Head {
            path: path.to_path_buf(),
            meta,
            scenario,
        };
        Ok(Side::new(head, Source::File(rx), th))
    }

    fn item(&mut self) -> Result<Option<Item>, ReplayError> {
        match &mut self.src {
            Source::Memory { run, k, c } => {
                let Some(st) = run.steps.get(*k) else {
                    self.status = run.status.clone();
                    self.completed = run.completed();
                    return Ok(None);
                };
                if let Some(x) = run.contacts.get(*c).filter(|x| x.step <= st.step) {
                    *c += 1;
                    return Ok(Some(Item::Contact(x.clone())));
                }
                *k += 1;
                Ok(Some(Item::Step(st.clone())))
            }
            Source::File(rx) => loop {
                match rx.recv() {
                    Ok(Feed::Msg(Message::Contact(c))) => return Ok(Some(Item::Contact(c))),
                    Ok(Feed::Msg(Message::Step(s))) => return Ok(Some(Item::Step(s))),
                    Ok(Feed::Msg(Message::Event(e))) if e.kind == "run_end" => {
                        self.completed = e.completed
                    }
                    Ok(Feed::Msg(_)) => {}
                    Ok(Feed::Done(res)) => {
                        self.status = res?;
                        if self.completed.is_none() {
                            self.completed = self
                                .status
                                .run_end
                                .as_ref()
                                .and_then(|m| m.get("completed"))
                                .map(|c| c == "true");
                        }
                        return Ok(None);
                    }
                    Err(_) => return Ok(None),
                }
            },
        }
    }

    /// Move to the next step: `cur` becomes the old `next`.
    fn advance(&mut self) -> Result<(), ReplayError> {
        if let Some(n) = self.next.take() {
            self.cur = Some(n);
        }
        while let Some(item) = self.item()? {
            match item {
                Item::Contact(c) => {
                    self.det.contact(c.sample());
                    self.pending.push(c);
                }
                Item::Step(st) => {
                    self.take_step(&st);
                    self.next = Some(st);
                    return Ok(());
                }
            }
        }
        Ok(())
    }

    fn take_step(&mut self, st: &Step) {
        let dynamic = self.head.dynamic();
        for c in std::mem::take(&mut self.pending) {
            // Only the accepted attempt's changes (same step, same time).
            if c.step == st.step && (!dynamic || c.t == st.t) {
                self.events.push(Ev {
                    rod: c.rod,
                    node: c.node,
                    change: c.change,
                    obstacle: c.obstacle,
                    t: c.t,
                    step: c.step,
                });
            } else if c.step > st.step {
                self.pending.push(c);
            }
        }
        let samples: Vec<_> = st.rods.iter().map(|r| r.sample()).collect();
        self.det.step(st.step, st.t, st.dt, &samples);
        match self.dts.last_mut() {
            Some(seg) if seg.2 == st.dt => seg.1 = st.t,
            _ => self.dts.push((st.t, st.t, st.dt)),
        }
        self.steps += 1;
        self.t_end = st.t;
    }

    /// The step size of the step that ends at or just after `t`.
    fn dt_at(&self, t: f64) -> f64 {
        let k = self.dts.partition_point(|s| s.1 < t);
        let k = k.min(self.dts.len().saturating_sub(1));
        match self.dts.get(k) {
            Some(s) if s.2 > 0.0 => s.2,
            Some(_) => self.dts.get(k + 1).map(|s| s.2).unwrap_or(0.0),
            None => 0.0,
        }
    }

    /// True when `t` falls strictly inside a gap of a decimated recording: between two
    /// recorded steps that are not consecutive steps of the run.
    fn in_gap(&self, t: f64) -> bool {
        match (&self.cur, &self.next) {
            (Some(c), Some(n)) => n.t != t && n.step > c.step + 1,
            _ => false,
        }
    }

    /// Node `i` of rod `r` of `field` at `t` (between `cur` and `next`, or at `next`).
    fn vec2(&self, t: f64, r: usize, i: usize, field: Field) -> [f64; 2] {
        let n = self
            .next
            .as_ref()
            .expect("a sample lies before the run's end");
        let b = field(&n.rods[r]);
        let vb = [b[2 * i], b[2 * i + 1]];
        match &self.cur {
            Some(c) if n.t != t => {
                let a = field(&c.rods[r]);
                let w = (t - c.t) / (n.t - c.t);
                [
                    a[2 * i] + w * (vb[0] - a[2 * i]),
                    a[2 * i + 1] + w * (vb[1] - a[2 * i + 1]),
                ]
            }
            _ => vb,
        }
    }

    fn reference(&self) -> RunRef {
        RunRef {
            file: self.head.path.display().to_string(),
            scenario: self.head.meta.scenario_name.clone(),
            gripsim_version: self.head.meta.gripsim_version.clone(),
            steps: self.steps,
            t_end: self.t_end,
            truncated: self.status.truncated.clone(),
            completed: self.completed,
            incomplete: self.status.truncated.is_some() || self.completed != Some(true),
        }
    }
}

/// Compare two recordings, streaming: both files are read at once, chunk by chunk, and
/// compared at the union of their step times; memory holds two steps per run, the detection
/// windows and the contact changes, not the runs.
pub fn diff_files(
    a: &Path,
    b: &Path,
    tol: &Tolerances,
    th: &Thresholds,
) -> Result<DiffReport, ReplayError> {
    let sa = Side::file(a, th)?;
    let sb = Side::file(b, th)?;
    run_diff(sa, sb, tol)
}

/// Compare two runs held in memory (the same comparison as [`diff_files`]).
pub fn diff(
    a: &Run,
    b: &Run,
    tol: &Tolerances,
    th: &Thresholds,
) -> Result<DiffReport, ReplayError> {
    run_diff(memory_side(a, th), memory_side(b, th), tol)
}

fn memory_side<'a>(r: &'a Run, th: &Thresholds) -> Side<'a> {
    Side::new(Head::of(r), Source::Memory { run: r, k: 0, c: 0 }, th)
}

fn run_diff(mut a: Side<'_>, mut b: Side<'_>, tol: &Tolerances) -> Result<DiffReport, ReplayError> {
    comparable(&a.head, &b.head)?;
    let parameters = parameter_diff(&a.head, &b.head);
    let quantities: [(&'static str, Field, f64); 3] = [
        ("position", pos, tol.tol_position),
        ("velocity", vel, tol.tol_velocity),
        ("reaction", reac, tol.tol_reaction),
    ];
    let mut nodes: Vec<NodeDiff> = Vec::new();
    for (r, rod) in a.head.meta.rods.iter().enumerate() {
        for i in 0..rod.nodes {
            nodes.push(NodeDiff {
                rod: r,
                rod_name: rod.name.clone(),
                node: i,
                position: Max::default(),
                velocity: Max::default(),
                reaction: Max::default(),
                exceeds: Vec::new(),
                over: [false; 3],
            });
        }
    }
    a.advance()?;
    b.advance()?;
    let mut first: Option<Divergence> = None;
    let mut bitwise: Option<BitwiseDivergence> = None;
    let mut fingerprints = true;
    // Half an f32 unit in the last place, relative, per run recorded in f32.
    let half_ulp = |f32: bool| if f32 { 2f64.powi(-24) } else { 0.0 };
    let (ra_res, rb_res) = (half_ulp(a.head.meta.f32()), half_ulp(b.head.meta.f32()));
    let mut samples = 0usize;
    let mut skipped_in_gaps = 0usize;
    // The union of both runs' step times, while both runs reach it.
    while let (Some(na), Some(nb)) = (&a.next, &b.next) {
        let t = na.t.min(nb.t);
        let (step_a, step_b) = (na.step, nb.step);
        fingerprints &= na.fingerprint.is_some() && nb.fingerprint.is_some();
        if bitwise.is_none() && fingerprints && step_a == step_b {
            let what = if na.t != nb.t {
                Some("time")
            } else if na.fingerprint != nb.fingerprint {
                Some("state")
            } else {
                None
            };
            bitwise = what.map(|what| BitwiseDivergence {
                step: step_a,
                t: na.t,
                what,
                below_f32_resolution: what == "state"
                    && na.rods.iter().zip(&nb.rods).all(|(x, y)| {
                        f32_agree(&x.q, &y.q)
                            && f32_agree(&x.u, &y.u)
                            && f32_agree(&x.reaction, &y.reaction)
                    }),
            });
        }
        if a.in_gap(t) || b.in_gap(t) {
            // A decimated recording has no state here: nothing to compare.
            skipped_in_gaps += 1;
            let (ta, tb) = (na.t, nb.t);
            if ta == t {
                a.advance()?;
            }
            if tb == t {
                b.advance()?;
            }
            continue;
        }
        samples += 1;
        let mut worst: Option<(f64, Divergence)> = None;
        let mut idx = 0;
        for (r, rod) in a.head.meta.rods.iter().enumerate() {
            for i in 0..rod.nodes {
                let nd = &mut nodes[idx];
                idx += 1;
                for (q, (name, field, tolerance)) in quantities.iter().enumerate() {
                    let (va, vb) = (a.vec2(t, r, i, *field), b.vec2(t, r, i, *field));
                    let d = (va[0] - vb[0]).hypot(va[1] - vb[1]);
                    // The f32 rounding of each recorded component: at most half an ulp.
                    let resolution = (ra_res * va[0].abs() + rb_res * vb[0].abs())
                        .hypot(ra_res * va[1].abs() + rb_res * vb[1].abs());
                    match q {
                        0 => nd.position.add(d, t),
                        1 => nd.velocity.add(d, t),
                        _ => nd.reaction.add(d, t),
                    }
                    let over = d > *tolerance + resolution;
                    nd.over[q] |= over;
                    if first.is_none() && over {
                        let ratio = if *tolerance > 0.0 {
                            d / tolerance
                        } else {
                            f64::INFINITY
                        };
                        if worst.as_ref().is_none_or(|(w, _)| ratio > *w) {
                            worst = Some((
                                ratio,
                                Divergence {
                                    t,
                                    rod: r,
                                    rod_name: rod.name.clone(),
                                    node: i,
                                    quantity: name,
                                    a: va,
                                    b: vb,
                                    difference: d,
                                    tolerance: *tolerance,
                                    step_a,
                                    step_b,
                                    resolution,
                                },
                            ));
                        }
                    }
                }
            }
        }
        if first.is_none() {
            first = worst.map(|w| w.1);
        }
        let (ta, tb) = (na.t, nb.t);
        if ta == t {
            a.advance()?;
        }
        if tb == t {
            b.advance()?;
        }
    }
    // The rest of the longer run: its detector, contact changes and end.
    while a.next.is_some() {
        a.advance()?;
    }
    while b.next.is_some() {
        b.advance()?;
    }
    for nd in &mut nodes {
        for (q, name) in ["position", "velocity", "reaction"].into_iter().enumerate() {
            if nd.over[q] {
                nd.exceeds.push(name);
            }
        }
    }
    let (ta, tb) = (a.t_end, b.t_end);
    let end = ta.min(tb);
    let time_tol = |t: f64| {
        tol.tol_time
            .unwrap_or_else(|| a.dt_at(t).max(b.dt_at(t)) * (1.0 + 1e-9))
    };
    let span = Span {
        a_t_end: ta,
        b_t_end: tb,
        compared_to: end,
        differs: (ta - tb).abs() > time_tol(end),
    };
    let (counts, events) = contact_diff(&a, &b, tol, end, &time_tol);
    let end_tol = time_tol(end);
    let (ra, rb) = (a.reference(), b.reference());
    let (tha, thb) = (a.det.th, b.det.th);
    let fa = a.det.finish();
    let fb = b.det.finish();
    let findings = finding_diff(&fa, &fb, end + end_tol, tol.event_window);

    let within_tolerance = !span.differs
        && first.is_none()
        && counts.shifted == 0
        && counts.only_a == 0
        && counts.only_b == 0
        && findings.is_empty();
    Ok(DiffReport {
        report_version: REPORT_VERSION,
        a: ra,
        b: rb,
        tolerances: *tol,
        thresholds_a: tha,
        thresholds_b: thb,
        within_tolerance,
        parameters,
        span,
        samples,
        skipped_in_gaps,
        first_divergence: first,
        fingerprints,
        first_bitwise_divergence: bitwise,
        nodes,
        contact_event_counts: counts,
        contact_events: events,
        counts_a: fa.counts(),
        counts_b: fb.counts(),
        findings,
        findings_a: fa,
        findings_b: fb,
    })
}

/// Two recorded arrays of one quantity agree to f32 resolution: every pair of values differs
/// by at most one f32 unit in the last place at the arrays' largest magnitude (a velocity
/// component near 0 is judged at the scale of the rod's velocities, not its own).
fn f32_agree(a: &[f64], b: &[f64]) -> bool {
    let scale = a.iter().chain(b).fold(0.0f64, |m, x| m.max(x.abs()));
    let ulp = f64::from(f32::EPSILON) * scale;
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= ulp)
}

/// Contact events, paired by (rod, node, change, obstacle) and nearest time.
fn contact_diff(
    a: &Side<'_>,
    b: &Side<'_>,
    tol: &Tolerances,
    end: f64,
    time_tol: &dyn Fn(f64) -> f64,
) -> (EventCounts, Vec<EventDiff>) {
    let name = |r: usize| a.head.meta.rods[r].name.clone();
    pair_events(&a.events, &b.events, &name, tol.event_window, end, time_tol)
}

/// Contact events of two runs up to `end`, paired by (rod, node, change, obstacle) and
/// nearest time within `window`; a pair further apart than `time_tol` is `shifted`.
pub(crate) fn pair_events(
    a: &[Ev],
    b: &[Ev],
    name: &dyn Fn(usize) -> String,
    window: f64,
    end: f64,
    time_tol: &dyn Fn(f64) -> f64,
) -> (EventCounts, Vec<EventDiff>) {
    let in_span = |t: f64| t <= end + time_tol(end);
    let ea: Vec<&Ev> = a.iter().filter(|c| in_span(c.t)).collect();
    let eb: Vec<&Ev> = b.iter().filter(|c| in_span(c.t)).collect();
    let mut used = vec![false; eb.len()];
    let mut counts = EventCounts {
        a: ea.len(),
        b: eb.len(),
        ..EventCounts::default()
    };
    let mut events = Vec::new();
    // B's events by (rod, node, change, obstacle), so pairing looks at one node's events only.
    let mut groups: BTreeMap<(usize, usize, &str, usize), Vec<usize>> = BTreeMap::new();
    for (j, y) in eb.iter().enumerate() {
        groups
            .entry((y.rod, y.node, y.change.as_str(), y.obstacle))
            .or_default()
            .push(j);
    }
    let event = |status, x: &Ev, ta: Option<&Ev>, tb: Option<&Ev>| EventDiff {
        status,
        rod: x.rod,
        rod_name: name(x.rod),
        node: x.node,
        change: x.change.clone(),
        obstacle: x.obstacle,
        t_a: ta.map(|e| e.t),
        t_b: tb.map(|e| e.t),
        step_a: ta.map(|e| e.step),
        step_b: tb.map(|e| e.step),
        shift: ta.zip(tb).map(|(p, q)| q.t - p.t),
    };
    for x in &ea {
        let best = groups
            .get(&(x.rod, x.node, x.change.as_str(), x.obstacle))
            .into_iter()
            .flatten()
            .map(|&j| (j, eb[j]))
            .filter(|(j, y)| !used[*j] && (y.t - x.t).abs() <= window)
            .min_by(|p, q| (p.1.t - x.t).abs().total_cmp(&(q.1.t - x.t).abs()));
        match best {
            Some((j, y)) => {
                used[j] = true;
                counts.matched += 1;
                if (y.t - x.t).abs() > time_tol(x.t.min(y.t)) {
                    counts.shifted += 1;
                    events.push(event("shifted", x, Some(x), Some(y)));
                }
            }
            None => {
                counts.only_a += 1;
                events.push(event("only_a", x, Some(x), None));
            }
        }
    }
    for (j, y) in eb.iter().enumerate() {
        if !used[j] {
            counts.only_b += 1;
            events.push(event("only_b", y, None, Some(y)));
        }
    }
    events.sort_by(|p, q| {
        let t = |e: &EventDiff| e.t_a.or(e.t_b).unwrap_or(0.0);
        t(p).total_cmp(&t(q))
    });
    (counts, events)
}

/// Findings of one run with no counterpart (same category, kind, rod and node within
/// `window` seconds) in the other.
fn finding_diff(fa: &Findings, fb: &Findings, end: f64, window: f64) -> Vec<FindingDiff> {
    let list = |f: &Findings| -> Vec<FindingItem> {
        f.spikes
            .iter()
            .map(|s| {
                (
                    ("spike", s.kind, s.rod, s.node),
                    s.rod_name.clone(),
                    s.step,
                    s.t,
                )
            })
            .chain(f.sticking.iter().map(|s| {
                (
                    ("sticking", s.rule, s.rod, s.node),
                    s.rod_name.clone(),
                    s.step,
                    s.t,
                )
            }))
            .filter(|x| x.3 <= end)
            .collect()
    };
    pair_findings(&list(fa), &list(fb), window)
}

/// What `finding_diff` pairs: (category, kind, rod, node), rod name, step, time.
pub(crate) type FindingKey = (&'static str, &'static str, usize, usize);
pub(crate) type FindingItem = (FindingKey, String, u64, f64);

/// Findings of one run with no counterpart (same key within `window` seconds) in the other.
pub(crate) fn pair_findings(
    la: &[FindingItem],
    lb: &[FindingItem],
    window: f64,
) -> Vec<FindingDiff> {
    let mut used_b = vec![false; lb.len()];
    let mut used_a = vec![false; la.len()];
    let mut groups: BTreeMap<FindingKey, Vec<usize>> = BTreeMap::new();
    for (j, y) in lb.iter().enumerate() {
        groups.entry(y.0).or_default().push(j);
    }
    for (i, x) in la.iter().enumerate() {
        let best = groups
            .get(&x.0)
            .into_iter()
            .flatten()
            .map(|&j| (j, &lb[j]))
            .filter(|(j, y)| !used_b[*j] && (y.3 - x.3).abs() <= window)
            .min_by(|p, q| (p.1 .3 - x.3).abs().total_cmp(&(q.1 .3 - x.3).abs()));
        if let Some((j, _)) = best {
            used_b[j] = true;
            used_a[i] = true;
        }
    }
    let mut out: Vec<FindingDiff> = Vec::new();
    for (status, l, used) in [("only_a", la, &used_a), ("only_b", lb, &used_b)] {
        for (x, u) in l.iter().zip(used.iter()) {
            if !u {
                out.push(FindingDiff {
                    status,
                    category: x.0 .0,
                    kind: x.0 .1,
                    rod: x.0 .2,
                    rod_name: x.1.clone(),
                    node: x.0 .3,
                    step: x.2,
                    t: x.3,
                });
            }
        }
    }
    out.sort_by(|p, q| p.t.total_cmp(&q.t));
    out
}

fn g(x: f64) -> String {
    super::g(x)
}

/// The human form of a diff report.
pub fn format_diff(rep: &DiffReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    for (tag, r) in [("A", &rep.a), ("B", &rep.b)] {
        let _ = writeln!(
            s,
            "{tag}  {}  ({}, {} steps to t = {} s{})",
            r.file,
            r.scenario,
            r.steps,
            g(r.t_end),
            if r.truncated.is_some() {
                ", INCOMPLETE"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(s);
    if rep.parameters.is_empty() {
        let _ = writeln!(s, "parameters       identical");
    } else {
        let _ = writeln!(s, "parameters       {} differ", rep.parameters.len());
        let show = |v: &Option<serde_json::Value>| match v {
            None => "(absent)".to_string(),
            Some(x) => x.to_string(),
        };
        let _ = writeln!(s, "  {:<28} {:>22} {:>22}", "key", "A", "B");
        for p in rep.parameters.iter().take(super::MAX_ROWS) {
            let _ = writeln!(s, "  {:<28} {:>22} {:>22}", p.key, show(&p.a), show(&p.b));
        }
    }
    let _ = writeln!(
        s,
        "span             A to {} s, B to {} s; compared at {} times up to {} s{}",
        g(rep.span.a_t_end),
        g(rep.span.b_t_end),
        rep.samples,
        g(rep.span.compared_to),
        if rep.span.differs { "  DIFFERS" } else { "" }
    );
    if rep.skipped_in_gaps > 0 {
        let _ = writeln!(
            s,
            "decimated        {} step times fall in gaps of a --detail auto recording: not compared",
            rep.skipped_in_gaps
        );
    }
    match &rep.first_divergence {
        None => {
            let _ = writeln!(s, "first divergence none");
        }
        Some(d) => {
            let _ = writeln!(
                s,
                "first divergence t = {} s, rod {:?} node {}, {}: |A - B| = {} > {} (A step {}, B step {})",
                g(d.t),
                d.rod_name,
                d.node,
                d.quantity,
                g(d.difference),
                g(d.tolerance),
                d.step_a,
                d.step_b
            );
            if d.resolution > 0.0 {
                let _ = writeln!(
                    s,
                    "                 (beyond the f32 rounding of the recorded values, {})",
                    g(d.resolution)
                );
            }
        }
    }
    match (&rep.first_bitwise_divergence, rep.fingerprints) {
        (_, false) => {
            let _ = writeln!(
                s,
                "bit for bit      not compared: a run without step fingerprints (format 3 or older)"
            );
        }
        (None, true) => {
            let _ = writeln!(s, "bit for bit      identical at every step both runs hold");
        }
        (Some(b), true) => {
            let why = match (b.what, b.below_f32_resolution) {
                ("time", _) => "the step ends at another time".to_string(),
                (_, true) => "the exact states differ (fingerprints), below the recording's f32 resolution (every recorded position, velocity and reaction agrees to one f32 unit)".to_string(),
                _ => "the exact states differ (fingerprints)".to_string(),
            };
            let _ = writeln!(
                s,
                "first bitwise    step {} (t = {} s): {why}",
                b.step,
                g(b.t)
            );
        }
    }
    let over: Vec<&NodeDiff> = rep.nodes.iter().filter(|n| !n.exceeds.is_empty()).collect();
    let _ = writeln!(
        s,
        "\nper node maxima   ({} of {} nodes over tolerance: position {} m, velocity {} m/s, reaction {} N)",
        over.len(),
        rep.nodes.len(),
        g(rep.tolerances.tol_position),
        g(rep.tolerances.tol_velocity),
        g(rep.tolerances.tol_reaction)
    );
    let _ = writeln!(
        s,
        "  {:<10} {:>4}  {:>10} {:>10}  {:>10} {:>10}  {:>10} {:>10}",
        "rod", "node", "|dq| m", "at t", "|du| m/s", "at t", "|dR| N", "at t"
    );
    let mark = |n: &NodeDiff, q: &str| if n.exceeds.contains(&q) { "*" } else { " " };
    for n in rep.nodes.iter().take(super::MAX_ROWS) {
        let _ = writeln!(
            s,
            "  {:<10} {:>4}  {:>9}{} {:>10}  {:>9}{} {:>10}  {:>9}{} {:>10}",
            n.rod_name,
            n.node,
            g(n.position.max),
            mark(n, "position"),
            g(n.position.t),
            g(n.velocity.max),
            mark(n, "velocity"),
            g(n.velocity.t),
            g(n.reaction.max),
            mark(n, "reaction"),
            g(n.reaction.t)
        );
    }
    if rep.nodes.len() > super::MAX_ROWS {
        let _ = writeln!(
            s,
            "  … and {} more nodes (all in --json)",
            rep.nodes.len() - super::MAX_ROWS
        );
    }
    let c = &rep.contact_event_counts;
    let _ = writeln!(
        s,
        "\ncontact events   A {}, B {}: {} paired ({} shifted), {} only in A, {} only in B",
        c.a, c.b, c.matched, c.shifted, c.only_a, c.only_b
    );
    if !rep.contact_events.is_empty() {
        let _ = writeln!(
            s,
            "  {:<8} {:<10} {:>4} {:<9} {:>12} {:>12} {:>11}",
            "status", "rod", "node", "change", "t A (s)", "t B (s)", "shift (s)"
        );
        let opt = |x: Option<f64>| x.map(g).unwrap_or_else(|| "-".into());
        for e in rep.contact_events.iter().take(super::MAX_ROWS) {
            let _ = writeln!(
                s,
                "  {:<8} {:<10} {:>4} {:<9} {:>12} {:>12} {:>11}",
                e.status,
                e.rod_name,
                e.node,
                e.change,
                opt(e.t_a),
                opt(e.t_b),
                opt(e.shift)
            );
        }
        if rep.contact_events.len() > super::MAX_ROWS {
            let _ = writeln!(
                s,
                "  … and {} more (all in --json)",
                rep.contact_events.len() - super::MAX_ROWS
            );
        }
    }
    let _ = writeln!(
        s,
        "\nspikes           A {} (impact {}, unexplained {}), B {} (impact {}, unexplained {})",
        rep.counts_a.spikes,
        rep.counts_a.impact,
        rep.counts_a.unexplained,
        rep.counts_b.spikes,
        rep.counts_b.impact,
        rep.counts_b.unexplained
    );
    let _ = writeln!(
        s,
        "sticking         A {}, B {}",
        rep.counts_a.sticking, rep.counts_b.sticking
    );
    if !rep.findings.is_empty() {
        let _ = writeln!(s, "found in one run only");
        let _ = writeln!(
            s,
            "  {:<8} {:<9} {:<14} {:<10} {:>4} {:>9} {:>12}",
            "status", "category", "kind", "rod", "node", "step", "t (s)"
        );
        for f in rep.findings.iter().take(super::MAX_ROWS) {
            let _ = writeln!(
                s,
                "  {:<8} {:<9} {:<14} {:<10} {:>4} {:>9} {:>12}",
                f.status,
                f.category,
                f.kind,
                f.rod_name,
                f.node,
                f.step,
                g(f.t)
            );
        }
        if rep.findings.len() > super::MAX_ROWS {
            let _ = writeln!(
                s,
                "  … and {} more (all in --json)",
                rep.findings.len() - super::MAX_ROWS
            );
        }
    }
    let _ = writeln!(
        s,
        "\n{}",
        if rep.within_tolerance {
            "WITHIN TOLERANCE (exit 0)"
        } else {
            "DIFFERENT (exit 1)"
        }
    );
    s
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        tol: Tolerances,
    }

    #[test]
    fn flag_defaults_are_the_documented_defaults() {
        let cli = Cli::try_parse_from(["x"]).unwrap();
        assert_eq!(cli.tol, Tolerances::DEFAULT);
    }

    #[test]
    fn scenario_tables_flatten_to_dotted_paths() {
        let t: toml::Table = "a = 1\n[solve]\ngravity = [0.0, -9.8]\n[[rod]]\nE = 1e6\n[[rod]]\nE = 2e6\nshape = { kind = \"straight\" }\n"
            .parse()
            .unwrap();
        let mut m = BTreeMap::new();
        flatten("", &toml::Value::Table(t), &mut m);
        let keys: Vec<&str> = m.keys().map(|k| k.as_str()).collect();
        assert_eq!(
            keys,
            [
                "a",
                "rod.0.E",
                "rod.1.E",
                "rod.1.shape.kind",
                "solve.gravity"
            ]
        );
    }
}
