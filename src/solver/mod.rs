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

struct StepFailure {
    rod: usize,
    fail: NewtonFailure,
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
        while self.t < t_end * (1.0 - 1e-12) {
            self.check_interrupt()?;
            let nominal = self.nominal_dt();
            if prev_nominal.is_finite() && nominal != prev_nominal {
                let reason = if nominal < prev_nominal {
                    "proximity: a node is near an obstacle"
                } else {
                    "proximity: all nodes are clear"
                };
                obs.on_event(&Event::DtChanged {
                    step: self.step + 1,
                    t: self.t,
                    old: prev_nominal,
                    new: nominal,
                    reason,
                });
            }
            prev_nominal = nominal;
            let mut dt = nominal.min(t_end - self.t);
            // Avoid a sliver of a last step.
            if t_end - (self.t + dt) < 1e-9 * dt {
                dt = t_end - self.t;
            }
            let mut attempt = 0u32;
            loop {
                match self.try_step(dt, 0.0, obs) {
                    Ok(()) => break,
                    Err(f) => {
                        let rod = f.rod;
                        obs.on_event(&Event::NewtonFailed {
                            step: self.step + 1,
                            t: self.t,
                            dt,
                            rod,
                            node: f.fail.node,
                            residual: f.fail.residual,
                            reason: f.fail.reason,
                        });
                        if attempt >= max_backoff {
                            return Err(SimError::Diverged {
                                step: self.step + 1,
                                t: self.t,
                                rod: self.rods[rod].name.clone(),
                                node: f.fail.node,
                                residual: f.fail.residual,
                                reason: f.fail.reason.to_string(),
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
            match self.try_step(1.0, target, obs) {
                Ok(()) => {
                    lambda = target;
                    inc = (inc * 1.5).min(1.0);
                }
                Err(f) => {
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
        obs: &mut O,
    ) -> Result<(), StepFailure> {
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
                    w.contact[i] = Some(contact::constraint_at(c.obstacle, &prox));
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
                        return Err(StepFailure { rod: r, fail });
                    }
                }
                if pass == 0 && wants_steps {
                    let w = &self.work[r];
                    let o = &mut self.out[r];
                    o.q_pred.copy_from_slice(&w.qn);
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
                            let rn = c.normal[0] * w.r[2 * i] + c.normal[1] * w.r[2 * i + 1];
                            if rn < 0.0 && !c.locked {
                                w.contact[i] = None;
                                changed = true;
                                obs.on_event(&Event::ConstraintReleased(
                                    ContactChange {
                                        step,
                                        t: t1,
                                        pass: pass + 1,
                                        rod: r,
                                        node: i,
                                        obstacle: c.obstacle,
                                        normal: c.normal,
                                        gap: self.obstacles[c.obstacle].query(p).distance,
                                        reaction: [w.r[2 * i], w.r[2 * i + 1]],
                                        z: 0.0,
                                    },
                                    ReleaseReason::Adhesive,
                                ));
                                // Mark so that a re-penetration in this step locks it.
                                w.contact_saved_mark(i);
                            } else {
                                let prox = self.obstacles[c.obstacle].query(p);
                                if prox.distance < -relin_tol {
                                    let mut nc = contact::constraint_at(c.obstacle, &prox);
                                    nc.locked = c.locked;
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
                    return Err(StepFailure {
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
