//! `replay diff` on two 3D runs: what the planar diff reports ([`super::diff`]), from the
//! 3D MCAPs. Run B is interpolated linearly at run A's step times; the report lists the
//! scenario values that differ, the largest node position and velocity differences (and
//! where), the first time either exceeds its tolerance, the runs' ends, contact events found
//! in one run only or shifted in time, and spikes or sticking found in one run only (each
//! run's own `replay check`).

use super::detect::Thresholds;
use super::diff::{
    differing_values, flatten, pair_events, pair_findings, Ev, EventCounts, EventDiff, FindingDiff,
    FindingItem, ParamDiff, Span, Tolerances,
};
use super::three::{locate_b, node_between, AtB, Check3Report, Detector3, Run3};
use super::ReplayError;
use crate::record::mcap3::Step3;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The largest difference of one quantity over all nodes and compared steps, and where.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Worst3 {
    pub max: f64,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    pub t: f64,
}

/// The first compared time a node's position or velocity differs beyond its tolerance.
#[derive(Debug, Clone, Serialize)]
pub struct Divergence3 {
    pub t: f64,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// `position` or `velocity`.
    pub quantity: &'static str,
    pub a: [f64; 3],
    pub b: [f64; 3],
    pub difference: f64,
    pub tolerance: f64,
}

/// What each run's own check found.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Counts3 {
    pub spikes: usize,
    pub sticking: usize,
    pub grasp: usize,
}

/// The comparison of two 3D runs.
#[derive(Debug, Clone, Serialize)]
pub struct Diff3Report {
    pub a: String,
    pub b: String,
    pub compared_steps: u64,
    /// The largest node distance: its value, rod, node and time (kept flat: the fields of
    /// the first 3D diff report).
    pub max_distance: f64,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    pub t: f64,
    /// The largest node distance at A's last compared step.
    pub final_distance: f64,
    pub tol_position: f64,
    /// The largest node velocity difference (m/s).
    pub velocity: Worst3,
    pub tolerances: Tolerances,
    pub first_divergence: Option<Divergence3>,
    /// Scenario values (after each run's `--set` overrides) that differ, by dotted path.
    pub parameters: Vec<ParamDiff>,
    pub span: Span,
    pub contact_event_counts: EventCounts,
    pub contact_events: Vec<EventDiff>,
    pub counts_a: Counts3,
    pub counts_b: Counts3,
    /// Spikes and sticking found in one run only.
    pub findings: Vec<FindingDiff>,
    pub within_tolerance: bool,
    /// A recording stops before its run's end (truncated, or no run end).
    pub incomplete: bool,
}

/// The flattened scenario of a run, its overrides applied.
fn values(run: &Run3) -> BTreeMap<String, toml::Value> {
    let mut m = BTreeMap::new();
    if let Ok(mut t) = run.scenario_text.parse::<toml::Table>() {
        if crate::scenario::apply_sets(&mut t, &run.sets, "").is_ok() {
            flatten("", &toml::Value::Table(t), &mut m);
        }
    }
    m
}

/// A run's accepted contact changes and its own check.
fn side(path: &Path, run: &Run3, th: &Thresholds) -> Result<(Vec<Ev>, Check3Report), ReplayError> {
    let mut d = Detector3::new(&run.scenario, th).map_err(|e| ReplayError::file(path, e))?;
    let mut events = Vec::new();
    for s in &run.steps {
        d.step(s);
        events.extend(s.changes.iter().map(|c| Ev {
            rod: c.rod as usize,
            node: c.node as usize,
            change: if c.added { "added" } else { "released" }.to_string(),
            obstacle: 0,
            t: s.t,
            step: s.step,
        }));
    }
    Ok((events, d.finish(&path.display().to_string(), &run.name)))
}

/// A check's spikes and sticking as the diff pairs them.
fn findings(c: &Check3Report) -> Vec<FindingItem> {
    let spikes = c.spikes.iter().map(|s| {
        (
            ("spike", s.kind, s.rod, s.node),
            s.rod_name.clone(),
            s.step,
            s.t,
        )
    });
    let sticking = c.sticking.iter().map(|s| {
        (
            ("sticking", s.rule, s.rod, s.node),
            s.rod_name.clone(),
            s.step,
            s.t,
        )
    });
    spikes.chain(sticking).collect()
}

fn counts(c: &Check3Report) -> Counts3 {
    Counts3 {
        spikes: c.spikes.len(),
        sticking: c.sticking.len(),
        grasp: c.grasp.len(),
    }
}

/// The step of `run` at or just after `t`: its step size.
fn dt_at(run: &Run3, t: f64) -> f64 {
    let k = run.steps.partition_point(|s| s.t < t);
    run.steps
        .get(k.min(run.steps.len().saturating_sub(1)))
        .map_or(0.0, |s| s.dt)
}

fn nodes_per_rod(r: &Run3) -> Vec<usize> {
    r.steps
        .first()
        .map(|s| s.rods.iter().map(|r| r.x.len() / 3).collect())
        .unwrap_or_default()
}

/// Node `i` of rod `r` of a step, position or velocity.
fn at(s: &Step3, r: usize, i: usize, velocity: bool) -> [f64; 3] {
    let v = if velocity { &s.rods[r].v } else { &s.rods[r].x };
    [0, 1, 2].map(|k| v[3 * i + k])
}

/// Velocity of B between two steps, as [`node_between`] does positions.
fn velocity_between(b0: &Step3, b1: &Step3, w: f64, r: usize, i: usize) -> [f64; 3] {
    let (p, q) = (at(b0, r, i, true), at(b1, r, i, true));
    [0, 1, 2].map(|k| (1.0 - w) * p[k] + w * q[k])
}

/// The node-by-node comparison: the report's distance, velocity and divergence fields.
struct Compare<'a> {
    names: &'a [String],
    tol: &'a Tolerances,
    steps: u64,
    dist: Worst3,
    vel: Worst3,
    final_distance: f64,
    first: Option<Divergence3>,
}

impl Compare<'_> {
    /// One of A's steps against B at its time.
    fn step(&mut self, sa: &Step3, b0: &Step3, b1: &Step3, w: f64) {
        let mut step_max = 0.0f64;
        let mut worst: Option<(f64, Divergence3)> = None;
        let rods = sa.rods.len().min(b0.rods.len()).min(b1.rods.len());
        for r in 0..rods {
            for i in 0..sa.rods[r].x.len() / 3 {
                let pairs = [
                    (
                        "position",
                        at(sa, r, i, false),
                        node_between(b0, b1, w, r, i),
                    ),
                    (
                        "velocity",
                        at(sa, r, i, true),
                        velocity_between(b0, b1, w, r, i),
                    ),
                ];
                for (q, (quantity, xa, xb)) in pairs.into_iter().enumerate() {
                    let d = super::three::norm([0, 1, 2].map(|k| xa[k] - xb[k]));
                    let (worst_q, tolerance) = if q == 0 {
                        step_max = step_max.max(d);
                        (&mut self.dist, self.tol.tol_position)
                    } else {
                        (&mut self.vel, self.tol.tol_velocity)
                    };
                    if d > worst_q.max {
                        *worst_q = Worst3 {
                            max: d,
                            rod: r,
                            rod_name: String::new(),
                            node: i,
                            t: sa.t,
                        };
                    }
                    let ratio = if tolerance > 0.0 {
                        d / tolerance
                    } else {
                        f64::INFINITY
                    };
                    if self.first.is_none()
                        && d > tolerance
                        && worst.as_ref().is_none_or(|(w, _)| ratio > *w)
                    {
                        let rod_name = self.names.get(r).cloned().unwrap_or_default();
                        let (a, b, t) = (xa, xb, sa.t);
                        let div = Divergence3 {
                            t,
                            rod: r,
                            rod_name,
                            node: i,
                            quantity,
                            a,
                            b,
                            difference: d,
                            tolerance,
                        };
                        worst = Some((ratio, div));
                    }
                }
            }
        }
        if self.first.is_none() {
            self.first = worst.map(|w| w.1);
        }
        self.final_distance = step_max;
        self.steps += 1;
    }
}

/// `replay diff` on two 3D runs.
pub fn diff(
    a: &Path,
    b: &Path,
    tol: &Tolerances,
    th: &Thresholds,
) -> Result<Diff3Report, ReplayError> {
    let (ra, rb) = (Run3::load(a)?, Run3::load(b)?);
    if nodes_per_rod(&ra) != nodes_per_rod(&rb) {
        return Err(ReplayError::new(format!(
            "{} and {}: the runs' rods differ (nodes per rod {:?} vs {:?}): not comparable",
            a.display(),
            b.display(),
            nodes_per_rod(&ra),
            nodes_per_rod(&rb)
        )));
    }
    let names = crate::rod3d::run3::build(&ra.scenario)
        .map(|(w, _)| w.rod_names)
        .unwrap_or_default();
    let mut cmp = Compare {
        names: &names,
        tol,
        steps: 0,
        dist: Worst3::default(),
        vel: Worst3::default(),
        final_distance: 0.0,
        first: None,
    };
    let mut j = 0;
    for sa in &ra.steps {
        match locate_b(&rb, &mut j, sa.t) {
            AtB::Before => continue,
            AtB::After => break,
            AtB::Between(k0, k1, w) => cmp.step(sa, &rb.steps[k0], &rb.steps[k1], w),
        }
    }
    for w in [&mut cmp.dist, &mut cmp.vel] {
        w.rod_name = names.get(w.rod).cloned().unwrap_or_default();
    }
    let ((ea, ca), (eb, cb)) = (side(a, &ra, th)?, side(b, &rb, th)?);
    let end_of = |r: &Run3| r.steps.last().map_or(0.0, |s| s.t);
    let (ta, tb) = (end_of(&ra), end_of(&rb));
    let end = ta.min(tb);
    let time_tol = |t: f64| {
        tol.tol_time
            .unwrap_or_else(|| dt_at(&ra, t).max(dt_at(&rb, t)) * (1.0 + 1e-9))
    };
    let span = Span {
        a_t_end: ta,
        b_t_end: tb,
        compared_to: end,
        differs: (ta - tb).abs() > time_tol(end),
    };
    let name = |r: usize| names.get(r).cloned().unwrap_or_default();
    let (event_counts, events) = pair_events(&ea, &eb, &name, tol.event_window, end, &time_tol);
    let in_span = |f: &Vec<FindingItem>| -> Vec<FindingItem> {
        f.iter()
            .filter(|x| x.3 <= end + time_tol(end))
            .cloned()
            .collect()
    };
    let found = pair_findings(
        &in_span(&findings(&ca)),
        &in_span(&findings(&cb)),
        tol.event_window,
    );
    let within_tolerance = !span.differs
        && cmp.first.is_none()
        && event_counts.shifted == 0
        && event_counts.only_a == 0
        && event_counts.only_b == 0
        && found.is_empty();
    Ok(Diff3Report {
        a: a.display().to_string(),
        b: b.display().to_string(),
        compared_steps: cmp.steps,
        max_distance: cmp.dist.max,
        rod: cmp.dist.rod,
        rod_name: cmp.dist.rod_name.clone(),
        node: cmp.dist.node,
        t: cmp.dist.t,
        final_distance: cmp.final_distance,
        tol_position: tol.tol_position,
        velocity: cmp.vel,
        tolerances: *tol,
        first_divergence: cmp.first,
        parameters: differing_values(&values(&ra), &values(&rb)),
        span,
        contact_event_counts: event_counts,
        contact_events: events,
        counts_a: counts(&ca),
        counts_b: counts(&cb),
        findings: found,
        within_tolerance,
        incomplete: ra.incomplete() || rb.incomplete(),
    })
}

fn json(v: &Option<serde_json::Value>) -> String {
    v.as_ref().map_or("(absent)".into(), |v| v.to_string())
}

/// The text report of a 3D diff.
pub fn format_diff(r: &Diff3Report) -> String {
    use std::fmt::Write;
    let mut s = format!(
        "{} vs {} (3D): {} steps compared\n",
        r.a, r.b, r.compared_steps
    );
    for p in &r.parameters {
        let _ = writeln!(s, "parameter {}: A {} B {}", p.key, json(&p.a), json(&p.b));
    }
    let _ = writeln!(
        s,
        "largest node distance {:.6e} m ({} node {} at t = {:.6} s), {:.6e} m at the last step; tolerance {:e} m",
        r.max_distance, r.rod_name, r.node, r.t, r.final_distance, r.tolerances.tol_position
    );
    let v = &r.velocity;
    let _ = writeln!(
        s,
        "largest node velocity difference {:.6e} m/s ({} node {} at t = {:.6} s); tolerance {:e} m/s",
        v.max, v.rod_name, v.node, v.t, r.tolerances.tol_velocity
    );
    if let Some(d) = &r.first_divergence {
        let _ = writeln!(
            s,
            "first divergence at t = {:.6} s: {} node {} {} differs by {:.3e} (tolerance {:e})",
            d.t, d.rod_name, d.node, d.quantity, d.difference, d.tolerance
        );
    }
    let sp = &r.span;
    let _ = writeln!(
        s,
        "runs end at A {} s, B {} s{}",
        super::g(sp.a_t_end),
        super::g(sp.b_t_end),
        if sp.differs { " (DIFFERENT)" } else { "" }
    );
    let c = &r.contact_event_counts;
    let _ = writeln!(
        s,
        "contact events   A {}, B {}: {} paired ({} shifted), {} only in A, {} only in B",
        c.a, c.b, c.matched, c.shifted, c.only_a, c.only_b
    );
    for e in &r.contact_events {
        let t = |x: Option<f64>| x.map_or("-".into(), |t| format!("{t:.6}"));
        let _ = writeln!(
            s,
            "  {} {} node {} {}: t A {} s, B {} s",
            e.status,
            e.rod_name,
            e.node,
            e.change,
            t(e.t_a),
            t(e.t_b)
        );
    }
    let _ = writeln!(
        s,
        "findings         A {} spike(s) {} sticking, B {} spike(s) {} sticking; {} found in one run only",
        r.counts_a.spikes, r.counts_a.sticking, r.counts_b.spikes, r.counts_b.sticking, r.findings.len()
    );
    for f in &r.findings {
        let _ = writeln!(
            s,
            "  {} {} {}: {} node {} step {} t = {:.6} s",
            f.status, f.category, f.kind, f.rod_name, f.node, f.step, f.t
        );
    }
    s += if r.within_tolerance {
        "within tolerance\n"
    } else {
        "DIFFERENT\n"
    };
    s
}
