//! Replay of 3D runs (`dimension = 3`): `replay check`, `diff` and `show` on the MCAP of
//! `gripsim run --mcap` (src/record/mcap3.rs, `/sim/step` of schema `gripsim.Step3`), and the
//! detector behind `run --check` on a 3D scenario.
//!
//! The rules are the planar ones ([`super::detect`]) with three components:
//! * **Spike** (per free node and step): e = Δv − Δt f(q_{k+1})/m, f the elastic force (the
//!   3D rod's energy gradient at the recorded configuration, with the reference frames carried
//!   along the recorded steps exactly as the solver carries them) plus gravity. A node in
//!   contact explains, along its contact normal, support (up to what the forces push into the
//!   surface) and impact (up to the normal velocity it brought into the step), and tangentially
//!   up to μ_s times that (the Coulomb cone); `impact` is flagged when the impact jump is
//!   ≥ `spike_floor` and jump × Δt ≥ `spike_displacement`, `unexplained` when the rest is
//!   ≥ `spike_floor` and ≥ `spike_accel_ratio` × max(a, |f|/m) × Δt.
//! * **Sticking** (`toggling`): ≥ `stick_toggles` contact changes of one node within
//!   `stick_window` seconds.
//!
//! Scales: L the largest of the prong length and the shapes' sizes (sphere and ellipsoid
//! diameters, box diagonals); a = |g| (else L/t_end²), v = √(aL), time √(L/a), dt the
//! scenario's.

use super::detect::{Effective, Scales, Sticking, Thresholds};
use super::read3::{read3, Message3, Meta3In};
use super::ReplayError;
use crate::obstacle3::Shape3;
use crate::record::mcap3::Step3;
use crate::rod3d::rod::{angle, pos};
use crate::rod3d::solver::assemble;
use crate::rod3d::Sim3;
use crate::scenario::three::Scenario3;
use serde::Serialize;
use std::collections::VecDeque;
use std::path::Path;

/// One velocity spike of a 3D run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spike3 {
    /// `impact` or `unexplained`.
    pub kind: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    pub step: u64,
    pub t: f64,
    pub dt: f64,
    /// Δv (m/s).
    pub dv: [f64; 3],
    /// |Δt f/m| (m/s).
    pub force_dv: f64,
    /// The flagged jump (m/s).
    pub jump: f64,
    pub impact_jump: f64,
    pub unexplained_jump: f64,
    /// |jump| / dt over the scale it is compared with.
    pub accel_ratio: f64,
    /// |jump| × dt (m).
    pub displacement: f64,
    pub in_contact: bool,
}

/// What `replay check` (and `run --check`) finds in a 3D run.
#[derive(Debug, Clone, Serialize)]
pub struct Check3Report {
    pub file: String,
    pub scenario: String,
    pub dimension: u32,
    pub steps: u64,
    pub t_end: f64,
    /// Why the file was read only in part (null when whole).
    pub truncated: Option<String>,
    /// The run's own end: true, false for a run that failed, or null when the file has no
    /// run-end record.
    pub completed: Option<bool>,
    /// Why the run failed (its run-end record's error).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub run_error: Option<String>,
    /// The recording stops before its run's end (truncated, or no run end).
    pub incomplete: bool,
    pub scales: Scales,
    pub thresholds: Effective,
    pub flagged: bool,
    pub spikes: Vec<Spike3>,
    pub sticking: Vec<Sticking>,
    /// A fruit that slipped in the gripper during the lift or was dropped (the planar rule,
    /// [`super::grasp`]; runs with a free fruit only).
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub grasp: Vec<super::grasp::GraspFlag>,
    /// The slips and drops the scenario expects (`[expect] grasp`): not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub grasp_expected: Vec<super::grasp::GraspFlag>,
    /// Contacts above the compliant fruit's bruise pressure, found on the live run's contact
    /// pressures (`gripsim run --check`; [`Check3Report::add_bruise`]). A 3D recording does
    /// not keep the pressures, so `replay check` of a 3D file finds none; a rigid fruit has
    /// none.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub bruise: Vec<super::bruise::BruiseFlag>,
    /// The bruises the scenario expects (`[expect] bruised = true`): not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty", default)]
    pub bruise_expected: Vec<super::bruise::BruiseFlag>,
    /// The scenario expects a bruise and the run made none (flagged).
    #[serde(skip_serializing_if = "std::ops::Not::not", default)]
    pub bruise_missing: bool,
}

impl Check3Report {
    /// What the live bruise rule found: flagged unless the scenario expects it; a bruise the
    /// scenario expects and the run did not make is flagged.
    pub fn add_bruise(&mut self, found: super::bruise::BruiseObserver) {
        let (expected, count) = (found.expected(), found.count());
        let flags = found.finish();
        if expected {
            self.bruise_missing = flags.is_empty();
            self.bruise_expected = flags;
        } else {
            self.bruise = flags;
        }
        self.flagged |= count > 0;
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn axpy(a: f64, x: [f64; 3], y: [f64; 3]) -> [f64; 3] {
    [y[0] + a * x[0], y[1] + a * x[1], y[2] + a * x[2]]
}

/// The scales of a 3D scene (module documentation).
pub fn scales(sc: &Scenario3) -> Scales {
    let mut length: f64 = sc
        .prong
        .points
        .windows(2)
        .map(|w| norm(sub(w[1], w[0])))
        .sum();
    let size = |s: &Shape3| match s {
        Shape3::Sphere { radius } => 2.0 * radius,
        Shape3::Ellipsoid { semi_axes } => 2.0 * semi_axes.iter().fold(0.0f64, |a, b| a.max(*b)),
        Shape3::Box { half } => 2.0 * norm(*half),
        Shape3::Mesh(m) => 2.0 * m.radius,
        Shape3::Plane => 0.0,
    };
    for o in &sc.obstacles {
        length = length.max(size(&o.shape));
    }
    if let Some(f) = &sc.fruit {
        length = length.max(size(&f.shape));
    }
    if !(length > 0.0) {
        length = 1.0;
    }
    let mut accel = norm(sc.gravity);
    if !(accel > 0.0) {
        let t = sc.t_end.unwrap_or(1.0);
        accel = length / (t * t);
    }
    Scales {
        length,
        acceleration: accel,
        velocity: (accel * length).sqrt(),
        time: (length / accel).sqrt(),
        dt: sc.dt,
    }
}

#[derive(Debug, Clone, Default)]
struct NodeState {
    changes: VecDeque<(u64, f64)>,
    open: Option<Sticking>,
}

/// The spike and sticking rules over the steps of a 3D run.
pub struct Detector3 {
    pub scales: Scales,
    pub th: Effective,
    sims: Vec<Sim3>,
    names: Vec<String>,
    mu: f64,
    prev_v: Vec<Vec<f64>>,
    have_prev: bool,
    grad: Vec<f64>,
    q: Vec<f64>,
    nodes: Vec<Vec<NodeState>>,
    grasp: Option<super::grasp::GraspRule>,
    pub spikes: Vec<Spike3>,
    pub sticking: Vec<Sticking>,
    pub steps: u64,
    pub t_end: f64,
}

impl Detector3 {
    pub fn new(sc: &Scenario3, th: &Thresholds) -> Result<Detector3, String> {
        let (w, _) = crate::rod3d::run3::build(sc)?;
        let scales = scales(sc);
        let mut sims = w.rods;
        for s in &mut sims {
            s.gravity = sc.gravity;
        }
        // The largest static friction coefficient of any prong-surface pair (the cone that
        // bounds the tangential part of an impact).
        let mut mu = 0.0f64;
        for r in &w.rod_names {
            for o in w
                .obstacles
                .iter()
                .chain(w.bodies.iter().map(|b| &b.obstacle))
            {
                mu = mu.max(sc.friction.between(r, &o.name).mu_s);
            }
        }
        // The grasp rule on a free fruit: the gripper is the centroid of the driven nodes.
        let clamped: Vec<Vec<usize>> = sims
            .iter()
            .map(|s| (0..s.rod.n).filter(|&i| s.fixed[pos(i)]).collect())
            .collect();
        let grasp = sc.fruit.as_ref().filter(|f| f.free).map(|f| {
            super::grasp::GraspRule::of3(clamped, sc.gravity, f.hold_tolerance, sc.expect.grasp)
        });
        Ok(Detector3 {
            grasp,
            scales,
            th: Effective::for_scene(th, &scales),
            names: w.rod_names,
            mu,
            // The initial velocities: the first step's jump is judged against them.
            prev_v: sims
                .iter()
                .map(|s| {
                    (0..s.rod.n)
                        .flat_map(|i| [0, 1, 2].map(|a| s.v[pos(i) + a]))
                        .collect()
                })
                .collect(),
            have_prev: true,
            grad: Vec::new(),
            q: Vec::new(),
            nodes: sims
                .iter()
                .map(|s| vec![NodeState::default(); s.rod.n])
                .collect(),
            sims,
            spikes: vec![],
            sticking: vec![],
            steps: 0,
            t_end: 0.0,
        })
    }

    /// The reference frames of rod r as the solver carries them (after the last step fed).
    pub fn sim(&self, r: usize) -> &Sim3 {
        &self.sims[r]
    }

    /// One recorded step. Step 0 (the initial state) is where the detector starts: nothing is
    /// judged on it.
    pub fn step(&mut self, m: &Step3) {
        if m.step == 0 {
            return;
        }
        self.changes(m);
        for (r, rod) in m.rods.iter().enumerate().take(self.sims.len()) {
            let n = self.sims[r].rod.n;
            if rod.x.len() != 3 * n || rod.theta.len() + 1 != n {
                continue;
            }
            self.q.clear();
            self.q.resize(self.sims[r].q.len(), 0.0);
            for i in 0..n {
                self.q[pos(i)..pos(i) + 3].copy_from_slice(&rod.x[3 * i..3 * i + 3]);
                if i + 1 < n {
                    self.q[angle(i)] = rod.theta[i];
                }
            }
            if self.have_prev && m.dt > 0.0 && rod.v.len() == 3 * n {
                self.spikes_of(r, m, &rod.v);
            }
            // Carry the frames to this step's configuration, as the solver does on accepting it.
            let sim = &mut self.sims[r];
            sim.q.copy_from_slice(&self.q);
            sim.advance_frames();
            self.prev_v[r].clear();
            self.prev_v[r].extend_from_slice(&rod.v);
        }
        self.close_stale(m.t);
        if let (Some(g), Some(b)) = (self.grasp.as_mut(), m.bodies.first()) {
            if let [x, y, z] = b.position[..] {
                let xs: Vec<&[f64]> = m.rods.iter().map(|r| r.x.as_slice()).collect();
                let touching = m.contacts.iter().any(|c| c.shape == b.shape);
                g.step3(m.step, m.t, &xs, [x, y, z], touching);
            }
        }
        self.have_prev = true;
        self.steps += 1;
        self.t_end = m.t;
    }

    fn changes(&mut self, m: &Step3) {
        let (window, need) = (self.th.stick_window, self.th.stick_toggles);
        for c in &m.changes {
            let (r, i) = (c.rod as usize, c.node as usize);
            let Some(n) = self.nodes.get_mut(r).and_then(|v| v.get_mut(i)) else {
                continue;
            };
            n.changes.push_back((m.step, m.t));
            while n.changes.front().is_some_and(|&(_, t0)| m.t - t0 >= window) {
                n.changes.pop_front();
            }
            if n.changes.len() as u64 >= need {
                let (s0, t0) = n.changes[0];
                let ep = n.open.get_or_insert(Sticking {
                    rule: "toggling",
                    rod: r,
                    rod_name: self.names[r].clone(),
                    node: i,
                    step: s0,
                    t: t0,
                    last_step: m.step,
                    last_t: m.t,
                    count: n.changes.len() as u64 - 1,
                });
                ep.last_step = m.step;
                ep.last_t = m.t;
                ep.count += 1;
            }
        }
    }

    fn close_stale(&mut self, t: f64) {
        let sw = self.th.stick_window;
        for nodes in &mut self.nodes {
            for n in nodes.iter_mut() {
                if n.open.as_ref().is_some_and(|ep| t - ep.last_t >= sw) {
                    self.sticking.push(n.open.take().expect("checked"));
                }
            }
        }
    }

    fn spikes_of(&mut self, r: usize, m: &Step3, v: &[f64]) {
        let sim = &self.sims[r];
        self.grad.resize(sim.q.len(), 0.0);
        assemble(
            &sim.rod,
            &sim.frames,
            &sim.ref_twist,
            &self.q,
            &mut self.grad,
            None,
            &[],
        );
        // The prong's Kelvin–Voigt damping force, from the recorded positions of this step and
        // the last, as the solver adds it (its velocity jumps are the material's, not spikes).
        if sim.damping_time > 0.0 && m.dt > 0.0 {
            crate::rod3d::solver::damping_into::<crate::solver::banded::BandLu>(
                &sim.rod,
                &sim.frames,
                &self.q,
                &sim.q,
                m.dt,
                sim.damping_time,
                &mut self.grad,
                None,
                &[],
            );
        }
        let (th, dt, a_scene) = (self.th, m.dt, self.scales.acceleration);
        for i in 0..sim.rod.n {
            let k = pos(i);
            if sim.fixed[k] {
                continue;
            }
            let mass = sim.rod.mass[k];
            let f = [0, 1, 2].map(|a| sim.external(k + a) - self.grad[k + a]);
            let prev = [0, 1, 2].map(|a| self.prev_v[r][3 * i + a]);
            let dv = sub([v[3 * i], v[3 * i + 1], v[3 * i + 2]], prev);
            let fdv = f.map(|x| dt * x / mass);
            let e = sub(dv, fdv);
            let node_ref = a_scene.max(norm(f) / mass);
            let normal = m
                .contacts
                .iter()
                .find(|c| {
                    // A node's own contact, or an edge contact on a segment it ends.
                    let (k, edge) = (c.node as usize, c.weight > 0.0);
                    c.rod as usize == r && (k == i || (edge && k + 1 == i)) && c.normal.len() == 3
                })
                .map(|c| [c.normal[0], c.normal[1], c.normal[2]]);
            let (impact, rest) = match normal {
                Some(n) => {
                    let (en, fnn, un) = (dot(e, n), dot(fdv, n), dot(prev, n));
                    let support = en.clamp(0.0, (-fnn).max(0.0));
                    let impact = (en - support).clamp(0.0, (-un).max(0.0));
                    let held = support + impact;
                    let r0 = axpy(-held, n, e);
                    (impact, within_cone(r0, n, self.mu * held))
                }
                None => (0.0, e),
            };
            let unexplained = norm(rest);
            let flag_unexplained = unexplained >= th.spike_floor
                && unexplained / dt >= th.spike_accel_ratio * node_ref
                && unexplained * dt >= 1e-9 * self.scales.length;
            let flag_impact = impact >= th.spike_floor && impact * dt >= th.spike_displacement;
            let make = |kind, jump: f64, scale: f64| Spike3 {
                kind,
                rod: r,
                rod_name: self.names[r].clone(),
                node: i,
                step: m.step,
                t: m.t,
                dt,
                dv,
                force_dv: norm(fdv),
                jump,
                impact_jump: impact,
                unexplained_jump: unexplained,
                accel_ratio: jump / dt / scale,
                displacement: jump * dt,
                in_contact: normal.is_some(),
            };
            if flag_unexplained {
                let s = make("unexplained", unexplained, node_ref);
                self.spikes.push(s);
            } else if flag_impact {
                let s = make("impact", impact, a_scene);
                self.spikes.push(s);
            }
        }
    }

    /// The report; open episodes are closed at the last step.
    pub fn finish(mut self, file: &str, scenario: &str) -> Check3Report {
        for nodes in &mut self.nodes {
            for n in nodes.iter_mut() {
                if let Some(ep) = n.open.take() {
                    self.sticking.push(ep);
                }
            }
        }
        self.sticking.sort_by_key(|a| (a.step, a.rod, a.node));
        let grasp = self.grasp.take().map(|g| g.finish()).unwrap_or_default();
        Check3Report {
            file: file.to_string(),
            scenario: scenario.to_string(),
            dimension: 3,
            steps: self.steps,
            t_end: self.t_end,
            truncated: None,
            completed: Some(true),
            run_error: None,
            incomplete: false,
            scales: self.scales,
            thresholds: self.th,
            flagged: !(self.spikes.is_empty()
                && self.sticking.is_empty()
                && grasp.flags.is_empty()),
            spikes: self.spikes,
            sticking: self.sticking,
            grasp: grasp.flags,
            grasp_expected: grasp.expected,
            bruise: Vec::new(),
            bruise_expected: Vec::new(),
            bruise_missing: false,
        }
    }
}

/// The counts of a 3D check, in the planar check's terms, with `bruise` flags found on the
/// live run's contact pressures ([`super::bruise::BruiseObserver`]; a 3D recording does not
/// keep them).
pub fn counts(r: &Check3Report, bruise: usize) -> super::detect::Counts {
    let s = |k: &str| r.spikes.iter().filter(|x| x.kind == k).count();
    let g = |k: &str| r.grasp.iter().filter(|x| x.kind == k).count();
    super::detect::Counts {
        spikes: r.spikes.len(),
        impact: s("impact"),
        unexplained: s("unexplained"),
        sticking: r.sticking.len(),
        toggling: r.sticking.iter().filter(|x| x.rule == "toggling").count(),
        slip: g("slip"),
        drop: g("drop"),
        held: g("held"),
        bruise,
    }
}

/// The tangential part of `r` beyond `cone` (the Coulomb cone of the contact).
fn within_cone(r: [f64; 3], n: [f64; 3], cone: f64) -> [f64; 3] {
    if !(cone > 0.0) {
        return r;
    }
    let rn = dot(r, n);
    let t = axpy(-rn, n, r);
    let tl = norm(t);
    let k = if tl > 0.0 {
        (tl - cone).max(0.0) / tl
    } else {
        0.0
    };
    axpy(rn, n, t.map(|x| k * x))
}

/// A 3D run read back from its MCAP.
pub struct Run3 {
    pub scenario: Scenario3,
    pub name: String,
    /// `/sim/meta` `scenario_text` and `sets`: the scenario as written and its overrides.
    pub scenario_text: String,
    pub sets: Vec<String>,
    /// `/sim/meta` rods: name and node count, in the steps' order.
    pub rods: Vec<(String, usize)>,
    pub steps: Vec<Step3>,
    /// The run-end record's `completed` (None: the file has none, e.g. a killed run's).
    pub completed: Option<bool>,
    /// The run-end record's `error` (a failed run's).
    pub run_error: Option<String>,
    /// Why the file was read only in part (an unreadable message: the steps before it).
    pub truncated: Option<String>,
}

impl Run3 {
    /// The recording stops before its run's end.
    pub fn incomplete(&self) -> bool {
        self.truncated.is_some() || self.completed != Some(true)
    }
}

/// Each mesh the recording hashed must be the mesh the re-read scenario found (beside the
/// recording): a different file at that path is refused, never replayed silently.
fn same_meshes(sc: &Scenario3, shapes: &[super::read3::ShapeIn]) -> Result<(), String> {
    use crate::obstacle3::Shape3;
    let fruit = sc.fruit.iter().map(|f| (f.name.as_str(), &f.shape));
    let obstacles = sc.obstacles.iter().map(|o| (o.name.as_str(), &o.shape));
    for (name, shape) in fruit.chain(obstacles) {
        let Shape3::Mesh(m) = shape else { continue };
        let recorded = shapes
            .iter()
            .find(|s| s.name == name)
            .and_then(|s| s.mesh_hash.as_deref());
        let found = format!("{:016x}", m.source_hash);
        if let Some(r) = recorded.filter(|r| *r != found) {
            return Err(format!(
                "the mesh of {name:?} found beside the recording ({} triangles, hash {found}) \
                 is not the mesh the run used (hash {r}): put the run's mesh file there, \
                 at the path its scenario names",
                m.triangles.len()
            ));
        }
    }
    Ok(())
}

/// Whether `path` is the MCAP of a 3D run (`gripsim.Step3`, `gripsim.Meta3`): the
/// summary section's schema records are looked at (found through the footer), so a planar
/// recording is not read whole to find out.
pub fn is_3d_mcap(path: &Path) -> bool {
    summary_says_3d(path).unwrap_or_else(|| first_message_says_3d(path))
}

/// Without a summary (a file cut short): whether its first message is a 3D `/sim/meta`
/// (schema `gripsim.Meta3`), read by replay's guarded record reader (a damaged file is no 3D
/// file and is refused by the planar reader with its own words).
fn first_message_says_3d(path: &Path) -> bool {
    super::read::first_message_schema(path).is_some_and(|s| s == "gripsim.Meta3")
}

/// Whether the summary section (found through the footer) names `gripsim.Step3` or
/// `gripsim.Meta3`; None when the file has no readable footer.
fn summary_says_3d(path: &Path) -> Option<bool> {
    use std::io::{Read as _, Seek as _, SeekFrom};
    super::read::not_a_pipe(path).ok()?;
    let Ok(mut f) = std::fs::File::open(path) else {
        return None;
    };
    let Ok(len) = f.seek(SeekFrom::End(0)) else {
        return None;
    };
    // The footer: opcode, length, summary_start (u64), summary_offset_start, crc; then magic.
    if len < 8 + 29 + 8 {
        return None;
    }
    let mut tail = [0u8; 28];
    if f.seek(SeekFrom::Start(len - 28)).is_err() || f.read_exact(&mut tail).is_err() {
        return None;
    }
    // A whole file ends with the magic; a cut one has no footer to trust.
    if &tail[20..] != b"\x89MCAP0\r\n" {
        return None;
    }
    let start = u64::from_le_bytes(tail[..8].try_into().expect("8 bytes"));
    if start == 0 || start >= len || len - start > (64 << 20) {
        return None;
    }
    let mut summary = Vec::new();
    if f.seek(SeekFrom::Start(start)).is_err() || f.read_to_end(&mut summary).is_err() {
        return None;
    }
    // `gripsim.Meta3` too: a 3D file without steps is a 3D file refused as such.
    let has = |needle: &[u8]| summary.windows(needle.len()).any(|w| w == needle);
    Some(has(b"gripsim.Step3") || has(b"gripsim.Meta3"))
}

/// The recorded scenario of a 3D run, its meshes those the run used and its rods those
/// `/sim/meta` lists.
fn recorded_scenario3(path: &Path, meta: &Meta3In) -> Result<Scenario3, ReplayError> {
    let err = |m: String| ReplayError::file(path, m);
    let dir = path.parent().unwrap_or(Path::new("."));
    let scenario = Scenario3::from_str_with(
        &meta.scenario_text,
        &format!("{} (/sim/meta)", path.display()),
        dir,
        &meta.sets,
    )
    .map_err(|e| err(format!("the recorded scenario: {e}")))?;
    same_meshes(&scenario, &meta.shapes).map_err(err)?;
    let (w, _) = crate::rod3d::run3::build(&scenario).map_err(err)?;
    let built: Vec<usize> = w.rods.iter().map(|s| s.rod.n).collect();
    let listed: Vec<usize> = meta.rods.iter().map(|r| r.nodes).collect();
    if built != listed {
        return Err(err(format!(
            "/sim/meta rods do not match its own scenario_text: /sim/meta lists {} rod(s) of \
             {listed:?} nodes, the scenario builds {} of {built:?}",
            listed.len(),
            built.len()
        )));
    }
    Ok(scenario)
}

impl Run3 {
    /// Read a 3D run (every step checked, `/scene` skipped): a damaged or self-contradicting
    /// file is an error naming it and where; a file cut short is read up to its last complete
    /// chunk ([`Run3::truncated`]).
    pub fn load(path: &Path) -> Result<Run3, ReplayError> {
        let mut head: Option<(Scenario3, Meta3In)> = None;
        let mut steps = Vec::new();
        let (mut completed, mut run_error) = (None, None);
        let truncated = read3(path, |m| {
            match m {
                Message3::Meta(m) => head = Some((recorded_scenario3(path, &m)?, *m)),
                Message3::Step(s) => steps.push(*s),
                Message3::End(c, e) => (completed, run_error) = (c, e),
            }
            Ok(())
        })?;
        let (scenario, meta) = head.expect("read3 checks /sim/meta");
        Ok(Run3 {
            scenario,
            name: meta.scenario_name,
            scenario_text: meta.scenario_text,
            sets: meta.sets,
            rods: meta
                .rods
                .iter()
                .map(|r| (r.name.clone(), r.nodes))
                .collect(),
            steps,
            completed,
            run_error,
            truncated,
        })
    }
}

/// `replay check` on a 3D run: the steps fed to the detector as they are read (the file is
/// streamed, never held whole), every one checked before the report is made.
pub fn check(path: &Path, th: &Thresholds) -> Result<Check3Report, ReplayError> {
    th.validate().map_err(ReplayError::new)?;
    let mut head: Option<(Detector3, String)> = None;
    let (mut completed, mut run_error) = (None, None);
    let truncated = read3(path, |m| {
        match m {
            Message3::Meta(m) => {
                let sc = recorded_scenario3(path, &m)?;
                let d = Detector3::new(&sc, th).map_err(|e| ReplayError::file(path, e))?;
                head = Some((d, m.scenario_name));
            }
            Message3::Step(s) => {
                if let Some((d, _)) = head.as_mut() {
                    d.step(&s);
                }
            }
            Message3::End(c, e) => (completed, run_error) = (c, e),
        }
        Ok(())
    })?;
    let (d, name) = head.expect("read3 checks /sim/meta");
    let mut rep = d.finish(&path.display().to_string(), &name);
    rep.incomplete = truncated.is_some() || completed != Some(true);
    rep.completed = completed;
    rep.run_error = run_error;
    rep.truncated = truncated;
    Ok(rep)
}

/// The text report of a 3D check.
pub fn format_check(r: &Check3Report) -> String {
    let mut s = format!(
        "{} (3D, {}): {} steps to t = {} s; {} spike(s), {} sticking episode(s), {} grasp flag(s)\n",
        r.file,
        r.scenario,
        r.steps,
        super::g(r.t_end),
        r.spikes.len(),
        r.sticking.len(),
        r.grasp.len()
    );
    if !r.bruise.is_empty() || !r.bruise_expected.is_empty() || r.bruise_missing {
        s += &super::bruise_lines(
            r.bruise.len(),
            &r.bruise,
            &r.bruise_expected,
            r.bruise_missing,
        );
    }
    for k in &r.spikes {
        s += &format!(
            "  spike {}: {} node {} step {} t = {:.6} s: jump {:.3e} m/s (impact {:.3e}, unexplained {:.3e}), displacement {:.3e} m, accel ratio {:.3}\n",
            k.kind, k.rod_name, k.node, k.step, k.t, k.jump, k.impact_jump, k.unexplained_jump, k.displacement, k.accel_ratio
        );
    }
    for k in &r.sticking {
        s += &format!(
            "  sticking {}: {} node {} steps {}..{} (t = {:.6}..{:.6} s), {} changes\n",
            k.rule, k.rod_name, k.node, k.step, k.last_step, k.t, k.last_t, k.count
        );
    }
    let grasp = r.grasp.iter().map(|f| (f, "")).chain(
        r.grasp_expected
            .iter()
            .map(|f| (f, " (expected by the scenario: not flagged)")),
    );
    for (f, note) in grasp {
        s += &format!(
            "  grasp {}: step {} t = {:.6} s: the fruit moved {:.3e} m in the gripper (tolerance {:.3e} m){note}\n",
            f.kind, f.step, f.t, f.slip_m, f.hold_tolerance_m
        );
    }
    s += if r.flagged { "FLAGGED\n" } else { "clean\n" };
    if r.incomplete {
        s += &format!(
            "INCOMPLETE: the recording stops before the run's end ({}) (exit {} unless --allow-partial)\n",
            match (&r.truncated, &r.run_error) {
                (Some(why), _) => why.clone(),
                (None, Some(e)) => format!("the run ended early: {e}"),
                (None, None) => "no run-end record".into(),
            },
            super::EXIT_INCOMPLETE
        );
    }
    s
}

/// Where run B stands at a time of run A.
pub enum AtB {
    /// Before B's first step.
    Before,
    /// After B's last step.
    After,
    /// Between B's steps k0 and k1 (k1 = k0 at B's last step), weight w of k1.
    Between(usize, usize, f64),
}

/// B's steps around time `t` (times increasing over the calls; `j` is the cursor): B is
/// interpolated linearly between them.
pub fn locate_b(rb: &Run3, j: &mut usize, t: f64) -> AtB {
    while *j + 1 < rb.steps.len() && rb.steps[*j + 1].t <= t {
        *j += 1;
    }
    let Some(b0) = rb.steps.get(*j) else {
        return AtB::After;
    };
    if t < b0.t - 1e-12 * t.abs() {
        return AtB::Before;
    }
    let k1 = if *j + 1 < rb.steps.len() { *j + 1 } else { *j };
    let b1 = &rb.steps[k1];
    let w = if b1.t > b0.t {
        ((t - b0.t) / (b1.t - b0.t)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    if b1.t == b0.t && (t - b0.t).abs() > 1e-9 * t.abs().max(1e-12) {
        return AtB::After;
    }
    AtB::Between(*j, k1, w)
}

/// Node `i` of rod `r` of B between its steps `b0` and `b1` (weight `w` of `b1`).
pub fn node_between(b0: &Step3, b1: &Step3, w: f64, r: usize, i: usize) -> [f64; 3] {
    let (x0, x1) = (&b0.rods[r].x, &b1.rods[r].x);
    [0, 1, 2].map(|k| (1.0 - w) * x0[3 * i + k] + w * x1[3 * i + k])
}

/// `run --check` on a 3D scenario: the detector fed from the live events.
pub struct Detect3Observer {
    pub detector: Detector3,
}

impl crate::rod3d::events::Observer3 for Detect3Observer {
    fn on_event(&mut self, e: &crate::rod3d::events::Event3<'_>) {
        if let Some(m) = crate::record::mcap3::step_message(e) {
            self.detector.step(&m);
        }
    }
}

/// `replay show` on a 3D run: the recording turned into the `.rrd` a live run writes
/// (src/record/rerun3.rs), the material frames carried along the recorded steps.
pub fn show(path: &Path, out: &Path) -> Result<u64, ReplayError> {
    let run = Run3::load(path)?;
    drive(
        path,
        &run,
        out,
        &run.name,
        crate::record::rerun3::blueprint3(),
        |_, _, _| Ok(()),
    )
}

/// Feed the recorded steps of `run` (read from `path`) to a new [`crate::record::rerun3::Rrd3`]
/// writing `out` with the recording name `name` and the layout `blueprint`, calling
/// `after_step(stream, step, rods)` right after each step is logged (at its time) with the
/// rods as the replay carries them (positions and reference frames). Returns the steps fed.
/// A failure leaves no `.rrd` behind.
pub fn drive(
    path: &Path,
    run: &Run3,
    out: &Path,
    name: &str,
    blueprint: ::rerun::blueprint::Blueprint,
    mut after_step: impl FnMut(&::rerun::RecordingStream, &Step3, &[Sim3]) -> Result<(), ReplayError>,
) -> Result<u64, ReplayError> {
    use crate::rod3d::events::Emit3;
    let (mut w, _) =
        crate::rod3d::run3::build(&run.scenario).map_err(|e| ReplayError::file(path, e))?;
    let mut rrd = crate::record::rerun3::Rrd3::create_with(out, name, blueprint)
        .map_err(|e| ReplayError::file(out, e))?;
    w.start_observed(&mut Emit3::default(), &mut rrd);
    for m in &run.steps {
        if let Err(e) = load_step(&mut w.rods, m) {
            let _ = rrd.abandon();
            return Err(ReplayError::file(path, e));
        }
        send_step(&w.rods, m, &mut rrd);
        let rec = rrd.stream().cloned();
        if let Some(rec) = rec {
            if let Err(e) = after_step(&rec, m, &w.rods) {
                let _ = rrd.abandon();
                return Err(e);
            }
        }
    }
    rrd.finish().map_err(|e| ReplayError::file(out, e))?;
    Ok(run.steps.len() as u64)
}

/// Set the rods to a recorded step (positions, velocities, material angles) and carry their
/// reference frames to it as the solver does.
fn load_step(rods: &mut [Sim3], m: &Step3) -> Result<(), String> {
    for (sim, rod) in rods.iter_mut().zip(&m.rods) {
        let n = sim.rod.n;
        if rod.x.len() != 3 * n || rod.theta.len() + 1 != n || rod.v.len() != 3 * n {
            return Err(format!(
                "step {}: a rod's arrays do not match the scenario",
                m.step
            ));
        }
        for i in 0..n {
            sim.q[pos(i)..pos(i) + 3].copy_from_slice(&rod.x[3 * i..3 * i + 3]);
            sim.v[pos(i)..pos(i) + 3].copy_from_slice(&rod.v[3 * i..3 * i + 3]);
            if i + 1 < n {
                sim.q[angle(i)] = rod.theta[i];
            }
        }
        // Step 0 is the state the frames were built at.
        if m.step > 0 {
            sim.advance_frames();
        }
    }
    Ok(())
}

/// A recorded step as the live [`crate::rod3d::events::Event3::Step`], to `obs`.
fn send_step(rods: &[Sim3], m: &Step3, obs: &mut impl crate::rod3d::events::Observer3) {
    use crate::rod3d::events::{BodyPose3, Contact3, ContactChange3, Event3, Rod3StepView};
    let v3 = |v: &[f64]| -> [f64; 3] {
        match v {
            [a, b, c] => [*a, *b, *c],
            _ => [0.0; 3],
        }
    };
    let views: Vec<Rod3StepView<'_>> = rods.iter().map(|s| s.view()).collect();
    let contacts: Vec<Contact3> = m
        .contacts
        .iter()
        .map(|c| Contact3 {
            rod: c.rod as usize,
            node: c.node as usize,
            point: v3(&c.point),
            normal: v3(&c.normal),
            reaction: v3(&c.reaction),
            friction: v3(&c.friction),
            gap: c.gap,
            surface: c.shape as usize,
            stick: c.stuck,
            normal_reaction: c.normal_force,
            weight: c.weight,
        })
        .collect();
    let bodies: Vec<BodyPose3> = m
        .bodies
        .iter()
        .map(|b| BodyPose3 {
            shape: b.shape as usize,
            position: v3(&b.position),
            rotation: match b.rotation[..] {
                [x, y, z, w] => [x, y, z, w],
                _ => [0.0, 0.0, 0.0, 1.0],
            },
            velocity: v3(&b.velocity),
            angular_velocity: v3(&b.angular_velocity),
        })
        .collect();
    let changes: Vec<ContactChange3> = m
        .changes
        .iter()
        .map(|c| ContactChange3 {
            rod: c.rod as usize,
            node: c.node as usize,
            added: c.added,
        })
        .collect();
    obs.on_event(&Event3::Step {
        step: m.step,
        time: m.t,
        dt: m.dt,
        newton_iterations: m.newton_iterations,
        rods: &views,
        contacts: &contacts,
        bodies: &bodies,
        changes: &changes,
        passes: m.passes,
        switches: 0,
    });
}
