//! The time stepper: implicit Euler + Newton per rod, the modified mass method for contact,
//! fixed or proximity step sizes, dt back-off on failure. No I/O: everything it does is
//! reported through [`crate::events::Observer`].

pub mod banded;
mod contacts;
pub mod coupled;
mod edge_sets;
mod edges;
mod edges_coupled;
mod fruit;
pub mod joints;
mod joints_coupled;
pub mod newton;
mod outputs;
mod release;
mod stability;
mod statics;
mod step;
mod trbdf2;

/// TR-BDF2's stage fraction γ = 2 − √2: its first stage's constraint changes carry the time
/// t + γ dt (the replay detector recognises them by it).
pub use trbdf2::GAMMA as TR_BDF2_GAMMA;

use crate::actuation::{clamp_centroid, Actuator, Measure};
use crate::contact::{self, friction::Coulomb};
use crate::events::{ContactView, Event, Observer, RodInfo, RunInfo};
use crate::model::Rod;
use crate::obstacle::Obstacle;
use crate::scenario::{Mode, Scenario, Stepping};
use crate::world::body::Pose;
use crate::world::Body;
use coupled::{BodyScratch, RodCoupling};
use newton::{NewtonFailure, RodWork};

/// Why a run stopped early.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error(
        "diverged at step {step}, t = {t:.9} s: rod {rod:?} node {node}: {reason} (residual {residual:.3e} N) \
         after {backoffs} dt back-offs down to dt = {dt:.3e} s"
    )]
    Diverged {
        step: u64,
        t: f64,
        rod: String,
        node: usize,
        residual: f64,
        reason: String,
        backoffs: u32,
        dt: f64,
    },
    #[error("interrupted at step {step}, t = {t:.9} s")]
    Interrupted { step: u64, t: f64 },
    #[error("actuator {actuator:?} at step {step}, t = {t:.9} s: {message}")]
    Actuation {
        step: u64,
        t: f64,
        actuator: String,
        message: String,
    },
}

/// Counters of a run.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct RunStats {
    pub steps: u64,
    pub newton_iterations: u64,
    pub contact_passes: u64,
    pub backoffs: u64,
    /// Adaptive stepping: attempts rejected by the error estimate.
    pub rejected_steps: u64,
    /// Steps cut short at a time of impact or of release.
    pub split_steps: u64,
    /// Jacobians factorised by the per-rod Newton solves, over every attempt (rejected and
    /// split ones included; the coupled rod–body solve is not counted).
    pub jacobian_factorizations: u64,
    /// BDF2: free node-steps estimated at first order (contact, or no smooth history), over
    /// every attempt the error estimate looked at (0 under backward Euler).
    pub first_order_node_steps: u64,
    /// Deepest penetration of any node after the corrector (m, ≥ 0).
    pub max_penetration: f64,
    /// Simulated time reached (s); the load factor in static mode.
    pub t: f64,
    /// Dynamic mode: the energy balance of the rods.
    pub energy: crate::energy::balance::Balance,
    /// Static mode: the smallest eigenvalue of the free-DOF Hessian at the end (N/m; None
    /// when no rod could be checked), and whether it is negative.
    pub min_eigenvalue: Option<f64>,
    pub unstable_equilibrium: bool,
}

/// Output arrays of one rod for the step-end view.
#[derive(Debug, Clone)]
struct RodOut {
    reaction: Vec<f64>,
    impulse: Vec<f64>,
    drive_force: Vec<f64>,
    normal: Vec<f64>,
    obstacle: Vec<usize>,
    normal2: Vec<f64>,
    obstacle2: Vec<usize>,
    in_contact: Vec<bool>,
    stress: Vec<f64>,
    gap: Vec<f64>,
    q_pred: Vec<f64>,
    /// BDF2's contact impulse over the history's last interval (the step's impulse, or the
    /// step before a sliver and the sliver together).
    impulse_hist: Vec<f64>,
    /// TR-BDF2: the trapezoidal stage's contact impulse (added to the step's).
    impulse_stage: Vec<f64>,
}

impl RodOut {
    fn new(n: usize) -> Self {
        Self {
            reaction: vec![0.0; 2 * n],
            impulse: vec![0.0; 2 * n],
            drive_force: vec![0.0; 2 * n],
            normal: vec![0.0; 2 * n],
            obstacle: vec![usize::MAX; n],
            normal2: vec![0.0; 2 * n],
            obstacle2: vec![usize::MAX; n],
            in_contact: vec![false; n],
            stress: vec![0.0; n],
            gap: vec![f64::INFINITY; n],
            q_pred: vec![0.0; 2 * n],
            impulse_hist: vec![0.0; 2 * n],
            impulse_stage: vec![0.0; 2 * n],
        }
    }
}

impl StepError {
    /// As a failure report (static mode never splits or rejects; this keeps it total).
    fn into_failure(self) -> StepFailure {
        match self {
            StepError::Newton { rod, fail } => StepFailure { rod, fail },
            StepError::Split { rod, node, .. } => StepFailure {
                rod,
                fail: NewtonFailure {
                    node,
                    residual: 0.0,
                    reason: "time-of-impact split",
                    iterations: 0,
                },
            },
            StepError::Reject { .. } => StepFailure {
                rod: 0,
                fail: NewtonFailure {
                    node: 0,
                    residual: 0.0,
                    reason: "step rejected",
                    iterations: 0,
                },
            },
        }
    }
}

struct StepFailure {
    rod: usize,
    fail: NewtonFailure,
}

/// Why a step attempt was not accepted.
enum StepError {
    /// Newton failed (or the contact set did not settle) on a rod.
    Newton { rod: usize, fail: NewtonFailure },
    /// A free node would cross an obstacle at this fraction of the step, or (`release`) a
    /// held node's reaction crosses zero or the friction cone there.
    Split {
        theta: f64,
        rod: usize,
        node: usize,
        release: bool,
    },
    /// Adaptive stepping: the error estimate exceeds the tolerance; retry with `dt`.
    Reject { dt: f64 },
}

/// A simulation in progress.
pub struct Simulation {
    pub scenario: Scenario,
    pub rods: Vec<Rod>,
    pub obstacles: Vec<Obstacle>,
    pub work: Vec<RodWork>,
    out: Vec<RodOut>,
    infos: Vec<RodInfo>,
    pub t: f64,
    pub step: u64,
    pub stats: RunStats,
    /// The step size used by the last accepted step.
    pub last_dt: f64,
    drive_warned: Vec<bool>,
    /// Adaptive stepping: the next step size proposed by the error estimate.
    pub next_dt: f64,
    /// Checked between steps; when it returns true the run stops with [`SimError::Interrupted`].
    pub interrupt: Option<Box<dyn Fn() -> bool + Send>>,
    /// Free rigid bodies (fruit).
    pub bodies: Vec<Body>,
    /// The actuation programs (the `[[actuator]]`s, then one per rod driven by its own
    /// `drive`), and each rod's program and mirror line.
    pub actuators: Vec<Actuator>,
    actuator_names: Vec<String>,
    rod_actuator: Vec<(usize, Option<f64>)>,
    /// Per obstacle: the free body that carries it (`usize::MAX` when fixed).
    body_of: Vec<usize>,
    /// Per obstacle: where detection sees it (None: fixed; a body at its start or trial pose).
    placement: Vec<Option<([f64; 2], Pose)>>,
    /// Per obstacle: whether it is a compliant fruit (met through the force law, not as a
    /// constraint).
    compliant: Vec<bool>,
    /// Per rod: how far its contact surface lies off its centreline (0 for centreline
    /// contact; h/2 or the section radius for `[contact] surface = "face"`).
    rod_offset: Vec<f64>,
    /// Coulomb coefficients per rod and obstacle, and per body and obstacle.
    rod_coulomb: Vec<Vec<Coulomb>>,
    body_coulomb: Vec<Vec<Coulomb>>,
    coupling: Vec<RodCoupling>,
    scratch: BodyScratch,
    /// Rods whose constraint set changed (re-solved in the next pass); rods solved with the
    /// bodies; whether the body group must be re-solved.
    dirty: Vec<bool>,
    is_member: Vec<bool>,
    group_dirty: bool,
    /// The step being solved is the first part of a step split at a time of impact or
    /// release.
    split_step: bool,
    /// Step-end outputs of the contacts and bodies.
    contact_out: Vec<ContactView>,
    body_out: Vec<BodyOut>,
    /// TR-BDF2: the state at the step's start, for a rejection after the first stage.
    stage_start: trbdf2::StageStart,
    /// Static mode: per edge contact (rod, segment, obstacle) its last re-linearisation in
    /// this load increment (weight, closest weight − weight), for the secant step.
    edge_history: Vec<(usize, usize, usize, f64, f64)>,
    /// `[[joint]]`s and the networks of rods they join (solved together).
    pub joints: joints::Joints,
}

/// Step-end outputs of one body.
#[derive(Debug, Clone, Copy, Default)]
struct BodyOut {
    force: [f64; 2],
    torque: f64,
}

impl Simulation {
    pub fn new(scenario: &Scenario) -> Self {
        let rods: Vec<Rod> = scenario.rods.iter().map(Rod::new).collect();
        let g = scenario.solve.gravity;
        let work = rod_works(scenario, &rods);
        let joints = joints::Joints::new(&scenario.joints, &rods, &work);
        let out = rods.iter().map(|r| RodOut::new(r.n)).collect();
        let infos = rods.iter().map(|r| r.info()).collect();
        let bodies: Vec<Body> = scenario.bodies.iter().map(|b| Body::new(b, g)).collect();
        let mut body_of = vec![usize::MAX; scenario.obstacles.len()];
        for (i, b) in scenario.bodies.iter().enumerate() {
            body_of[b.obstacle] = i;
        }
        let names = &scenario.obstacle_names;
        let rod_coulomb = rods
            .iter()
            .map(|r| {
                names
                    .iter()
                    .map(|o| scenario.friction.between(&r.name, o))
                    .collect()
            })
            .collect();
        let body_coulomb = scenario
            .bodies
            .iter()
            .map(|b| {
                names
                    .iter()
                    .map(|o| scenario.friction.between(&b.name, o))
                    .collect()
            })
            .collect();
        let n_rods = rods.len();
        let (actuators, actuator_names, rod_actuator) = build_actuators(scenario, &rods);
        let mut sim = Self {
            scenario: scenario.clone(),
            obstacles: scenario.obstacles.clone(),
            drive_warned: vec![false; rods.len()],
            rods,
            work,
            out,
            infos,
            t: 0.0,
            step: 0,
            stats: RunStats::default(),
            last_dt: scenario.solve.dt,
            next_dt: scenario.solve.dt,
            interrupt: None,
            body_out: vec![BodyOut::default(); bodies.len()],
            actuators,
            actuator_names,
            rod_actuator,
            bodies,
            body_of,
            placement: vec![None; scenario.obstacles.len()],
            compliant: (0..scenario.obstacles.len())
                .map(|k| matches!(scenario.materials.get(k), Some(Some(_))))
                .collect(),
            rod_offset: scenario
                .rods
                .iter()
                .map(|r| scenario.contact.offset(r))
                .collect(),
            rod_coulomb,
            body_coulomb,
            coupling: vec![RodCoupling::default(); n_rods],
            scratch: BodyScratch::default(),
            dirty: vec![false; n_rods],
            is_member: vec![false; n_rods],
            group_dirty: false,
            split_step: false,
            contact_out: Vec::new(),
            stage_start: Default::default(),
            edge_history: Vec::new(),
            joints,
        };
        sim.place_bodies(true);
        sim.start_balance();
        sim
    }

    /// The balance's starting point: kinetic energy of the free nodes and elastic energy.
    fn start_balance(&mut self) {
        let mut e0 = 0.0;
        for (rod, w) in self.rods.iter().zip(&mut self.work) {
            w.energy_start = w.energy;
            e0 += w.energy;
            for i in (0..rod.n).filter(|&i| !rod.clamped[i]) {
                let v2 = w.u[2 * i] * w.u[2 * i] + w.u[2 * i + 1] * w.u[2 * i + 1];
                self.stats.energy.kinetic_j += 0.5 * rod.mass[i] * v2;
            }
        }
        self.stats.energy.elastic_j = e0;
        self.stats.energy.initial_j = e0 + self.stats.energy.kinetic_j;
    }

    pub fn rod_infos(&self) -> &[RodInfo] {
        &self.infos
    }

    /// Run to the end (dynamic: t_end; static: full load).
    pub fn run<O: Observer>(&mut self, obs: &mut O) -> Result<RunStats, SimError> {
        let sc_name = self.scenario.name.clone();
        let text = self.scenario.text.clone();
        let info = RunInfo {
            dimension: 2,
            scenario_name: &sc_name,
            scenario_text: &text,
            rods: &self.infos.clone(),
            scene: crate::events::Scene::Planar {
                obstacles: &self.obstacles.clone(),
            },
            obstacle_names: &self.scenario.obstacle_names.clone(),
            bodies: &self.scenario.bodies.clone(),
            mode: self.scenario.solve.mode,
        };
        obs.on_event(&Event::RunStart(&info));
        for message in self.scenario.warnings() {
            obs.on_event(&Event::Warning {
                step: 0,
                t: 0.0,
                message: &message,
            });
        }
        // The initial state as step 0, so recordings start from the rest shape.
        if obs_wants_steps(obs) {
            for r in 0..self.rods.len() {
                self.fill_outputs(r, 0.0, true);
            }
            self.fill_contact_outputs(0.0);
            self.emit_step_end(obs, 0.0, 0, 0);
        }
        let result = match self.scenario.solve.mode {
            Mode::Dynamic => self.run_dynamic(obs),
            Mode::Static => self.run_static(obs),
        };
        let err = result.as_ref().err().map(|e| e.to_string());
        obs.on_event(&Event::RunEnd {
            steps: self.stats.steps,
            t: self.t,
            error: err.as_deref(),
        });
        result.map(|_| self.stats.clone())
    }

    fn nominal_dt(&self) -> f64 {
        let s = &self.scenario.solve;
        match s.stepping {
            Stepping::Fixed => s.dt,
            Stepping::Proximity => {
                if self.any_node_within(s.near_distance) {
                    s.dt_near
                } else {
                    s.dt
                }
            }
            Stepping::Adaptive => {
                // A squeeze that ends on the sensed grip is resolved in steps the sensor sees.
                let grip = self
                    .actuators
                    .iter()
                    .filter_map(|a| a.grip_end_resolution())
                    .fold(s.dt_max, f64::min);
                self.next_dt
                    .clamp(s.dt_min, s.dt_max)
                    .min(grip.max(s.dt_min))
            }
        }
    }

    /// Whether any non-driven node is within `d` of an obstacle (or a free body within `d` of
    /// a fixed obstacle).
    pub fn any_node_within(&self, d: f64) -> bool {
        for b in &self.bodies {
            let placed = crate::world::body::Placed {
                shape: &self.obstacles[b.spec.obstacle],
                c0: b.spec.centroid,
                pose: b.pose,
            };
            let mut found = Vec::new();
            for (k, o) in self.obstacles.iter().enumerate() {
                if self.body_of[k] == usize::MAX {
                    contact::body::points(&placed, o, d, &mut found);
                    if !found.is_empty() {
                        return true;
                    }
                }
            }
        }
        for (r, rod) in self.rods.iter().enumerate() {
            let q = &self.work[r].q;
            let s = self.rod_surfaces(r);
            for i in 0..rod.n {
                if rod.clamped[i] {
                    continue;
                }
                let p = [q[2 * i], q[2 * i + 1]];
                for k in 0..s.len() {
                    if s.lower_bound(k, p) < d && s.query(k, p).distance < d {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Stop with [`SimError::Interrupted`] when the [`Simulation::interrupt`] hook says so.
    fn check_interrupt(&self) -> Result<(), SimError> {
        match &self.interrupt {
            Some(f) if f() => Err(SimError::Interrupted {
                step: self.step,
                t: self.t,
            }),
            _ => Ok(()),
        }
    }

    fn run_dynamic<O: Observer>(&mut self, obs: &mut O) -> Result<(), SimError> {
        let t_end = self.scenario.solve.t_end;
        let mut prev_nominal = f64::NAN;
        let mut recovery_cap = f64::INFINITY;
        while self.t < t_end * (1.0 - 1e-12) {
            self.check_interrupt()?;
            let nominal = self.nominal_dt();
            // After a back-off the step grows back by 2x per accepted step, not at once.
            let planned = nominal.min(recovery_cap);
            if prev_nominal.is_finite() && planned != prev_nominal {
                // Static texts: no allocation in the step loop.
                let reason = match self.scenario.solve.stepping {
                    _ if planned == recovery_cap => "dt grows back after a back-off",
                    Stepping::Proximity if planned < prev_nominal => {
                        "proximity: a node is near an obstacle"
                    }
                    Stepping::Proximity => "proximity: all nodes are clear",
                    Stepping::Adaptive => "adaptive: the step the error estimate allows",
                    Stepping::Fixed => "back to the nominal dt",
                };
                obs.on_event(&Event::DtChanged {
                    step: self.step + 1,
                    t: self.t,
                    old: prev_nominal,
                    new: planned,
                    reason,
                });
            }
            prev_nominal = planned;
            let mut dt = planned.min(t_end - self.t);
            // Avoid a sliver of a last step: t is a sum of steps, so after 1e5 steps it may
            // fall short of t_end by ~1e-12 s, and a step that short makes eq. 2's reaction
            // (a difference divided by dt²) round-off (it released held contacts).
            if t_end - (self.t + dt) < 1e-6 * dt {
                dt = t_end - self.t;
            }
            let attempts = self.take_step(&mut dt, &mut prev_nominal, obs)?;
            recovery_cap = if attempts > 0 {
                2.0 * dt
            } else if recovery_cap < nominal {
                2.0 * recovery_cap
            } else {
                f64::INFINITY
            };
            self.after_step(obs)?;
        }
        Ok(())
    }

    /// Take one step starting at `dt`: split at a time of impact, shrink on rejection, back
    /// off on a Newton failure. Returns the number of back-offs (`dt` ends as the size taken).
    fn take_step<O: Observer>(
        &mut self,
        dt: &mut f64,
        prev_nominal: &mut f64,
        obs: &mut O,
    ) -> Result<u32, SimError> {
        let mut attempt = 0u32;
        let mut allow_split = self.scenario.solve.time_of_impact;
        let mut split_from = None;
        loop {
            self.split_step = split_from.is_some();
            let result = self.try_step(*dt, 0.0, allow_split, obs);
            self.split_step = false;
            let (new_dt, reason) = match result {
                Ok(()) => {
                    if let Some(rest) = split_from {
                        self.resume_after_split(rest);
                    }
                    return Ok(attempt);
                }
                Err(StepError::Split { theta, release, .. }) => {
                    allow_split = false;
                    split_from = Some(*dt * (1.0 - theta));
                    self.stats.split_steps += 1;
                    let reason = if release {
                        "time of release: a held node's reaction crosses zero (or the friction cone) inside the step"
                    } else {
                        "time of impact: a free node reaches an obstacle inside the step"
                    };
                    (*dt * theta, reason)
                }
                Err(StepError::Reject { dt: retry, .. }) => {
                    self.stats.rejected_steps += 1;
                    (
                        retry,
                        "adaptive: the error estimate exceeds the tolerance, step rejected",
                    )
                }
                Err(StepError::Newton { rod, fail }) => {
                    self.newton_failed(*dt, rod, &fail, attempt, obs)?;
                    attempt += 1;
                    self.stats.backoffs += 1;
                    self.next_dt = *dt * 0.5;
                    (*dt * 0.5, "back-off after a Newton failure")
                }
            };
            // Static texts: no allocation in the step loop when nobody listens.
            obs.on_event(&Event::DtChanged {
                step: self.step + 1,
                t: self.t,
                old: *dt,
                new: new_dt,
                reason,
            });
            *dt = new_dt;
            *prev_nominal = new_dt;
        }
    }

    /// Adaptive stepping after a step cut short at a time of impact: the error estimate of
    /// that (often tiny) step says nothing about the steps after it, so the next one may be as
    /// long as the rest of the step that was cut (the estimate of that step decides).
    fn resume_after_split(&mut self, rest: f64) {
        let s = &self.scenario.solve;
        if s.stepping == Stepping::Adaptive {
            self.next_dt = self.next_dt.max(rest).clamp(s.dt_min, s.dt_max);
        }
    }

    /// Report a Newton failure; stop the run when the back-offs are used up.
    fn newton_failed<O: Observer>(
        &self,
        dt: f64,
        rod: usize,
        fail: &NewtonFailure,
        attempt: u32,
        obs: &mut O,
    ) -> Result<(), SimError> {
        obs.on_event(&Event::NewtonFailed {
            step: self.step + 1,
            t: self.t,
            dt,
            rod,
            node: fail.node,
            residual: fail.residual,
            reason: fail.reason,
        });
        if attempt >= self.scenario.solve.max_backoff {
            return Err(SimError::Diverged {
                step: self.step + 1,
                t: self.t,
                rod: self.part_name(rod),
                node: fail.node,
                residual: fail.residual,
                reason: fail.reason.to_string(),
                backoffs: attempt,
                dt,
            });
        }
        Ok(())
    }

    /// What happens between accepted steps: the actuation programs measure their drive
    /// forces and move on to their next phase when an end is reached.
    fn after_step<O: Observer>(&mut self, obs: &mut O) -> Result<(), SimError> {
        for g in 0..self.actuators.len() {
            let pivot = self.actuators[g].pivot_world(self.t);
            let mut m = Measure::default();
            for (r, rod) in self.rods.iter().enumerate() {
                let (a, mirror) = self.rod_actuator[r];
                if a != g {
                    continue;
                }
                let w = &self.work[r];
                // The force the prong's elasticity puts on its clamp, ∇E at the clamped nodes:
                // what a force sensor at the prong's root reads. The clamped nodes' own
                // inertia and weight belong to the actuator, so a jolt in the motion law is
                // not read as grip.
                for i in (0..rod.n).filter(|&i| rod.clamped[i]) {
                    let x = [w.q[2 * i], w.q[2 * i + 1]];
                    m.add(x, [w.grad[2 * i], w.grad[2 * i + 1]], mirror, pivot);
                }
            }
            let switches =
                self.actuators[g]
                    .commit(self.t, &m)
                    .map_err(|e| SimError::Actuation {
                        step: self.step,
                        t: self.t,
                        actuator: self.actuator_names[g].clone(),
                        message: e.to_string(),
                    })?;
            for s in switches {
                let label = match s.to {
                    Some(k) => self.actuators[g].program().phases[k].label(),
                    None => String::new(),
                };
                obs.on_event(&Event::PhaseChanged {
                    step: self.step,
                    t: s.t,
                    actuator: g,
                    from: s.from,
                    to: s.to,
                    name: &label,
                    reason: s.reason,
                });
            }
        }
        Ok(())
    }

    /// The name of a rod, or of the free body when `rod` is `usize::MAX` (a body's failure).
    fn part_name(&self, rod: usize) -> String {
        match self.rods.get(rod) {
            Some(r) => r.name.clone(),
            None => self
                .bodies
                .first()
                .map(|b| format!("free body {}", b.spec.name))
                .unwrap_or_default(),
        }
    }

    fn run_static<O: Observer>(&mut self, obs: &mut O) -> Result<(), SimError> {
        let mut lambda = 0.0;
        let mut inc = self.scenario.solve.load_step;
        let mut backoffs = 0u32;
        let amp = self.scenario.solve.imperfection;
        for (rod, w) in self.rods.iter_mut().zip(&mut self.work) {
            stability::imperfection(rod, w, amp);
        }
        while lambda < 1.0 {
            self.check_interrupt()?;
            let target = (lambda + inc).min(1.0);
            self.edge_history.clear();
            match self.try_step(1.0, target, false, obs) {
                Ok(()) => {
                    lambda = target;
                    inc = (inc * 1.5).min(1.0);
                }
                Err(StepError::Split { rod, node, .. }) => {
                    inc = self.cut_increment(inc, rod, node, obs)?;
                }
                Err(e) => {
                    let f = e.into_failure();
                    obs.on_event(&Event::NewtonFailed {
                        step: self.step + 1,
                        t: target,
                        dt: inc,
                        rod: f.rod,
                        node: f.fail.node,
                        residual: f.fail.residual,
                        reason: f.fail.reason,
                    });
                    backoffs += 1;
                    self.stats.backoffs += 1;
                    inc *= 0.5;
                    if inc < 1e-6 || backoffs > 40 {
                        return Err(SimError::Diverged {
                            step: self.step + 1,
                            t: target,
                            rod: self.part_name(f.rod),
                            node: f.fail.node,
                            residual: f.fail.residual,
                            reason: format!("static solve: {}", f.fail.reason),
                            backoffs,
                            dt: inc,
                        });
                    }
                }
            }
        }
        self.check_stability();
        if amp > 0.0 {
            self.seek_stable_branch(obs)?;
        }
        Ok(())
    }

    /// Static mode: a point went through an obstacle in the load increment, or a contact
    /// released and locked in it still pulls (solver/statics.rs): halve the increment
    /// (counted in `split_steps`), or stop when it would fall below 1e-6.
    fn cut_increment<O: Observer>(
        &mut self,
        inc: f64,
        rod: usize,
        node: usize,
        obs: &mut O,
    ) -> Result<f64, SimError> {
        let reason = "static: a point went through an obstacle in this load increment, or a \
                      contact released and locked in it still pulls; increment cut";
        self.stats.split_steps += 1;
        if inc * 0.5 < 1e-6 {
            return Err(SimError::Diverged {
                step: self.step + 1,
                t: self.t + inc,
                rod: self.part_name(rod),
                node,
                residual: 0.0,
                reason: format!("static solve: {reason} below a load increment of 1e-6"),
                backoffs: self.stats.backoffs as u32,
                dt: inc,
            });
        }
        obs.on_event(&Event::DtChanged {
            step: self.step + 1,
            t: self.t,
            old: inc,
            new: inc * 0.5,
            reason,
        });
        Ok(inc * 0.5)
    }

    /// Static mode with an imperfection: the load ramp can still land on the unstable branch
    /// past a bifurcation (near-straight, bent against the imperfection). Push the shape along
    /// the unstable mode, both ways, by growing amounts, and re-solve at full load until the
    /// equilibrium is stable.
    fn seek_stable_branch<O: Observer>(&mut self, obs: &mut O) -> Result<(), SimError> {
        for k in 0..12 {
            if !self.stats.unstable_equilibrium {
                return Ok(());
            }
            let push = 0.02 * (1 + k / 2) as f64;
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            let saved: Vec<Vec<f64>> = self.work.iter().map(|w| w.q.clone()).collect();
            for (rod, w) in self.rods.iter().zip(&mut self.work) {
                stability::push_along_mode(rod, w, push, sign);
            }
            if self.try_step(1.0, 1.0, false, obs).is_err() {
                for (w, q) in self.work.iter_mut().zip(saved) {
                    w.q = q;
                }
                continue;
            }
            self.check_stability();
        }
        Ok(())
    }

    /// Smallest step a time-of-impact split may produce.
    fn min_split_dt(&self, dt: f64) -> f64 {
        let s = &self.scenario.solve;
        if s.stepping == Stepping::Adaptive {
            s.dt_min
        } else {
            1e-6 * dt
        }
    }

    /// For rod `r` after its predictor: the earliest fraction θ ∈ (0, 1) of the step at which a
    /// free node that started outside every obstacle reaches one, along the path a backward
    /// Euler sub-step would take (root of the signed distance by bracketed false position).
    fn impact_fraction(&self, r: usize) -> Option<(f64, usize)> {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let mut best: Option<(f64, usize)> = None;
        for i in 0..rod.n {
            if rod.clamped[i] || w.contact_saved[i].is_some() {
                continue;
            }
            let p1 = [w.qn[2 * i], w.qn[2 * i + 1]];
            let Some((k, _)) = contact::deepest(&self.rod_surfaces(r), p1, 0.0) else {
                continue;
            };
            if self.body_of[k] != usize::MAX {
                // A body moves inside the step: its contact starts where the step ends.
                continue;
            }
            let (o, off) = (&self.obstacles[k], self.rod_offset[r]);
            // Backward Euler over a sub-step θ dt with the predictor's acceleration:
            // p(θ) = p₀ + θ (dt u) + θ² (Δq − dt u), which is p₁ at θ = 1.
            let p0 = [w.q[2 * i], w.q[2 * i + 1]];
            let v = [w.dt_u(i, 0), w.dt_u(i, 1)];
            let acc = [p1[0] - p0[0] - v[0], p1[1] - p0[1] - v[1]];
            let at = |th: f64| {
                o.query([
                    p0[0] + th * v[0] + th * th * acc[0],
                    p0[1] + th * v[1] + th * th * acc[1],
                ])
                .distance
                    - off
            };
            let (mut a, mut b) = (0.0, 1.0);
            let (mut fa, mut fb) = (at(0.0), at(1.0));
            if !(fa > 0.0 && fb < 0.0) {
                continue;
            }
            // Illinois false position: superlinear and bracketed.
            for _ in 0..60 {
                let c = (a * fb - b * fa) / (fb - fa);
                let fc = at(c);
                if fc > 0.0 {
                    a = c;
                    fa = fc;
                    fb *= 0.5;
                } else {
                    b = c;
                    fb = fc;
                    fa *= 0.5;
                }
                if (b - a) < 1e-12 || fc == 0.0 {
                    break;
                }
            }
            // The end of the bracket on or just inside the surface: the step ends at contact.
            let theta = b;
            if theta < 1.0 - 1e-9 && best.is_none_or(|(t, _)| theta < t) {
                best = Some((theta, i));
            }
        }
        best
    }

    /// Adaptive stepping: the embedded error estimates of the step just solved, as multiples
    /// of the tolerance: (first-order nodes, second-order nodes). Backward Euler's position
    /// differs from the trapezoidal rule's by ½ dt (u_{k+1} − u_k) = ½ dt² a_{k+1}, its leading
    /// local error. BDF2's is (2/9) dt³ q⁽³⁾ ≈ (2/9) dt² |a_{k+1} − a_k|. Nodes that drop to
    /// first order under BDF2 (contact, no smooth history) are counted in
    /// [`RunStats::first_order_node_steps`] and estimated as backward Euler. The tolerance is
    /// atol + rtol · L (the rod length). Nodes whose contact state changed in this step are
    /// left out: their velocity jump is the modelled inelastic impact, not truncation error —
    /// except a release taken on the BDF2 row, estimated as a free node (its acceleration
    /// jumps by the reaction it had on the surface, which the estimate sees).
    /// A node held at both ends of the step counts its tangential part only
    /// ([`held_part`]): along the contact normal its position is the constraint's.
    fn error_estimate(&mut self, dt: f64) -> (f64, f64) {
        let s = &self.scenario.solve;
        let (mut err, mut err2): (f64, f64) = (0.0, 0.0);
        let tr = s.integrator == crate::scenario::Integrator::TrBdf2;
        let bdf2 = s.integrator == crate::scenario::Integrator::Bdf2 || tr;
        // TR-BDF2: `dt` is the whole step; the first-order rows below are the BDF2 stage's.
        let dt_row = if tr { (1.0 - trbdf2::GAMMA) * dt } else { dt };
        let mut first_order = 0u64;
        for (rod, w) in self.rods.iter().zip(&self.work) {
            // A particle's length scale is 1 m (see `Rod::length`).
            let tol = s.atol + s.rtol * rod.length;
            for i in 0..rod.n {
                let second = w.second_order(i);
                if rod.clamped[i]
                    || (!second && w.contact_saved[i].is_some() != w.contact[i].is_some())
                {
                    continue;
                }
                if second && tr {
                    err2 = err2.max(tr_bdf2_error(w, i, dt) / tol);
                    continue;
                }
                if second {
                    let b = &w.bdf;
                    let mut da = [0.0; 2];
                    for (a, d) in da.iter_mut().enumerate() {
                        let k = 2 * i + a;
                        let un = (w.dq[k] - b.alpha * b.dq_prev[k]) / b.beta;
                        let hu = w.u[k] + b.alpha * (w.u[k] - b.u_prev[k]);
                        *d = (un - hu) / b.beta - w.a[k];
                    }
                    err2 = err2.max(2.0 / 9.0 * dt * dt * held_part(w.contact[i], da) / tol);
                    continue;
                }
                first_order += bdf2 as u64;
                let ax = (w.dq[2 * i] / dt_row - w.u[2 * i]) / dt_row;
                let ay = (w.dq[2 * i + 1] / dt_row - w.u[2 * i + 1]) / dt_row;
                err = err.max(0.5 * dt_row * dt_row * held_part(w.contact[i], [ax, ay]) / tol);
            }
        }
        self.stats.first_order_node_steps += first_order;
        (err, err2)
    }

    /// Warn (once per rod) when a driven node enters an obstacle: driven nodes are not
    /// contact-constrained.
    fn check_drives<O: Observer>(&mut self, obs: &mut O) {
        for r in 0..self.rods.len() {
            if self.drive_warned[r] {
                continue;
            }
            let rod = &self.rods[r];
            for i in 0..rod.n {
                if !rod.clamped[i] {
                    continue;
                }
                let p = [self.work[r].q[2 * i], self.work[r].q[2 * i + 1]];
                if let Some((k, prox)) = contact::deepest(&self.rod_surfaces(r), p, 0.0) {
                    let msg = format!(
                        "driven node {i} of rod {:?} entered obstacle.{k} ({}) by {:.3e} m at t = {:.6} s: driven nodes follow \
                         their drive and are not contact-constrained; give the drive a stop_travel or stop_time",
                        rod.name,
                        self.obstacles[k].kind(),
                        -prox.distance,
                        self.t
                    );
                    obs.on_event(&Event::Warning {
                        step: self.step,
                        t: self.t,
                        message: &msg,
                    });
                    self.drive_warned[r] = true;
                    break;
                }
            }
        }
    }

    /// Take exactly one dynamic step of size `dt` (no time-of-impact split, no error
    /// control, no back-off): for library users who drive the clock themselves, and for the
    /// kernel benchmarks.
    pub fn advance<O: Observer>(&mut self, dt: f64, obs: &mut O) -> Result<(), SimError> {
        match self.try_step(dt, 0.0, false, obs) {
            Ok(()) => Ok(()),
            Err(e) => {
                let f = e.into_failure();
                Err(SimError::Diverged {
                    step: self.step + 1,
                    t: self.t,
                    rod: self.part_name(f.rod),
                    node: f.fail.node,
                    residual: f.fail.residual,
                    reason: f.fail.reason.to_string(),
                    backoffs: 0,
                    dt,
                })
            }
        }
    }

    /// Current positions of rod `r` (interleaved).
    pub fn positions(&self, r: usize) -> &[f64] {
        &self.work[r].q
    }

    pub fn velocities(&self, r: usize) -> &[f64] {
        &self.work[r].u
    }

    /// Set the state of rod `r` (for tests and studies that start from a computed shape).
    pub fn set_state(&mut self, r: usize, q: &[f64], u: &[f64]) {
        self.work[r].q.copy_from_slice(q);
        self.work[r].u.copy_from_slice(u);
        self.work[r].a.fill(0.0);
        self.work[r].bdf.hist.fill(false);
        self.work[r].bdf.settled.fill(false);
        self.work[r].bdf.dt_prev = 0.0;
        let rod = &self.rods[r];
        let w = &mut self.work[r];
        let mut g = vec![0.0; 2 * rod.n];
        w.energy = if rod.n > 1 {
            newton::assemble(rod, &w.free_index, q, &mut g, None)
        } else {
            0.0
        };
        self.stats.energy = Default::default();
        self.start_balance();
    }

    /// Replace the dead loads of rod `r` (N per DOF, interleaved).
    pub fn set_loads(&mut self, r: usize, load: &[f64]) {
        let rod = &mut self.rods[r];
        rod.load.copy_from_slice(load);
        let g = self.scenario.solve.gravity;
        self.work[r] = {
            let mut w = RodWork::new(rod, g);
            w.q.copy_from_slice(&self.work[r].q);
            w.u.copy_from_slice(&self.work[r].u);
            let mut g = vec![0.0; 2 * rod.n];
            if rod.n > 1 {
                w.energy = newton::assemble(rod, &w.free_index, &w.q, &mut g, None);
            }
            w
        };
        self.stats.energy = Default::default();
        self.start_balance();
    }
}

/// The actuators of a scenario (its `[[actuator]]`s, then one per rod driven by its own
/// `drive`), their names for messages, and each rod's actuator and mirror line.
#[allow(clippy::type_complexity)]
/// Each rod's Newton workspace, with the compliant fruits its nodes can press into.
fn rod_works(scenario: &Scenario, rods: &[Rod]) -> Vec<RodWork> {
    let g = scenario.solve.gravity;
    let mut work: Vec<RodWork> = rods.iter().map(|r| RodWork::new(r, g)).collect();
    let mut body_of = vec![usize::MAX; scenario.obstacles.len()];
    for (i, b) in scenario.bodies.iter().enumerate() {
        body_of[b.obstacle] = i;
    }
    for (w, spec) in work.iter_mut().zip(&scenario.rods) {
        w.compliant = contact::compliant::circles_for(
            spec,
            scenario.contact.offset(spec),
            &scenario.obstacles,
            &scenario.materials,
            &body_of,
        );
        for c in &mut w.compliant {
            c.coulomb = scenario
                .friction
                .between(&spec.name, &scenario.obstacle_names[c.obstacle]);
        }
        w.edge_mode = scenario.contact.points == crate::scenario::contact::ContactPoints::Edges;
    }
    work
}

/// The actuators, their names, and per rod (actuator, its fixed offset if any).
type Actuators = (Vec<Actuator>, Vec<String>, Vec<(usize, Option<f64>)>);

fn build_actuators(scenario: &Scenario, rods: &[Rod]) -> Actuators {
    let (programs, rod_actuator) = crate::scenario::actuation::groups(scenario);
    let actuators: Vec<Actuator> = programs
        .into_iter()
        .enumerate()
        .map(|(g, p)| {
            let nodes = rods
                .iter()
                .zip(&rod_actuator)
                .filter(|(_, a)| a.0 == g)
                .flat_map(|(r, a)| {
                    (0..r.n)
                        .filter(|&i| r.clamped[i])
                        .map(move |i| ([r.q0[2 * i], r.q0[2 * i + 1]], a.1.is_some()))
                });
            let c0 = clamp_centroid(nodes, p.mirror_x);
            Actuator::new(p, c0)
        })
        .collect();
    let actuator_names = (0..actuators.len())
        .map(|g| match scenario.actuators.get(g) {
            Some(a) => a.name.clone(),
            None => rod_actuator
                .iter()
                .position(|a| a.0 == g)
                .map(|r| format!("drive of rod {:?}", rods[r].name))
                .unwrap_or_default(),
        })
        .collect();
    (actuators, actuator_names, rod_actuator)
}

/// The part of a node's error estimate `v` (a position error or the acceleration change it
/// stands for) that the integrator makes: all of it for a free node; for a node held against
/// one surface its component along the surface (the constraint puts it on the surface, so
/// along the normal the position is exact, and the normal part of its acceleration is the
/// contact's support or impact — the step after a time of impact starts on the surface and
/// stops the node along the normal, which is not truncation error); nothing for a node held
/// in a corner (both directions are constrained).
/// TR-BDF2's local position error at node i after its BDF2 stage, the whole step `dt`:
/// k dt³ q⁽³⁾ with k = (−3γ² + 4γ − 2)/(12 (2 − γ)) ≈ −0.0404 (Hosea & Shampine 1996), where
/// dt² q⁽³⁾ ≈ 2 (u₀/γ − u_γ/(γ(1−γ)) + u₁/(1−γ)) from the three velocities of the step.
fn tr_bdf2_error(w: &RodWork, i: usize, dt: f64) -> f64 {
    let g = trbdf2::GAMMA;
    let k = (-3.0 * g * g + 4.0 * g - 2.0) / (12.0 * (2.0 - g));
    let b = &w.bdf;
    let mut d = [0.0; 2];
    for (a, d) in d.iter_mut().enumerate() {
        let j = 2 * i + a;
        let u1 = (w.dq[j] - b.alpha * b.dq_prev[j]) / b.beta;
        *d = 2.0 * (b.u_prev[j] / g - w.u[j] / (g * (1.0 - g)) + u1 / (1.0 - g));
    }
    k.abs() * dt * held_part(w.contact[i], d)
}

fn held_part(c: Option<crate::contact::Constraint>, v: [f64; 2]) -> f64 {
    match c {
        None => v[0].hypot(v[1]),
        Some(c) if c.second.is_some() => 0.0,
        Some(c) => (v[0] * c.normal[1] - v[1] * c.normal[0]).abs(),
    }
}

fn obs_wants_steps<O: Observer>(obs: &O) -> bool {
    obs.wants_steps()
}

impl RodWork {
    /// dt·u of DOF (node i, axis a) for the step being solved.
    fn dt_u(&self, i: usize, a: usize) -> f64 {
        self.u[2 * i + a] * self.step_dt
    }

    /// Remember that node i was released in this step.
    fn contact_saved_mark(&mut self, i: usize) {
        self.released.push(i);
    }
    fn was_released(&self, i: usize) -> bool {
        self.released.contains(&i)
    }
    fn clear_release_marks(&mut self) {
        self.released.clear();
    }
}
