//! Velocity spikes and sticking nodes, found while a run streams past: one [`Detector`] fed
//! step by step, from the live event stream ([`DetectObserver`], used by `gripsim run
//! --check` and `gripsim sweep`) or from a recording read chunk by chunk (`gripsim replay
//! check` and `diff`). It keeps the previous step and, per node, what lies inside the detection
//! windows, so its memory does not grow with the run. The rules, their reasoning and the
//! defaults are in docs/replay.md; in short:
//!
//! * **Spike** (per free node and step, dynamic runs): the velocity change not explained by the
//!   smooth forces, e = Δv − Δt f(q_{k+1})/m (elastic + gravity + loads, recomputed from the
//!   positions as implicit Euler evaluates them; under BDF2 and TR-BDF2 also their own
//!   relations, the one that explains most kept: [`Detector::smooth_dv`]), is split into what
//!   a perfectly inelastic, frictionless contact does along the outward normal of every
//!   surface the node is held against (cancel what the forces push into it — support — and
//!   remove at most the normal velocity the node brought into the step — impact) and the rest.
//!   - `impact`: the impact part is ≥ `spike_floor` and the displacement it stands for,
//!     jump × Δt, ≥ `spike_displacement` (its implied acceleration, jump / Δt, is no measure:
//!     a coarser step makes it smaller and the impact worse), unless the impact was located
//!     at the step's start by a time-of-impact split (docs/replay.md).
//!   - `unexplained`: the rest is ≥ `spike_floor` and ≥ `spike_accel_ratio` × the node's
//!     acceleration scale, at any Δt.
//! * **Sticking** (per free node): `toggling`, ≥ `stick_toggles` constraint changes of
//!   accepted steps within `stick_window` seconds.
//!
//! Three rules of earlier versions (`alternating`, `oscillating`, `adhesive_hold`) never fired
//! on a real simulated run and were removed (docs/replay.md says why).
//!
//! Defaults scale with the scene ([`Scales`]): its length L, acceleration a and velocity
//! √(aL) scales, node masses and time scale √(L/a). A new rule is one more method on
//! [`Detector`] called from [`Detector::step`] (or [`Detector::flush_contacts`] for event
//! rules) that pushes to [`Findings`] and a count in [`Counts`].

use super::bruise::PressureSample;
use crate::energy::{bend::bend, damping::rod_viscous, stretch::stretch};
use crate::events::{Event, Observer, RodStepView};
use crate::model::Rod;
use crate::obstacle::Obstacle;
use crate::scenario::{Mode, Scenario};
use serde::Serialize;
use std::collections::VecDeque;

/// The thresholds a user may set (each one a flag); unset ones follow the scene
/// ([`Effective::for_scene`]).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, clap::Args)]
pub struct Thresholds {
    /// Spikes: smallest velocity jump (m/s) counted at all [default: 1e-3 x the scene's
    /// velocity scale sqrt(a L)].
    #[arg(long, value_name = "M/S")]
    pub spike_floor: Option<f64>,
    /// Unexplained spikes: the jump's implied acceleration |jump|/dt must exceed this many
    /// times the node's own acceleration scale max(scene, |f|/m) [default: 10].
    #[arg(long, value_name = "RATIO")]
    pub spike_accel_ratio: Option<f64>,
    /// Impact spikes: the displacement the jump stands for, |jump| x dt (m), must exceed this
    /// [default: 1e-4 x the scene's length scale L].
    #[arg(long, value_name = "M")]
    pub spike_displacement: Option<f64>,
    /// Sticking: window (s of simulated time) for the toggling rule
    /// [default: the larger of 2e-3 x the scene's time scale sqrt(L/a) and 20 x solve.dt].
    #[arg(long, value_name = "S")]
    pub stick_window: Option<f64>,
    /// Sticking (toggling): constraint changes (added or released) needed within the window [5: more than
    /// one rebound].
    #[arg(long, value_name = "N")]
    pub stick_toggles: Option<u64>,
}

impl Thresholds {
    /// All unset: every threshold follows the scene.
    pub const DEFAULT: Thresholds = Thresholds {
        spike_floor: None,
        spike_accel_ratio: None,
        spike_displacement: None,
        stick_window: None,
        stick_toggles: None,
    };

    /// Reject values that make no sense (negative, NaN, empty windows).
    pub fn validate(&self) -> Result<(), String> {
        let pos = [
            ("--spike-floor", self.spike_floor),
            ("--spike-accel-ratio", self.spike_accel_ratio),
            ("--spike-displacement", self.spike_displacement),
        ];
        for (name, v) in pos {
            if let Some(v) = v {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(format!("{name} must be a finite number >= 0, got {v}"));
                }
            }
        }
        for (name, v) in [("--stick-window", self.stick_window)] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(format!("{name} must be a time > 0 (s), got {v}"));
                }
            }
        }
        let counts = [("--stick-toggles", self.stick_toggles)];
        for (name, v) in counts {
            if v == Some(0) {
                return Err(format!("{name} must be at least 1"));
            }
        }
        Ok(())
    }
}

/// The scales of a scene the default thresholds follow (reported in `--json` as `scales`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Scales {
    /// Length scale L (m): the largest of the rod lengths, the obstacle sizes (circle and
    /// ellipse diameters, polygon extents, sine wavelengths) and, for particles, the initial
    /// gap to the nearest obstacle (a drop height) and v0 × t_end (how far it slides); 1 m
    /// when all of them are 0.
    pub length: f64,
    /// Acceleration scale a (m/s²): the largest of |g|, the drives' and actuator programs'
    /// accelerations, the loads per node mass and the particles' v0²/L; L/t_end² when all of
    /// them are 0.
    pub acceleration: f64,
    /// Velocity scale √(a L) (m/s).
    pub velocity: f64,
    /// Time scale √(L / a) (s).
    pub time: f64,
    /// The scenario's step `solve.dt` (s; the first step of an adaptive run), 0 when static.
    pub dt: f64,
}

impl Scales {
    pub fn of(sc: &Scenario) -> Scales {
        let rods: Vec<Rod> = sc.rods.iter().map(Rod::new).collect();
        let mut length = 0.0f64;
        for rod in &rods {
            length = length.max(rod.rest_length.iter().sum());
        }
        for o in &sc.obstacles {
            length = length.max(obstacle_size(o));
        }
        let span = if sc.solve.mode == Mode::Dynamic {
            sc.solve.t_end
        } else {
            0.0
        };
        for rod in rods.iter().filter(|r| r.n == 1) {
            // How far it travels at its initial speed over the run.
            length = length.max(rod.velocity[0].hypot(rod.velocity[1]) * span);
            let gap = sc
                .obstacles
                .iter()
                .map(|o| o.query([rod.q0[0], rod.q0[1]]).distance)
                .fold(f64::INFINITY, f64::min);
            if gap.is_finite() {
                length = length.max(gap);
            }
        }
        if !(length > 0.0) {
            length = 1.0;
        }
        let mut accel = sc.solve.gravity[0].hypot(sc.solve.gravity[1]);
        let t_end = if sc.solve.mode == Mode::Dynamic && sc.solve.t_end > 0.0 {
            sc.solve.t_end
        } else {
            1.0
        };
        for rod in &rods {
            // The drive's acceleration, from its motion (whatever the drive's kind).
            let samples = 16;
            let mut v_prev = rod.drive.motion(0.0).1;
            for k in 1..=samples {
                let t = t_end * k as f64 / samples as f64;
                let v = rod.drive.motion(t).1;
                let dv = (v[0] - v_prev[0]).hypot(v[1] - v_prev[1]);
                accel = accel.max(dv / (t_end / samples as f64));
                v_prev = v;
            }
            for i in 0..rod.n {
                let f = rod.load[2 * i].hypot(rod.load[2 * i + 1]);
                accel = accel.max(f / rod.mass[i]);
            }
            let v0 = rod.velocity[0].hypot(rod.velocity[1]);
            accel = accel.max(v0 * v0 / length);
        }
        accel = accel.max(actuator_acceleration(sc, &rods));
        if !(accel > 0.0) {
            // Nothing accelerates anything: the run's own span sets the scale.
            accel = length / (t_end * t_end);
        }
        Scales {
            length,
            acceleration: accel,
            velocity: (accel * length).sqrt(),
            time: (length / accel).sqrt(),
            dt: if sc.solve.mode == Mode::Dynamic {
                sc.solve.dt
            } else {
                0.0
            },
        }
    }
}

/// The largest acceleration an `[[actuator]]` program gives a rod it moves: its laws' peak
/// accelerations (a rotation's angular acceleration times the farthest node's distance from
/// its pivot, which the gripper's rigid motion keeps).
fn actuator_acceleration(sc: &Scenario, rods: &[Rod]) -> f64 {
    let mut accel = 0.0f64;
    for (spec, rod) in sc.rods.iter().zip(rods) {
        let Some(program) = spec.actuator.and_then(|k| sc.actuators.get(k)) else {
            continue;
        };
        let mirror_x = program.program.mirror_x.filter(|_| spec.mirror);
        let lever = |pivot: [f64; 2]| {
            let px = mirror_x.map_or(pivot[0], |m| 2.0 * m - pivot[0]);
            (0..rod.n)
                .map(|i| (rod.q0[2 * i] - px).hypot(rod.q0[2 * i + 1] - pivot[1]))
                .fold(0.0, f64::max)
        };
        for phase in &program.program.phases {
            accel = accel.max(phase.peak_acceleration(lever));
        }
    }
    accel
}

/// The size of an obstacle's features (m); 0 for a plane.
fn obstacle_size(o: &Obstacle) -> f64 {
    match o {
        Obstacle::Circle(c) => 2.0 * c.radius,
        Obstacle::Ellipse(e) => 2.0 * e.a.max(e.b),
        Obstacle::Sine(s) if s.wavenumber > 0.0 => std::f64::consts::TAU / s.wavenumber,
        Obstacle::Polygon(p) => {
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for v in &p.vertices {
                for a in 0..2 {
                    lo[a] = lo[a].min(v[a]);
                    hi[a] = hi[a].max(v[a]);
                }
            }
            (hi[0] - lo[0]).hypot(hi[1] - lo[1])
        }
        #[allow(unreachable_patterns)]
        _ => 0.0,
    }
}

/// The thresholds in force for one run: the user's, else the scene's defaults. Reported in
/// `--json` as `thresholds`; windows in seconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Effective {
    pub spike_floor: f64,
    pub spike_accel_ratio: f64,
    pub spike_displacement: f64,
    pub stick_window: f64,
    pub stick_toggles: u64,
}

impl Effective {
    pub fn for_scene(th: &Thresholds, s: &Scales) -> Effective {
        Effective {
            spike_floor: th.spike_floor.unwrap_or(1e-3 * s.velocity),
            spike_accel_ratio: th.spike_accel_ratio.unwrap_or(10.0),
            spike_displacement: th.spike_displacement.unwrap_or(1e-4 * s.length),
            stick_window: th.stick_window.unwrap_or((2e-3 * s.time).max(20.0 * s.dt)),
            stick_toggles: th.stick_toggles.unwrap_or(5),
        }
    }
}

/// One velocity spike.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Spike {
    /// `impact` or `unexplained`.
    pub kind: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// The step whose velocity change triggered it.
    pub step: u64,
    /// Time at the end of that step (s).
    pub t: f64,
    /// Equal to `step` (kept for episodes of future rules).
    pub last_step: u64,
    pub dt: f64,
    /// Δv = u_k − u_{k−1} (m/s).
    pub dv: [f64; 2],
    pub dv_norm: f64,
    /// |Δt f/m|: the velocity change the smooth forces give over the step (m/s).
    pub force_dv: f64,
    /// The flagged jump (m/s): the contact part (`impact`) or the unexplained part
    /// (`unexplained`).
    pub jump: f64,
    /// The part of e = Δv − Δt f/m that removed the normal velocity the node brought into
    /// the step (m/s).
    pub impact_jump: f64,
    /// The part of e nothing explains (m/s).
    pub unexplained_jump: f64,
    /// Normal speed into the surface(s) at the start of the step (m/s), for a node
    /// constrained at its end; else 0.
    pub approach_speed: f64,
    /// |jump| / dt (m/s²).
    pub accel: f64,
    /// The scale it is compared with (m/s²).
    pub accel_ref: f64,
    pub accel_ratio: f64,
    /// |jump| × dt (m).
    pub displacement: f64,
    /// Node constrained at the end of the step.
    pub in_contact: bool,
}

/// One episode of a sticking node.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sticking {
    /// `toggling`.
    pub rule: &'static str,
    pub rod: usize,
    pub rod_name: String,
    pub node: usize,
    /// First step of the episode, and the time at its end (s).
    pub step: u64,
    pub t: f64,
    pub last_step: u64,
    pub last_t: f64,
    /// Constraint changes in the episode.
    pub count: u64,
}

/// A stretch of a recording that holds only some of its steps (`--detail auto`): recorded
/// steps `from` and `to` with gaps between them, the largest `every` steps apart. No spike is
/// judged across a gap (the velocity change over several steps is no one step's jump).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Decimated {
    pub from: u64,
    pub to: u64,
    /// The largest step difference between two recorded steps of the stretch.
    pub every: u64,
    /// Gaps in the stretch (pairs of recorded steps more than one step apart).
    pub gaps: u64,
}

/// Everything found in one run.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Findings {
    pub spikes: Vec<Spike>,
    pub sticking: Vec<Sticking>,
    /// A fruit that slipped in the gripper during the lift, or was dropped.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grasp: Vec<super::grasp::GraspFlag>,
    /// Slips and drops the scenario expects (`[expect] grasp`): reported, not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grasp_expected: Vec<super::grasp::GraspFlag>,
    /// Contacts on a compliant fruit above its bruise threshold.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub bruise: Vec<super::bruise::BruiseFlag>,
    /// The bruises a scenario expects (`[expect] bruised = true`): reported, not flagged.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub bruise_expected: Vec<super::bruise::BruiseFlag>,
    /// The scenario expects a bruise and the run made none (flagged).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub bruise_missing: bool,
}

/// Counts by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct Counts {
    pub spikes: usize,
    pub impact: usize,
    pub unexplained: usize,
    pub sticking: usize,
    pub toggling: usize,
    pub slip: usize,
    pub drop: usize,
    /// A fruit held where the scenario expects a slip or a drop.
    pub held: usize,
    /// Stretches of a contact above the fruit's bruise pressure.
    pub bruise: usize,
}

impl Findings {
    pub fn counts(&self) -> Counts {
        let s = |k: &str| self.spikes.iter().filter(|x| x.kind == k).count();
        let t = |k: &str| self.sticking.iter().filter(|x| x.rule == k).count();
        Counts {
            spikes: self.spikes.len(),
            impact: s("impact"),
            unexplained: s("unexplained"),
            sticking: self.sticking.len(),
            toggling: t("toggling"),
            slip: self.grasp.iter().filter(|g| g.kind == "slip").count(),
            drop: self.grasp.iter().filter(|g| g.kind == "drop").count(),
            held: self.grasp.iter().filter(|g| g.kind == "held").count(),
            bruise: self.bruise.len() + usize::from(self.bruise_missing),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.spikes.is_empty()
            && self.sticking.is_empty()
            && self.grasp.is_empty()
            && self.bruise.is_empty()
            && !self.bruise_missing
    }

    fn sort(&mut self) {
        self.spikes
            .sort_by(|a, b| (a.step, a.rod, a.node, a.kind).cmp(&(b.step, b.rod, b.node, b.kind)));
        self.sticking
            .sort_by(|a, b| (a.step, a.rod, a.node, a.rule).cmp(&(b.step, b.rod, b.node, b.rule)));
    }
}
/// Elastic + gravity + load force on every node of `rod` at `q` (interleaved, N).
pub fn smooth_force(rod: &Rod, gravity: [f64; 2], q: &[f64], f: &mut [f64]) {
    let n = rod.n;
    for i in 0..n {
        f[2 * i] = rod.load[2 * i] + rod.mass[i] * gravity[0];
        f[2 * i + 1] = rod.load[2 * i + 1] + rod.mass[i] * gravity[1];
    }
    if n < 2 {
        return;
    }
    let mut g4 = [0.0; 4];
    for e in 0..n - 1 {
        let x = [q[2 * e], q[2 * e + 1], q[2 * e + 2], q[2 * e + 3]];
        stretch(&x, rod.ea, rod.rest_length[e], &mut g4, None);
        for k in 0..4 {
            f[2 * e + k] -= g4[k];
        }
    }
    let mut g6 = [0.0; 6];
    for i in 1..n - 1 {
        let x = [
            q[2 * i - 2],
            q[2 * i - 1],
            q[2 * i],
            q[2 * i + 1],
            q[2 * i + 2],
            q[2 * i + 3],
        ];
        bend(
            &x,
            rod.ei / rod.bend_length(i),
            rod.rest_curvature[i],
            &mut g6,
            None,
        );
        for k in 0..6 {
            f[2 * i - 2 + k] -= g6[k];
        }
    }
}

fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// The coefficients (α, β) of `v = α n1 + β n2`, when n1 and n2 are not (nearly) parallel.
fn decompose(v: [f64; 2], n1: [f64; 2], n2: [f64; 2]) -> Option<(f64, f64)> {
    let det = n1[0] * n2[1] - n1[1] * n2[0];
    if det.abs() < 1e-6 {
        return None;
    }
    Some((
        (v[0] * n2[1] - v[1] * n2[0]) / det,
        (n1[0] * v[1] - n1[1] * v[0]) / det,
    ))
}

/// One rod's state at the end of a step, as the detector reads it (a live step view or a
/// recorded step). Interleaved vectors `[x0, y0, x1, y1, …]`.
#[derive(Debug, Clone, Copy)]
pub struct RodSample<'a> {
    pub q: &'a [f64],
    pub u: &'a [f64],
    pub reaction: &'a [f64],
    pub normal: &'a [f64],
    /// The second surface's normal of a node held at a corner (zero otherwise); may be empty
    /// (a recording from before it was recorded).
    pub normal2: &'a [f64],
    pub in_contact: &'a [bool],
    pub q_predictor: &'a [f64],
}

impl<'a> From<&RodStepView<'a>> for RodSample<'a> {
    fn from(v: &RodStepView<'a>) -> Self {
        RodSample {
            q: v.q,
            u: v.u,
            reaction: v.reaction,
            normal: v.normal,
            normal2: v.normal2,
            in_contact: v.in_contact,
            q_predictor: v.q_predictor,
        }
    }
}

impl RodSample<'_> {
    fn normal(&self, i: usize) -> [f64; 2] {
        [self.normal[2 * i], self.normal[2 * i + 1]]
    }

    /// The corner's second normal, when the node is held at one.
    fn normal2(&self, i: usize) -> Option<[f64; 2]> {
        let n = [*self.normal2.get(2 * i)?, *self.normal2.get(2 * i + 1)?];
        (n != [0.0, 0.0]).then_some(n)
    }
}

/// A constraint added or released, as the run reported it. Changes of attempts the solver threw
/// away (a rejected adaptive step, a Newton back-off, a time-of-impact split) carry the same
/// step number but another time than the accepted step; the detector drops them. Under
/// TR-BDF2 the changes of an accepted step's first stage carry the time t + γ dt (γ =
/// [`crate::solver::TR_BDF2_GAMMA`]) and are kept.
#[derive(Debug, Clone, Copy)]
pub struct ContactSample {
    pub step: u64,
    pub t: f64,
    pub rod: usize,
    pub node: usize,
    /// Added (else released).
    pub added: bool,
    /// The surface's outward normal.
    pub normal: [f64; 2],
}

impl ContactSample {
    /// The sample of a change the solver reported.
    pub fn of(c: &crate::events::ContactChange, added: bool) -> Self {
        ContactSample {
            step: c.step,
            t: c.t,
            rod: c.rod,
            node: c.node,
            added,
            normal: crate::events::xy(c.normal),
        }
    }
}

/// An open sticking episode.
#[derive(Debug, Clone, Copy)]
struct Episode {
    step: u64,
    t: f64,
    last_step: u64,
    last_t: f64,
    count: u64,
}

/// What one node carries between steps: only what lies inside the windows.
#[derive(Debug, Clone, Default)]
struct NodeState {
    /// Accepted constraint changes in the window: (step, time).
    changes: VecDeque<(u64, f64)>,
    toggle_open: Option<Episode>,
}

/// The spike and sticking rules over a stream of steps (module documentation).
pub struct Detector {
    pub scales: Scales,
    pub th: Effective,
    rods: Vec<Rod>,
    names: Vec<String>,
    /// The obstacles' and the free bodies' names (a fruit's own contact is named by both).
    obstacle_names: Vec<String>,
    body_names: Vec<String>,
    gravity: [f64; 2],
    dynamic: bool,
    /// Velocities of the previous step, per rod.
    prev_u: Vec<Vec<f64>>,
    /// Positions and contact flags of the previous step, per rod (an impact located at the
    /// step's start, see [`Detector::spikes`]).
    prev_q: Vec<Vec<f64>>,
    prev_contact: Vec<Vec<bool>>,
    /// Per rod and node: held since the end of the last step, which it reached on its own path
    /// (nothing stopped it yet), so its impact happens at the start of the next step.
    arrived: Vec<Vec<bool>>,
    /// Per rod and node: the normal of a constraint added or released in the current step (the
    /// last change's), which explains the jump of a node free at the step's end: it was held
    /// for part of the step (docs/replay.md).
    inside: Vec<Vec<Option<[f64; 2]>>>,
    /// The run's integrator: which smooth velocity changes a free node may have taken
    /// ([`Detector::smooth_dv`]); under TR-BDF2 an accepted step's first-stage changes are kept
    /// (see [`ContactSample`]).
    integrator: crate::scenario::Integrator,
    /// Velocities of the step before the previous one, per rod, and the previous step's dt
    /// (BDF2's history; `have_prev2` when both are the stream's consecutive steps).
    prev2_u: Vec<Vec<f64>>,
    prev_dt: f64,
    have_prev2: bool,
    /// The smooth force (viscous force included) at the previous step's end, per rod
    /// (TR-BDF2's start of the step).
    prev_force: Vec<Vec<f64>>,
    /// The relative rounding of the positions read (2⁻²⁴ for an f32 recording, 0 live or f64):
    /// a displacement is known only to within it.
    q_round: f64,
    have_prev: bool,
    /// Per node: the smooth force at the step's end, and a damped rod's viscous force.
    force: Vec<f64>,
    viscous: Vec<f64>,
    nodes: Vec<Vec<NodeState>>,
    pending: Vec<ContactSample>,
    out: Findings,
    /// Steps seen (with step 0) and the last time.
    pub steps: u64,
    pub t_end: f64,
    /// The last step seen.
    last_step: Option<u64>,
    /// The decimated stretches of the stream, in order.
    pub decimated: Vec<Decimated>,
    /// The grasp rules, when the scenario has a free body.
    grasp: Option<super::grasp::GraspRule>,
    /// Per rod: the largest static friction coefficient of its contact pairs (the cone that
    /// bounds the tangential part of an impact).
    mu: Vec<f64>,
    /// Contacts on a compliant fruit above its bruise pressure.
    bruise: super::bruise::BruiseRule,
    /// The scenario expects its fruit to bruise (`[expect] bruised`).
    bruise_expected: bool,
}

impl Detector {
    /// A detector for a recording whose per-node numbers are f32 (`f32`) or exact.
    pub fn for_recording(sc: &Scenario, th: &Thresholds, f32: bool) -> Detector {
        let mut d = Detector::new(sc, th);
        d.q_round = if f32 { 2f64.powi(-24) } else { 0.0 };
        d
    }

    pub fn new(sc: &Scenario, th: &Thresholds) -> Detector {
        let scales = Scales::of(sc);
        let rods: Vec<Rod> = sc.rods.iter().map(Rod::new).collect();
        let nmax = rods.iter().map(|r| r.n).max().unwrap_or(0);
        Detector {
            scales,
            th: Effective::for_scene(th, &scales),
            names: sc.rods.iter().map(|r| r.name.clone()).collect(),
            obstacle_names: sc.obstacle_names.clone(),
            body_names: sc.bodies.iter().map(|b| b.name.clone()).collect(),
            prev_u: rods.iter().map(|r| vec![0.0; 2 * r.n]).collect(),
            prev_q: rods.iter().map(|r| vec![0.0; 2 * r.n]).collect(),
            prev_contact: rods.iter().map(|r| vec![false; r.n]).collect(),
            arrived: rods.iter().map(|r| vec![false; r.n]).collect(),
            inside: rods.iter().map(|r| vec![None; r.n]).collect(),
            integrator: sc.solve.integrator,
            prev2_u: rods.iter().map(|r| vec![0.0; 2 * r.n]).collect(),
            prev_dt: 0.0,
            have_prev2: false,
            prev_force: rods.iter().map(|r| vec![0.0; 2 * r.n]).collect(),
            q_round: 0.0,
            nodes: rods
                .iter()
                .map(|r| vec![NodeState::default(); r.n])
                .collect(),
            rods,
            gravity: sc.solve.gravity,
            dynamic: sc.solve.mode == Mode::Dynamic,
            have_prev: false,
            force: vec![0.0; 2 * nmax],
            viscous: vec![0.0; 2 * nmax],
            pending: Vec::new(),
            out: Findings::default(),
            steps: 0,
            t_end: 0.0,
            last_step: None,
            decimated: Vec::new(),
            grasp: super::grasp::GraspRule::of(sc),
            mu: sc
                .rods
                .iter()
                .map(|r| {
                    sc.obstacle_names
                        .iter()
                        .map(|o| sc.friction.between(&r.name, o).mu_s)
                        .fold(0.0, f64::max)
                })
                .collect(),
            bruise: Default::default(),
            bruise_expected: sc.expect.bruised,
        }
    }

    /// The compliant contacts of an accepted step (after [`Detector::step`]).
    pub fn pressure(&mut self, step: u64, t: f64, samples: &[super::bruise::PressureSample]) {
        let places = super::bruise::Places {
            rods: &self.names,
            obstacles: &self.obstacle_names,
            bodies: &self.body_names,
        };
        self.bruise.step(step, t, samples, &places);
    }

    /// The grasp rules for one step (after [`Detector::step`]): the rods' positions, the first
    /// free body's centroid and whether a prong touches it.
    pub fn grasp(
        &mut self,
        step: u64,
        t: f64,
        q: &[&[f64]],
        fruit: Option<[f64; 2]>,
        touching: bool,
    ) {
        if let (Some(g), Some(f)) = (self.grasp.as_mut(), fruit) {
            g.step(step, t, q, f, touching);
        }
    }

    /// A constraint change; counted when the step it belongs to ends with the same time.
    pub fn contact(&mut self, c: ContactSample) {
        if c.rod < self.rods.len() && c.node < self.rods[c.rod].n {
            self.pending.push(c);
        }
    }

    /// The end of an accepted step (step 0: the initial state).
    pub fn step(&mut self, step: u64, t: f64, dt: f64, rods: &[RodSample<'_>]) {
        self.flush_contacts(step, t, dt);
        // A gap (a decimated recording): the previous step seen is not this step's start, so
        // nothing is compared across it; the stretch is reported instead.
        let gap = self.last_step.filter(|&s| step > s + 1);
        if let Some(s) = gap {
            self.note_gap(s, step);
            // Whether a node reached a surface unstopped is not known across a gap.
            self.arrived.iter_mut().for_each(|a| a.fill(false));
        }
        self.last_step = Some(step);
        let second_order = self.integrator != crate::scenario::Integrator::BackwardEuler;
        let compare = self.have_prev && gap.is_none() && self.dynamic && dt > 0.0;
        for (r, cur) in rods.iter().enumerate().take(self.rods.len()) {
            if compare || (second_order && self.dynamic) {
                self.end_force(r, cur);
            }
            if compare {
                self.spikes(r, step, t, dt, cur);
            }
            if second_order && self.dynamic {
                let n = 2 * self.rods[r].n;
                self.prev_force[r].copy_from_slice(&self.force[..n]);
            }
        }
        self.close_stale(t);
        self.inside.iter_mut().for_each(|n| n.fill(None));
        for (r, cur) in rods.iter().enumerate().take(self.rods.len()) {
            std::mem::swap(&mut self.prev2_u[r], &mut self.prev_u[r]);
            self.prev_u[r].copy_from_slice(cur.u);
            self.prev_q[r].copy_from_slice(cur.q);
            self.prev_contact[r].copy_from_slice(cur.in_contact);
        }
        self.have_prev2 = self.have_prev && gap.is_none();
        self.prev_dt = dt;
        self.have_prev = true;
        self.steps += 1;
        self.t_end = t;
    }

    /// A gap from recorded step `a` to `b`: a new decimated stretch, or the last one grown.
    fn note_gap(&mut self, a: u64, b: u64) {
        match self.decimated.last_mut() {
            Some(d) if d.to == a => {
                d.to = b;
                d.every = d.every.max(b - a);
                d.gaps += 1;
            }
            _ => self.decimated.push(Decimated {
                from: a,
                to: b,
                every: b - a,
                gaps: 1,
            }),
        }
    }

    /// Everything found; open episodes are closed at the last step.
    pub fn finish(mut self) -> Findings {
        if let Some(g) = self.grasp.take() {
            let found = g.finish();
            self.out.grasp = found.flags;
            self.out.grasp_expected = found.expected;
        }
        let bruises = std::mem::take(&mut self.bruise).finish();
        if self.bruise_expected {
            self.out.bruise_missing = bruises.is_empty();
            self.out.bruise_expected = bruises;
        } else {
            self.out.bruise = bruises;
        }
        for (r, nodes) in self.nodes.iter_mut().enumerate() {
            for (i, n) in nodes.iter_mut().enumerate() {
                if let Some(ep) = n.toggle_open.take() {
                    self.out
                        .sticking
                        .push(sticking("toggling", r, &self.names[r], i, ep));
                }
            }
        }
        self.out.sort();
        self.out
    }

    /// What has been found so far (open episodes not included).
    pub fn found(&self) -> &Findings {
        &self.out
    }

    /// `toggling`: the accepted changes of this step, in a window of simulated time. Also
    /// notes the constraints added in this step (for [`Detector::spikes`]).
    fn flush_contacts(&mut self, step: u64, t: f64, dt: f64) {
        let pending = std::mem::take(&mut self.pending);
        let (window, need) = (self.th.stick_window, self.th.stick_toggles);
        // TR-BDF2's first stage ends at t + γ dt of the step's start, the last step's end
        // (computed as the solver does, so it is the same number).
        let tr_bdf2 = self.integrator == crate::scenario::Integrator::TrBdf2;
        let stage1 = (tr_bdf2 && step > 0 && self.last_step == Some(step - 1))
            .then_some(self.t_end + crate::solver::TR_BDF2_GAMMA * dt);
        for c in pending {
            let accepted_time = c.t == t || stage1 == Some(c.t);
            if c.step != step || (self.dynamic && !accepted_time) {
                // A change of an attempt that was thrown away (or of a step never recorded).
                if c.step > step {
                    self.pending.push(c);
                }
                continue;
            }
            self.inside[c.rod][c.node] = Some(c.normal);
            let n = &mut self.nodes[c.rod][c.node];
            n.changes.push_back((c.step, c.t));
            while n.changes.front().is_some_and(|&(_, t0)| c.t - t0 >= window) {
                n.changes.pop_front();
            }
            if n.changes.len() as u64 >= need {
                match n.toggle_open.as_mut() {
                    Some(ep) => {
                        ep.last_step = c.step;
                        ep.last_t = c.t;
                        ep.count += 1;
                    }
                    None => {
                        let (s0, t0) = n.changes[0];
                        n.toggle_open = Some(Episode {
                            step: s0,
                            t: t0,
                            last_step: c.step,
                            last_t: c.t,
                            count: n.changes.len() as u64,
                        });
                    }
                }
            }
        }
    }

    /// Close the episodes that can no longer grow (their last event left the window).
    fn close_stale(&mut self, t: f64) {
        let sw = self.th.stick_window;
        for (r, nodes) in self.nodes.iter_mut().enumerate() {
            for (i, n) in nodes.iter_mut().enumerate() {
                if n.toggle_open.is_some_and(|ep| t - ep.last_t >= sw) {
                    let ep = n.toggle_open.take().expect("checked");
                    self.out
                        .sticking
                        .push(sticking("toggling", r, &self.names[r], i, ep));
                }
            }
        }
    }

    /// The smooth force at the step's end into `self.force`: elastic, gravity and loads, less
    /// a damped rod's viscous force at the end velocities (which explains what an impact does
    /// to the nodes beside it within the step, as the solver's does).
    fn end_force(&mut self, r: usize, cur: &RodSample<'_>) {
        let rod = &self.rods[r];
        let n = rod.n;
        let f = &mut self.force[..2 * n];
        smooth_force(rod, self.gravity, cur.q, f);
        if rod.damping_time > 0.0 {
            let fd = &mut self.viscous[..2 * n];
            fd.fill(0.0);
            rod_viscous(rod, cur.q, cur.u, fd, None, |_, _| {});
            for (f, d) in f.iter_mut().zip(fd.iter()) {
                *f -= d;
            }
        }
    }

    /// The smooth velocity changes node `i` of rod `r` may have taken in a step of `dt`
    /// ending with the force `f1` (per DOF pair): backward Euler's Δt f₁/m, which every
    /// integrator takes on a node whose contact state changes (and BDF2 on its first step);
    /// under BDF2 also the variable-step BDF2 row's α (u_k − u_{k−1}) + β f₁/m (ω = Δt/Δt_prev,
    /// α = ω²/(1+2ω), β = Δt (1+ω)/(1+2ω)); under TR-BDF2 also the trapezoidal rule's
    /// Δt (f₀ + f₁)/(2m), which TR-BDF2's two stages give to second order (their middle force
    /// unrecorded). The detector does not know which row the solver took for a node.
    fn smooth_dv(&self, r: usize, i: usize, dt: f64, f1: [f64; 2]) -> ([f64; 2], Option<[f64; 2]>) {
        use crate::scenario::Integrator;
        let m = self.rods[r].mass[i];
        let be = [dt * f1[0] / m, dt * f1[1] / m];
        let second = match self.integrator {
            Integrator::BackwardEuler => None,
            Integrator::Bdf2 => (self.have_prev2 && self.prev_dt > 0.0).then(|| {
                let w = dt / self.prev_dt;
                let alpha = w * w / (1.0 + 2.0 * w);
                let beta = dt * (1.0 + w) / (1.0 + 2.0 * w);
                let (u, u0) = (&self.prev_u[r], &self.prev2_u[r]);
                [
                    alpha * (u[2 * i] - u0[2 * i]) + beta * f1[0] / m,
                    alpha * (u[2 * i + 1] - u0[2 * i + 1]) + beta * f1[1] / m,
                ]
            }),
            Integrator::TrBdf2 => {
                let f0 = &self.prev_force[r];
                Some([
                    0.5 * dt * (f0[2 * i] + f1[0]) / m,
                    0.5 * dt * (f0[2 * i + 1] + f1[1]) / m,
                ])
            }
        };
        (be, second)
    }

    /// `impact` and `unexplained` for the free nodes of rod `r` (its end force in `self.force`).
    fn spikes(&mut self, r: usize, step: u64, t: f64, dt: f64, cur: &RodSample<'_>) {
        let n = self.rods[r].n;
        let a_scene = self.scales.acceleration;
        let th = self.th;
        for i in 0..n {
            if self.rods[r].clamped[i] {
                continue;
            }
            let m = self.rods[r].mass[i];
            let f1 = [self.force[2 * i], self.force[2 * i + 1]];
            let prev = [self.prev_u[r][2 * i], self.prev_u[r][2 * i + 1]];
            let dv = [cur.u[2 * i] - prev[0], cur.u[2 * i + 1] - prev[1]];
            let node_ref = a_scene.max(norm(f1) / m);
            // The surface that explains the jump: the one the node is held on at the step's
            // end, or one it was held on for part of the step (added or released in it: under
            // TR-BDF2 a node can be stopped in the first stage and released in the second).
            let surface = if cur.in_contact[i] {
                Some((cur.normal(i), cur.normal2(i)))
            } else {
                self.inside[r][i].map(|n| (n, None))
            };
            let explain = |fdv: [f64; 2]| {
                let e = [dv[0] - fdv[0], dv[1] - fdv[1]];
                match surface {
                    Some((n1, n2)) => {
                        let (impact, approach, rest, held) = split_contact(e, fdv, prev, n1, n2);
                        (impact, approach, within_cone(rest, n1, self.mu[r] * held))
                    }
                    None => (0.0, 0.0, e),
                }
            };
            // The velocity change the smooth forces explain best: the jump is what no row
            // the solver may have taken explains.
            let (be, second) = self.smooth_dv(r, i, dt, f1);
            let mut fdv = be;
            let (mut impact, mut approach, mut rest) = explain(be);
            if let Some(s) = second {
                let (i2, a2, r2) = explain(s);
                if norm(r2) < norm(rest) || (norm(r2) == norm(rest) && i2 < impact) {
                    (fdv, impact, approach, rest) = (s, i2, a2, r2);
                }
            }
            let unexplained = norm(rest);
            let large =
                |j: f64, scale: f64| j >= th.spike_floor && j / dt >= th.spike_accel_ratio * scale;
            // Floor: the jump must stand for a displacement over 1e-9 L (a sliver of a last
            // step turns position round-off into velocity noise of any size).
            let flag_unexplained =
                large(unexplained, node_ref) && unexplained * dt >= 1e-9 * self.scales.length;
            // An impact is judged by the displacement it stands for, not by its implied
            // acceleration: 10× coarser steps make that 10× smaller and the impact worse.
            // An impact located at the start of this step (a time-of-impact split ended the
            // last step at the contact instant) stands for no displacement, as the step's
            // length does not blur when the contact began: free at the end of the last step and not moving towards the
            // surface in this one (−n·Δq within round-off: it began on the surface), or held
            // since the end of the last step, which it reached unstopped.
            let added = surface.is_some() && !self.prev_contact[r][i];
            let located = if let (true, Some((n, _))) = (added, surface) {
                let dq = [
                    cur.q[2 * i] - self.prev_q[r][2 * i],
                    cur.q[2 * i + 1] - self.prev_q[r][2 * i + 1],
                ];
                // An f32 recording rounds each coordinate by up to 2⁻²⁴ of it: the test of a
                // start on the surface allows that on top of the round-off of the live test.
                let slack = self.q_round
                    * (cur.q[2 * i].abs()
                        + cur.q[2 * i + 1].abs()
                        + self.prev_q[r][2 * i].abs()
                        + self.prev_q[r][2 * i + 1].abs());
                -dot(n, dq) <= 1e-9 * self.scales.length + slack
            } else {
                surface.is_some() && self.arrived[r][i]
            };
            self.arrived[r][i] = added && cur.in_contact[i] && impact < th.spike_floor;
            let displacement = if located { 0.0 } else { impact * dt };
            let flag_impact = impact >= th.spike_floor && displacement >= th.spike_displacement;
            let make = |kind: &'static str, jump: f64, accel_ref: f64| Spike {
                kind,
                rod: r,
                rod_name: self.names[r].clone(),
                node: i,
                step,
                t,
                last_step: step,
                dt,
                dv,
                dv_norm: norm(dv),
                force_dv: norm(fdv),
                jump,
                impact_jump: impact,
                unexplained_jump: unexplained,
                approach_speed: approach,
                accel: jump / dt,
                accel_ref,
                accel_ratio: jump / dt / accel_ref,
                displacement: jump * dt,
                in_contact: cur.in_contact[i],
            };
            if flag_unexplained {
                self.out
                    .spikes
                    .push(make("unexplained", unexplained, node_ref));
            } else if flag_impact {
                self.out.spikes.push(make("impact", impact, a_scene));
            }
        }
    }
}

/// With Coulomb friction a contact's tangential impulse is at most μ_s times its normal one:
/// the tangential part of the rest `r` (against the normal `n`) is explained up to `cone`
/// (μ_s times the normal jump the contact explains). A stick at the moment of impact stops a
/// node's sliding within the step; without this it read as an unexplained jump.
fn within_cone(r: [f64; 2], n: [f64; 2], cone: f64) -> [f64; 2] {
    if !(cone > 0.0) {
        return r;
    }
    let rn = dot(r, n);
    let t = [r[0] - rn * n[0], r[1] - rn * n[1]];
    let tl = norm(t);
    let k = if tl > 0.0 {
        (tl - cone).max(0.0) / tl
    } else {
        0.0
    };
    [rn * n[0] + k * t[0], rn * n[1] + k * t[1]]
}

/// Split the jump `e` of a node held on the surface(s) n1 (and n2 at a corner) into what an
/// inelastic frictionless contact explains — per surface, support up to what the forces push
/// into it over the step (−n·Δt f/m) and impact up to the normal velocity the node brought
/// into the step (−n·u_k) — and the rest. Returns (|impact|, approach speed, rest, the normal
/// jump explained: support + impact).
fn split_contact(
    e: [f64; 2],
    fdv: [f64; 2],
    u_prev: [f64; 2],
    n1: [f64; 2],
    n2: Option<[f64; 2]>,
) -> (f64, f64, [f64; 2], f64) {
    // Coefficients along the surface normals: one surface, or both of a corner.
    let corner = n2.and_then(|n2| {
        let ce = decompose(e, n1, n2)?;
        let cf = decompose(fdv, n1, n2)?;
        let cu = decompose(u_prev, n1, n2)?;
        Some((n2, ce, cf, cu))
    });
    let part = |en: f64, fn_: f64, un: f64| {
        let support = en.clamp(0.0, (-fn_).max(0.0));
        let approach = (-un).max(0.0);
        let impact = (en - support).clamp(0.0, approach);
        (support + impact, impact, approach)
    };
    match corner {
        Some((n2, ce, cf, cu)) => {
            let (x1, i1, w1) = part(ce.0, cf.0, cu.0);
            let (x2, i2, w2) = part(ce.1, cf.1, cu.1);
            let impact = [i1 * n1[0] + i2 * n2[0], i1 * n1[1] + i2 * n2[1]];
            let approach = [w1 * n1[0] + w2 * n2[0], w1 * n1[1] + w2 * n2[1]];
            let rest = [
                e[0] - x1 * n1[0] - x2 * n2[0],
                e[1] - x1 * n1[1] - x2 * n2[1],
            ];
            (norm(impact), norm(approach), rest, x1.hypot(x2))
        }
        None => {
            let (x, impact, approach) = part(dot(e, n1), dot(fdv, n1), dot(u_prev, n1));
            (impact, approach, [e[0] - x * n1[0], e[1] - x * n1[1]], x)
        }
    }
}

fn sticking(rule: &'static str, r: usize, name: &str, i: usize, ep: Episode) -> Sticking {
    Sticking {
        rule,
        rod: r,
        rod_name: name.to_string(),
        node: i,
        step: ep.step,
        t: ep.t,
        last_step: ep.last_step,
        last_t: ep.last_t,
        count: ep.count,
    }
}

/// The detector on a live run: `gripsim run --check` and `gripsim sweep` listen with it.
pub struct DetectObserver {
    pub detector: Detector,
}

impl DetectObserver {
    pub fn new(sc: &Scenario, th: &Thresholds) -> Self {
        Self {
            detector: Detector::new(sc, th),
        }
    }
}

impl Observer for DetectObserver {
    fn on_event(&mut self, event: &Event<'_>) {
        match event {
            Event::ConstraintAdded(c) => self.detector.contact(ContactSample::of(c, true)),
            Event::ConstraintReleased(c, _) => self.detector.contact(ContactSample::of(c, false)),
            Event::StepEnd {
                step,
                t,
                dt,
                rods,
                bodies,
                contacts,
                ..
            } => {
                let samples: Vec<RodSample<'_>> = rods.iter().map(RodSample::from).collect();
                self.detector.step(*step, *t, *dt, &samples);
                let pressures: Vec<PressureSample> = contacts
                    .iter()
                    .filter_map(PressureSample::of_view)
                    .collect();
                if !pressures.is_empty() {
                    self.detector.pressure(*step, *t, &pressures);
                }
                if let Some(b) = bodies.first() {
                    let q: Vec<&[f64]> = rods.iter().map(|r| r.q).collect();
                    let touching = contacts
                        .iter()
                        .any(|c| c.rod != usize::MAX && c.obstacle == b.obstacle);
                    self.detector.grasp(
                        *step,
                        *t,
                        &q,
                        Some(crate::events::xy(b.position)),
                        touching,
                    );
                }
            }
            _ => {}
        }
    }
}

/// Scan a whole run held in memory (the streaming readers feed a [`Detector`] directly).
pub fn detect(run: &super::read::Run, th: &Thresholds) -> Findings {
    let mut d = Detector::for_recording(&run.scenario, th, run.meta.f32());
    let mut contacts = run.contacts.iter().peekable();
    for st in &run.steps {
        while let Some(c) = contacts.next_if(|c| c.step <= st.step) {
            d.contact(c.sample());
        }
        let samples: Vec<RodSample<'_>> = st.rods.iter().map(|r| r.sample()).collect();
        d.step(st.step, st.t, st.dt, &samples);
        st.grasp(&mut d);
        st.pressure(&mut d);
    }
    d.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        th: Thresholds,
    }

    #[test]
    fn flag_defaults_are_the_documented_defaults() {
        let cli = Cli::try_parse_from(["x"]).unwrap();
        assert_eq!(cli.th, Thresholds::DEFAULT);
        assert!(Thresholds::DEFAULT.validate().is_ok());
        let bad = Thresholds {
            stick_window: Some(0.0),
            ..Thresholds::DEFAULT
        };
        assert!(bad.validate().is_err());
    }

    /// A free node of the seed grasp's prong stopped from 1 m/s towards a surface within one
    /// step and free at both of the step's ends: `unexplained` unless the step reports a
    /// constraint on that node (added or released in it), whose normal then explains the stop.
    fn spikes_of_a_stop_within_a_step(event: Option<ContactSample>) -> Vec<(String, usize)> {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-grasp-r5.toml");
        let sc = Scenario::load(&path, &[]).unwrap();
        let mut d = Detector::new(&sc, &Thresholds::DEFAULT);
        let rod = d.rods[0].clone();
        let i = rod.n - 1;
        let (q, zero) = (rod.q0.clone(), vec![0.0; 2 * rod.n]);
        let mut u0 = zero.clone();
        u0[2 * i + 1] = -1.0;
        let flags = vec![false; rod.n];
        let u1 = zero.clone();
        let normal = zero.clone();
        let s = |u| {
            [RodSample {
                q: &q,
                u,
                reaction: &zero,
                normal: &normal,
                normal2: &[],
                in_contact: &flags,
                q_predictor: &q,
            }]
        };
        d.step(0, 0.0, 0.0, &s(u0.as_slice()));
        if let Some(c) = event {
            d.contact(c);
        }
        d.step(1, 1e-6, 1e-6, &s(u1.as_slice()));
        d.finish()
            .spikes
            .iter()
            .map(|sp| (sp.kind.to_string(), sp.node))
            .collect()
    }

    /// A free stream of the seed grasp's prong whose bend alternates between a tip pulled
    /// 1 mm aside and the rest shape (so the elastic force at the step ends alternates
    /// between large and nothing), its velocities made by `integrator`'s relation; `kick`
    /// adds 1 m/s to the tip's y velocity at step 6 (a rest shape at its end). What a
    /// detector for `detector` finds (kind, node, step).
    fn spikes_of_a_stream(
        integrator: crate::scenario::Integrator,
        detector: crate::scenario::Integrator,
        kick: bool,
    ) -> Vec<(String, usize, u64)> {
        use crate::scenario::Integrator as I;
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-grasp-r5.toml");
        let mut sc = Scenario::load(&path, &[]).unwrap();
        sc.solve.integrator = detector;
        let mut d = Detector::new(&sc, &Thresholds::DEFAULT);
        let rod = d.rods[0].clone();
        assert_eq!(
            rod.damping_time, 0.0,
            "the test computes the undamped force"
        );
        let (n, tip, dt) = (rod.n, rod.n - 1, 1e-5);
        let q_at = |k: u64| {
            let mut q = rod.q0.clone();
            if k % 2 == 1 {
                q[2 * tip + 1] += 1e-3;
            }
            q
        };
        let force = |q: &[f64]| {
            let mut f = vec![0.0; 2 * n];
            smooth_force(&rod, sc.solve.gravity, q, &mut f);
            f
        };
        let (zero, flags) = (vec![0.0; 2 * n], vec![false; n]);
        let (mut u_prev, mut u) = (zero.clone(), zero.clone());
        let mut f0 = force(&q_at(0));
        for k in 0..12u64 {
            let q = q_at(k);
            let f1 = force(&q);
            if k > 0 {
                let un: Vec<f64> = (0..2 * n)
                    .map(|j| {
                        let m = rod.mass[j / 2];
                        if rod.clamped[j / 2] {
                            return 0.0;
                        }
                        let kicked = if kick && k == 6 && j == 2 * tip + 1 {
                            1.0
                        } else {
                            0.0
                        };
                        kicked
                            + match integrator {
                                I::BackwardEuler => u[j] + dt * f1[j] / m,
                                I::TrBdf2 => u[j] + 0.5 * dt * (f0[j] + f1[j]) / m,
                                // Constant dt: α = 1/3, β = 2 dt/3 (the first step backward Euler).
                                I::Bdf2 if k == 1 => u[j] + dt * f1[j] / m,
                                I::Bdf2 => {
                                    u[j] + (u[j] - u_prev[j]) / 3.0 + 2.0 * dt * f1[j] / (3.0 * m)
                                }
                            }
                    })
                    .collect();
                u_prev = std::mem::replace(&mut u, un);
            }
            let sample = RodSample {
                q: &q,
                u: &u,
                reaction: &zero,
                normal: &zero,
                normal2: &[],
                in_contact: &flags,
                q_predictor: &q,
            };
            d.step(k, k as f64 * dt, if k == 0 { 0.0 } else { dt }, &[sample]);
            f0 = f1;
        }
        d.finish()
            .spikes
            .iter()
            .map(|sp| (sp.kind.to_string(), sp.node, sp.step))
            .collect()
    }

    /// Each integrator's smooth velocity change is explained under its own relation: a force
    /// that changes much within a step made TR-BDF2 and BDF2 runs read as spikes under
    /// backward Euler's Δt f₁/m alone (the damped jaws' first touch; docs/replay.md). A kick
    /// is still found under every relation.
    #[test]
    fn each_integrators_smooth_steps_are_explained_and_a_kick_is_not() {
        use crate::scenario::Integrator as I;
        let tip = Rod::new(
            &Scenario::load(
                &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                    .join("scenarios/seed-grasp-r5.toml"),
                &[],
            )
            .unwrap()
            .rods[0],
        )
        .n - 1;
        for i in [I::BackwardEuler, I::Bdf2, I::TrBdf2] {
            assert_eq!(spikes_of_a_stream(i, i, false), vec![], "{i:?}");
            assert_eq!(
                spikes_of_a_stream(i, i, true),
                vec![("unexplained".to_string(), tip, 6)],
                "{i:?}"
            );
        }
        // Under backward Euler's relation the second-order streams are spikes.
        for i in [I::Bdf2, I::TrBdf2] {
            let found = spikes_of_a_stream(i, I::BackwardEuler, false);
            assert!(
                found.iter().any(|s| s.0 == "unexplained"),
                "{i:?}: {found:?}"
            );
        }
    }

    #[test]
    fn a_node_held_for_part_of_a_step_is_explained_by_that_constraint() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-grasp-r5.toml");
        let i = Rod::new(&Scenario::load(&path, &[]).unwrap().rods[0]).n - 1;
        // No constraint change in the step: the stop is unexplained.
        assert_eq!(
            spikes_of_a_stop_within_a_step(None),
            vec![("unexplained".to_string(), i)]
        );
        for added in [true, false] {
            let c = ContactSample {
                step: 1,
                t: 1e-6,
                rod: 0,
                node: i,
                added,
                normal: [0.0, 1.0],
            };
            assert_eq!(spikes_of_a_stop_within_a_step(Some(c)), vec![], "{added}");
            // A change of a thrown-away attempt (another time) explains nothing.
            let stale = ContactSample { t: 2e-6, ..c };
            assert_eq!(
                spikes_of_a_stop_within_a_step(Some(stale)),
                vec![("unexplained".to_string(), i)]
            );
            // Nor does a surface the node was not stopped against (normal along the rod's x).
            let side = ContactSample {
                normal: [1.0, 0.0],
                ..c
            };
            assert_eq!(
                spikes_of_a_stop_within_a_step(Some(side)),
                vec![("unexplained".to_string(), i)]
            );
        }
    }
}
