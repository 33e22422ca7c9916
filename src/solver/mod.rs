//! The time stepper: implicit Euler + Newton per rod, the modified mass method for contact,
//! fixed or proximity step sizes, dt back-off on failure. No I/O: everything it does is
//! reported through [`crate::events::Observer`].

pub mod banded;
pub mod contact;
pub mod newton;

use crate::events::{
    ContactChange, Event, Observer, Phase, ReleaseReason, RodInfo, RodStepView, RunInfo,
};
use crate::model::Rod;
use crate::obstacle::Obstacle;
use crate::scenario::{Mode, Scenario, Stepping};
use newton::{NewtonFailure, NewtonOptions, RodWork};

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
    /// Deepest penetration of any node after the corrector (m, ≥ 0).
    pub max_penetration: f64,
    /// Simulated time reached (s); the load factor in static mode.
    pub t: f64,
}

/// Output arrays of one rod for the step-end view.
#[derive(Debug, Clone)]
struct RodOut {
    reaction: Vec<f64>,
    impulse: Vec<f64>,
    drive_force: Vec<f64>,
    normal: Vec<f64>,
    obstacle: Vec<usize>,
    in_contact: Vec<bool>,
    stress: Vec<f64>,
    gap: Vec<f64>,
    q_pred: Vec<f64>,
}

impl RodOut {
    fn new(n: usize) -> Self {
        Self {
            reaction: vec![0.0; 2 * n],
            impulse: vec![0.0; 2 * n],
            drive_force: vec![0.0; 2 * n],
            normal: vec![0.0; 2 * n],
            obstacle: vec![usize::MAX; n],
            in_contact: vec![false; n],
            stress: vec![0.0; n],
            gap: vec![f64::INFINITY; n],
            q_pred: vec![0.0; 2 * n],
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
    /// A free node would cross an obstacle at this fraction of the step.
    Split { theta: f64, rod: usize, node: usize },
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
}

impl Simulation {
    pub fn new(scenario: &Scenario) -> Self {
        let rods: Vec<Rod> = scenario.rods.iter().map(Rod::new).collect();
        let g = scenario.solve.gravity;
        let work = rods.iter().map(|r| RodWork::new(r, g)).collect();
        let out = rods.iter().map(|r| RodOut::new(r.n)).collect();
        let infos = rods.iter().map(|r| r.info()).collect();
        Self {
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
        }
    }

    pub fn rod_infos(&self) -> &[RodInfo] {
        &self.infos
    }

    /// Run to the end (dynamic: t_end; static: full load).
    pub fn run<O: Observer>(&mut self, obs: &mut O) -> Result<RunStats, SimError> {
        let sc_name = self.scenario.name.clone();
        let text = self.scenario.text.clone();
        let info = RunInfo {
            scenario_name: &sc_name,
            scenario_text: &text,
            rods: &self.infos.clone(),
            obstacles: &self.obstacles.clone(),
            mode: self.scenario.solve.mode,
        };
        obs.on_event(&Event::RunStart(&info));
        // The initial state as step 0, so recordings start from the rest shape.
        if obs_wants_steps(obs) {
            for r in 0..self.rods.len() {
                self.fill_outputs(r, 0.0, true);
            }
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
            Stepping::Adaptive => self.next_dt.clamp(s.dt_min, s.dt_max),
        }
    }

    /// Whether any non-driven node is within `d` of an obstacle.
    pub fn any_node_within(&self, d: f64) -> bool {
        for (r, rod) in self.rods.iter().enumerate() {
            let q = &self.work[r].q;
            for i in 0..rod.n {
                if rod.clamped[i] {
                    continue;
                }
                let p = [q[2 * i], q[2 * i + 1]];
                for o in &self.obstacles {
                    if o.lower_bound(p) < d && o.query(p).distance < d {
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
        let max_backoff = self.scenario.solve.max_backoff;
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
            // Avoid a sliver of a last step.
            if t_end - (self.t + dt) < 1e-9 * dt {
                dt = t_end - self.t;
            }
            let mut attempt = 0u32;
            let mut allow_split = self.scenario.solve.time_of_impact;
            loop {
                match self.try_step(dt, 0.0, allow_split, obs) {
                    Ok(()) => {
                        recovery_cap = if attempt > 0 {
                            2.0 * dt
                        } else if recovery_cap < nominal {
                            2.0 * recovery_cap
                        } else {
                            f64::INFINITY
                        };
                        break;
                    }
                    Err(StepError::Split { theta, .. }) => {
                        // Static texts: no allocation in the step loop when nobody listens.
                        obs.on_event(&Event::DtChanged {
                            step: self.step + 1,
                            t: self.t,
                            old: dt,
                            new: dt * theta,
                            reason:
                                "time of impact: a free node reaches an obstacle inside the step",
                        });
                        dt *= theta;
                        allow_split = false;
                        prev_nominal = dt;
                    }
                    Err(StepError::Reject { dt: retry, .. }) => {
                        obs.on_event(&Event::DtChanged {
                            step: self.step + 1,
                            t: self.t,
                            old: dt,
                            new: retry,
                            reason:
                                "adaptive: the error estimate exceeds the tolerance, step rejected",
                        });
                        self.stats.rejected_steps += 1;
                        dt = retry;
                        prev_nominal = dt;
                    }
                    Err(StepError::Newton { rod, fail }) => {
                        obs.on_event(&Event::NewtonFailed {
                            step: self.step + 1,
                            t: self.t,
                            dt,
                            rod,
                            node: fail.node,
                            residual: fail.residual,
                            reason: fail.reason,
                        });
                        if attempt >= max_backoff {
                            return Err(SimError::Diverged {
                                step: self.step + 1,
                                t: self.t,
                                rod: self.rods[rod].name.clone(),
                                node: fail.node,
                                residual: fail.residual,
                                reason: fail.reason.to_string(),
                                backoffs: attempt,
                                dt,
                            });
                        }
                        attempt += 1;
                        self.stats.backoffs += 1;
                        obs.on_event(&Event::DtChanged {
                            step: self.step + 1,
                            t: self.t,
                            old: dt,
                            new: dt * 0.5,
                            reason: "back-off after a Newton failure",
                        });
                        dt *= 0.5;
                        self.next_dt = dt;
                        prev_nominal = dt;
                    }
                }
            }
        }
        Ok(())
    }

    fn run_static<O: Observer>(&mut self, obs: &mut O) -> Result<(), SimError> {
        let mut lambda = 0.0;
        let mut inc = self.scenario.solve.load_step;
        let mut backoffs = 0u32;
        while lambda < 1.0 {
            self.check_interrupt()?;
            let target = (lambda + inc).min(1.0);
            match self.try_step(1.0, target, false, obs) {
                Ok(()) => {
                    lambda = target;
                    inc = (inc * 1.5).min(1.0);
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
                            rod: self.rods[f.rod].name.clone(),
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
        Ok(())
    }

    /// One step (dynamic: size dt; static: load factor `lambda`). Transactional: on failure the
    /// state is as before.
    fn try_step<O: Observer>(
        &mut self,
        dt: f64,
        lambda: f64,
        allow_split: bool,
        obs: &mut O,
    ) -> Result<(), StepError> {
        let solve = &self.scenario.solve;
        let dynamic = solve.mode == Mode::Dynamic;
        let t1 = if dynamic { self.t + dt } else { lambda };
        let step = self.step + 1;
        let opt = NewtonOptions {
            c: if dynamic { 1.0 / (dt * dt) } else { 0.0 },
            dt: if dynamic { dt } else { 0.0 },
            lambda: if dynamic { 1.0 } else { lambda },
            force_tol: solve.force_tol,
            step_tol: solve.step_tol,
            max_iterations: solve.max_newton_iterations,
        };
        let max_passes = solve
            .max_contact_passes
            .max(3 * self.rods.iter().map(|r| r.n as u32).max().unwrap_or(1));
        obs.on_event(&Event::StepBegin {
            step,
            t: self.t,
            dt,
        });
        let wants_iter = obs.wants_iterations();
        let wants_steps = obs_wants_steps(obs);
        let mut newton_iterations = 0u32;
        let mut passes_total = 0u32;

        for r in 0..self.rods.len() {
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            w.contact_saved.copy_from_slice(&w.contact);
            w.step_dt = if dynamic { dt } else { 0.0 };
            // Prescribed displacement of driven nodes; initial guess for the rest.
            let (d1, _) = rod.drive.motion(t1.max(0.0));
            for i in 0..rod.n {
                for a in 0..2 {
                    let k = 2 * i + a;
                    if rod.clamped[i] {
                        w.dq[k] = if dynamic {
                            rod.q0[k] + d1[a] - w.q[k]
                        } else {
                            0.0
                        };
                    } else if dynamic {
                        w.dq[k] = dt * w.u[k] + dt * dt * w.a[k];
                    } else {
                        w.dq[k] = 0.0;
                    }
                }
            }
            // Carried-over constraints: re-linearise at the current position.
            for i in 0..rod.n {
                if let Some(c) = w.contact[i] {
                    let p = [w.q[2 * i], w.q[2 * i + 1]];
                    let prox = self.obstacles[c.obstacle].query(p);
                    let mut nc = contact::constraint_at(c.obstacle, &prox);
                    nc.second = c.second.map(|s| {
                        contact::corner_at(s.obstacle, &self.obstacles[s.obstacle].query(p))
                    });
                    w.contact[i] = Some(nc);
                }
            }
        }

        for r in 0..self.rods.len() {
            let mut pass = 0u32;
            loop {
                let phase = if pass == 0 {
                    Phase::Predictor
                } else {
                    Phase::Corrector
                };
                let rod = &self.rods[r];
                let res = {
                    let w = &mut self.work[r];
                    if wants_iter {
                        let t = self.t;
                        let mut cb = |it: newton::IterationReport<'_>| {
                            obs.on_event(&Event::Iteration {
                                step,
                                t,
                                phase: if dynamic { phase } else { Phase::Static },
                                pass,
                                iteration: it.iteration,
                                rod: r,
                                residual: it.residual,
                                update: it.update,
                                q: it.q,
                            });
                        };
                        newton::solve(rod, w, &opt, Some(&mut cb))
                    } else {
                        newton::solve(rod, w, &opt, None)
                    }
                };
                match res {
                    Ok(it) => newton_iterations += it,
                    Err(fail) => {
                        self.rollback();
                        return Err(StepError::Newton { rod: r, fail });
                    }
                }
                if pass == 0 && wants_steps {
                    let w = &self.work[r];
                    let o = &mut self.out[r];
                    o.q_pred.copy_from_slice(&w.qn);
                }
                if pass == 0 && allow_split && dynamic {
                    if let Some((theta, node)) = self.impact_fraction(r) {
                        if theta * dt >= self.min_split_dt(dt) {
                            self.rollback();
                            return Err(StepError::Split {
                                theta,
                                rod: r,
                                node,
                            });
                        }
                    }
                }
                // Release adhesive constraints, detect new penetrations, re-linearise.
                let mut changed = false;
                let rod = &self.rods[r];
                let w = &mut self.work[r];
                let relin_tol = 1e-10 * rod.length;
                for i in 0..rod.n {
                    if rod.clamped[i] {
                        continue;
                    }
                    let p = [w.qn[2 * i], w.qn[2 * i + 1]];
                    match w.contact[i] {
                        Some(c) => {
                            let reaction = [w.r[2 * i], w.r[2 * i + 1]];
                            // The reaction's normal parts: along n, or on n₁ and n₂ in a corner.
                            let (rn, rn2) = contact::normal_parts(&c, reaction);
                            let release = |k: usize, normal: [f64; 2]| {
                                Event::ConstraintReleased(
                                    ContactChange {
                                        step,
                                        t: t1,
                                        pass: pass + 1,
                                        rod: r,
                                        node: i,
                                        obstacle: k,
                                        normal,
                                        gap: self.obstacles[k].query(p).distance,
                                        reaction,
                                        z: 0.0,
                                    },
                                    ReleaseReason::Adhesive,
                                )
                            };
                            if rn < 0.0 && !c.locked {
                                // In a corner the node stays on the other surface, unless that
                                // one pulls too.
                                let keep = c.second.filter(|_| rn2 >= 0.0);
                                w.contact[i] = keep.map(|s| contact::Constraint {
                                    obstacle: s.obstacle,
                                    normal: s.normal,
                                    target: s.target,
                                    locked: false,
                                    second: None,
                                });
                                changed = true;
                                obs.on_event(&release(c.obstacle, c.normal));
                                if let (None, Some(s)) = (keep, c.second) {
                                    obs.on_event(&release(s.obstacle, s.normal));
                                }
                                // Mark so that a re-penetration in this step locks it.
                                w.contact_saved_mark(i);
                            } else if let (true, Some(s)) = (rn2 < 0.0, c.second) {
                                w.contact[i] = Some(contact::Constraint { second: None, ..c });
                                changed = true;
                                obs.on_event(&release(s.obstacle, s.normal));
                            } else {
                                let mut nc = c;
                                let prox = self.obstacles[c.obstacle].query(p);
                                if prox.distance < -relin_tol {
                                    nc = contact::constraint_at(c.obstacle, &prox);
                                    nc.locked = c.locked;
                                    nc.second = c.second;
                                }
                                if let Some(s) = c.second {
                                    let prox = self.obstacles[s.obstacle].query(p);
                                    if prox.distance < -relin_tol {
                                        nc.second = Some(contact::corner_at(s.obstacle, &prox));
                                    }
                                } else if let Some((k, prox)) = contact::deepest_other(
                                    &self.obstacles,
                                    p,
                                    c.obstacle,
                                    -relin_tol,
                                ) {
                                    // Held on one obstacle but inside another: a corner (or,
                                    // for nearly parallel surfaces, the other one instead).
                                    let (held, corner) = contact::add_surface(&nc, k, &prox);
                                    nc = held;
                                    let un =
                                        |n: [f64; 2]| n[0] * w.u[2 * i] + n[1] * w.u[2 * i + 1];
                                    let qk = [w.q[2 * i], w.q[2 * i + 1]];
                                    let z = if dynamic {
                                        (corner.target
                                            - (corner.normal[0] * qk[0] + corner.normal[1] * qk[1]))
                                            / dt
                                            - un(corner.normal)
                                    } else {
                                        0.0
                                    };
                                    obs.on_event(&Event::ConstraintAdded(ContactChange {
                                        step,
                                        t: t1,
                                        pass: pass + 1,
                                        rod: r,
                                        node: i,
                                        obstacle: k,
                                        normal: corner.normal,
                                        gap: prox.distance,
                                        reaction: [0.0; 2],
                                        z,
                                    }));
                                }
                                if nc != c {
                                    w.contact[i] = Some(nc);
                                    changed = true;
                                }
                            }
                        }
                        None => {
                            if let Some((k, prox)) = contact::deepest(&self.obstacles, p, 0.0) {
                                let mut c = contact::constraint_at(k, &prox);
                                c.locked = w.was_released(i);
                                w.contact[i] = Some(c);
                                changed = true;
                                let qk = [w.q[2 * i], w.q[2 * i + 1]];
                                let un = c.normal[0] * w.u[2 * i] + c.normal[1] * w.u[2 * i + 1];
                                let z = if dynamic {
                                    (c.target - (c.normal[0] * qk[0] + c.normal[1] * qk[1])) / dt
                                        - un
                                } else {
                                    0.0
                                };
                                obs.on_event(&Event::ConstraintAdded(ContactChange {
                                    step,
                                    t: t1,
                                    pass: pass + 1,
                                    rod: r,
                                    node: i,
                                    obstacle: k,
                                    normal: c.normal,
                                    gap: prox.distance,
                                    reaction: [0.0; 2],
                                    z,
                                }));
                            }
                        }
                    }
                }
                if !changed {
                    break;
                }
                pass += 1;
                passes_total += 1;
                if pass > max_passes {
                    self.rollback();
                    return Err(StepError::Newton {
                        rod: r,
                        fail: NewtonFailure {
                            node: 0,
                            residual: 0.0,
                            reason: "the contact set did not settle",
                            iterations: 0,
                        },
                    });
                }
            }
        }

        if dynamic && solve.stepping == Stepping::Adaptive {
            let err = self.error_estimate(dt);
            let factor = if err > 0.0 {
                (0.9 / err.sqrt()).clamp(0.2, 2.0)
            } else {
                2.0
            };
            let (dt_min, dt_max) = (solve.dt_min, solve.dt_max);
            if err > 1.0 && dt > dt_min * (1.0 + 1e-12) {
                self.rollback();
                return Err(StepError::Reject {
                    dt: (dt * factor).max(dt_min),
                });
            }
            self.next_dt = (dt * factor).clamp(dt_min, dt_max);
        }

        // Accept: advance the state.
        let mut max_pen = self.stats.max_penetration;
        for r in 0..self.rods.len() {
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            for k in 0..2 * rod.n {
                let qn = w.q[k] + w.dq[k];
                if dynamic {
                    let un = w.dq[k] / dt;
                    w.a[k] = (un - w.u[k]) / dt;
                    w.u[k] = un;
                } else {
                    w.u[k] = 0.0;
                }
                w.q[k] = qn;
            }
            w.clear_release_marks();
            for i in 0..rod.n {
                if rod.clamped[i] {
                    continue;
                }
                let p = [w.q[2 * i], w.q[2 * i + 1]];
                for o in &self.obstacles {
                    if o.lower_bound(p) < 0.0 {
                        let d = o.query(p).distance;
                        if -d > max_pen {
                            max_pen = -d;
                        }
                    }
                }
            }
        }
        self.stats.max_penetration = max_pen;
        self.stats.steps += 1;
        self.stats.newton_iterations += newton_iterations as u64;
        self.stats.contact_passes += passes_total as u64;
        self.step = step;
        self.t = t1;
        self.stats.t = t1;
        self.last_dt = dt;
        self.check_drives(obs);
        if wants_steps {
            for r in 0..self.rods.len() {
                self.fill_outputs(r, if dynamic { dt } else { 0.0 }, false);
            }
            self.emit_step_end(obs, dt, newton_iterations, passes_total);
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
            let Some((k, _)) = contact::deepest(&self.obstacles, p1, 0.0) else {
                continue;
            };
            let o = &self.obstacles[k];
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
            if theta < 1.0 - 1e-9 && best.map_or(true, |(t, _)| theta < t) {
                best = Some((theta, i));
            }
        }
        best
    }

    /// Adaptive stepping: the embedded error estimate of the step just solved, as a multiple
    /// of the tolerance. Backward Euler's position differs from the trapezoidal rule's by
    /// ½ dt (u_{k+1} − u_k) = ½ dt² a_{k+1}, its leading local error; the tolerance is
    /// atol + rtol · L (the rod length). Nodes whose contact state changed in this step are
    /// left out: their velocity jump is the modelled inelastic impact, not truncation error.
    fn error_estimate(&self, dt: f64) -> f64 {
        let s = &self.scenario.solve;
        let mut err: f64 = 0.0;
        for (rod, w) in self.rods.iter().zip(&self.work) {
            // A particle's length scale is 1 m (see `Rod::length`).
            let tol = s.atol + s.rtol * rod.length;
            for i in 0..rod.n {
                if rod.clamped[i] || w.contact_saved[i].is_some() != w.contact[i].is_some() {
                    continue;
                }
                let ax = (w.dq[2 * i] / dt - w.u[2 * i]) / dt;
                let ay = (w.dq[2 * i + 1] / dt - w.u[2 * i + 1]) / dt;
                let e = 0.5 * dt * dt * ax.hypot(ay) / tol;
                if e > err {
                    err = e;
                }
            }
        }
        err
    }

    fn rollback(&mut self) {
        for w in &mut self.work {
            w.contact.copy_from_slice(&w.contact_saved);
            w.clear_release_marks();
        }
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
                if let Some((k, prox)) = contact::deepest(&self.obstacles, p, 0.0) {
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

    fn fill_outputs(&mut self, r: usize, dt: f64, initial: bool) {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let o = &mut self.out[r];
        for i in 0..rod.n {
            let c = if initial { None } else { w.contact[i] };
            let (rx, ry) = if initial {
                (0.0, 0.0)
            } else {
                (w.r[2 * i], w.r[2 * i + 1])
            };
            if rod.clamped[i] {
                o.reaction[2 * i] = 0.0;
                o.reaction[2 * i + 1] = 0.0;
                o.drive_force[2 * i] = rx;
                o.drive_force[2 * i + 1] = ry;
            } else {
                o.drive_force[2 * i] = 0.0;
                o.drive_force[2 * i + 1] = 0.0;
                let (gx, gy) = if c.is_some() { (rx, ry) } else { (0.0, 0.0) };
                o.reaction[2 * i] = gx;
                o.reaction[2 * i + 1] = gy;
            }
            o.impulse[2 * i] = o.reaction[2 * i] * dt;
            o.impulse[2 * i + 1] = o.reaction[2 * i + 1] * dt;
            match c {
                Some(c) if !rod.clamped[i] => {
                    o.normal[2 * i] = c.normal[0];
                    o.normal[2 * i + 1] = c.normal[1];
                    o.obstacle[i] = c.obstacle;
                    o.in_contact[i] = true;
                }
                _ => {
                    o.normal[2 * i] = 0.0;
                    o.normal[2 * i + 1] = 0.0;
                    o.obstacle[i] = usize::MAX;
                    o.in_contact[i] = false;
                }
            }
            o.gap[i] = contact::gap(&self.obstacles, [w.q[2 * i], w.q[2 * i + 1]], rod.length);
        }
        if initial {
            o.q_pred.copy_from_slice(&w.q);
        }
        rod.bending_stress(&w.q, &mut o.stress);
    }

    fn emit_step_end<O: Observer>(
        &self,
        obs: &mut O,
        dt: f64,
        newton_iterations: u32,
        passes: u32,
    ) {
        let views: Vec<RodStepView<'_>> = self
            .out
            .iter()
            .zip(&self.work)
            .map(|(o, w)| RodStepView {
                q: &w.q,
                u: &w.u,
                reaction: &o.reaction,
                impulse: &o.impulse,
                drive_force: &o.drive_force,
                normal: &o.normal,
                contact_obstacle: &o.obstacle,
                in_contact: &o.in_contact,
                bending_stress: &o.stress,
                gap: &o.gap,
                q_predictor: &o.q_pred,
            })
            .collect();
        obs.on_event(&Event::StepEnd {
            step: self.step,
            t: self.t,
            dt,
            newton_iterations,
            passes,
            rods: &views,
        });
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
                    rod: self.rods[f.rod].name.clone(),
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
            w
        };
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
