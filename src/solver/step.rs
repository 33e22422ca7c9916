//! One step of the modified mass method, in the order it happens: begin (carried constraints,
//! driven nodes, initial guesses), solve with the current constraint sets (predictor, then
//! corrector passes), update the sets (contact::* decides), accept.

use super::coupled::Coupled;
use super::newton::{self, IterationReport, NewtonFailure, NewtonOptions};
use super::{Simulation, StepError};
use crate::energy::balance::StepTerms;
use crate::events::{Event, Observer, Phase};
use crate::scenario::{Integrator, Mode, Stepping};

/// What every part of one step needs to know.
pub(super) struct StepCtx {
    pub dt: f64,
    pub t1: f64,
    pub step: u64,
    pub dynamic: bool,
    /// The scenario asks for a second-order integrator (dynamic mode): BDF2, or TR-BDF2 whose
    /// stages keep the same per-node histories.
    pub bdf2: bool,
    /// TR-BDF2's stage: 0 (not TR-BDF2), 1 (the trapezoidal stage over γ dt) or 2 (the BDF2
    /// stage over (1 − γ) dt). `dt` is the stage's size; `step_dt` the whole step's.
    pub stage: u8,
    pub step_dt: f64,
    pub opt: NewtonOptions,
    pub max_passes: u32,
    pub wants_iter: bool,
    pub wants_steps: bool,
}

/// The Newton start of free DOF k (node i) in a dynamic step of size dt: the step's own
/// update rule with the last step's acceleration a_k in place of a_{k+1}, so it is off by
/// O(dt³) where the motion is smooth. Backward Euler: Δq = dt u + dt² a. BDF2 (a node that
/// takes its row, see [`newton::RodWork::second_order`]): Δq = s + β² â, with s the BDF2
/// offset (the extrapolation of the last two steps) and â = a_k + ω (a_k − a_{k−1}) the
/// acceleration extrapolated linearly (a_k alone after a sliver folded into the history),
/// which makes the start O(dt⁴) off; backward Euler's start there is off by ½ dt² a and
/// costs a second Newton iteration on most steps.
#[inline]
fn predictor(w: &newton::RodWork, i: usize, k: usize, dt: f64) -> f64 {
    let b = &w.bdf;
    if b.on && b.hist[i] && !w.edge_nodes[i] {
        let a = if !b.merged {
            w.a[k] + b.omega * (w.a[k] - b.a_prev[k])
        } else {
            w.a[k]
        };
        b.s[k] + b.beta * b.beta * a
    } else {
        dt * w.u[k] + dt * dt * w.a[k]
    }
}

/// A split step shorter than this fraction of the step before it is a sliver, folded into the
/// BDF2 history (BDF2's step ratio ω = dt/dt_prev must stay below 1 + √2; the step after a
/// sliver would exceed it).
const SLIVER: f64 = 0.25;

impl Simulation {
    pub(super) fn step_ctx(
        &self,
        dt: f64,
        lambda: f64,
        wants_iter: bool,
        wants_steps: bool,
    ) -> StepCtx {
        let solve = &self.scenario.solve;
        let dynamic = solve.mode == Mode::Dynamic;
        StepCtx {
            dt,
            t1: if dynamic { self.t + dt } else { lambda },
            step: self.step + 1,
            dynamic,
            bdf2: dynamic && solve.integrator != Integrator::BackwardEuler,
            stage: 0,
            step_dt: dt,
            opt: NewtonOptions {
                c: if dynamic { 1.0 / (dt * dt) } else { 0.0 },
                dt: if dynamic { dt } else { 0.0 },
                lambda: if dynamic { 1.0 } else { lambda },
                force_tol: solve.force_tol,
                step_tol: solve.step_tol,
                max_iterations: solve.max_newton_iterations,
                chord: dynamic && solve.integrator != Integrator::BackwardEuler,
                error_tol: if dynamic
                    && solve.integrator == Integrator::TrBdf2
                    && solve.stepping == Stepping::Adaptive
                {
                    [
                        newton::NEWTON_ERROR_FRACTION * solve.atol,
                        newton::NEWTON_ERROR_FRACTION * solve.rtol,
                    ]
                } else {
                    [0.0; 2]
                },
            },
            max_passes: solve
                .max_contact_passes
                .max(3 * self.rods.iter().map(|r| r.n as u32).max().unwrap_or(1)),
            wants_iter,
            wants_steps,
        }
    }

    /// One step (dynamic: size dt; static: load factor `lambda`). Transactional: on failure the
    /// state is as before.
    pub(super) fn try_step<O: Observer>(
        &mut self,
        dt: f64,
        lambda: f64,
        allow_split: bool,
        obs: &mut O,
    ) -> Result<(), StepError> {
        if self.scenario.solve.mode == Mode::Dynamic
            && self.scenario.solve.integrator == Integrator::TrBdf2
        {
            return self.try_tr_bdf2(dt, allow_split, obs);
        }
        let ctx = self.step_ctx(dt, lambda, obs.wants_iterations(), obs.wants_steps());
        obs.on_event(&Event::StepBegin {
            step: ctx.step,
            t: self.t,
            dt,
        });
        let (newton_iterations, passes_total) = self.solve_stage(&ctx, allow_split, obs)?;
        if ctx.dynamic && self.scenario.solve.stepping == Stepping::Adaptive {
            self.adapt(dt)?;
        }
        self.accept(&ctx, obs, newton_iterations, passes_total);
        Ok(())
    }

    /// Begin a step (or a TR-BDF2 stage) and solve it until its constraint sets settle.
    /// Returns the Newton iterations and the contact changes over the passes.
    pub(super) fn solve_stage<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        allow_split: bool,
        obs: &mut O,
    ) -> Result<(u32, u32), StepError> {
        self.begin_step(ctx);
        let (mut newton_iterations, mut passes_total, mut pass) = (0u32, 0u32, 0u32);
        self.dirty.iter_mut().for_each(|d| *d = true);
        self.group_dirty = true;
        loop {
            newton_iterations += self.solve_pass(ctx, pass, obs)?;
            if pass == 0 {
                self.after_predictor(ctx, allow_split)?;
            }
            if allow_split && ctx.dynamic {
                self.split_at_release(ctx)?;
            }
            let mut changed = self.update_contacts(ctx, pass, obs);
            if !ctx.dynamic && changed == 0 {
                // Static mode: new contacts once the held ones have settled.
                changed = self.static_entries(ctx, pass, obs);
            }
            if changed == 0 {
                if !ctx.dynamic {
                    self.static_settled(ctx)?;
                }
                break;
            }
            pass += 1;
            passes_total += changed;
            if pass > ctx.max_passes {
                self.rollback();
                return Err(StepError::Newton {
                    rod: self.dirty.iter().position(|d| *d).unwrap_or(0),
                    fail: NewtonFailure {
                        node: 0,
                        residual: 0.0,
                        reason: "the contact set did not settle",
                        iterations: 0,
                    },
                });
            }
        }
        Ok((newton_iterations, passes_total))
    }

    /// Save the constraint sets, prescribe the driven nodes, guess the rest, re-linearise the
    /// constraints carried over from the last step at the current positions.
    fn begin_step(&mut self, ctx: &StepCtx) {
        for r in 0..self.rods.len() {
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            w.contact_saved.copy_from_slice(&w.contact);
            for s in w.law_slip.iter_mut().flatten() {
                s.switches = 0;
            }
            w.law_slip_saved.copy_from_slice(&w.law_slip);
            w.edges_saved.clone_from(&w.edges);
            w.edge_released.clear();
            w.step_dt = if ctx.dynamic { ctx.dt } else { 0.0 };
            if ctx.stage == 1 {
                w.begin_trap(ctx.dt);
            } else {
                w.begin_bdf2(ctx.bdf2, ctx.dt);
            }
            // Prescribed displacement of driven nodes; initial guess for the rest.
            let (g, mirror) = self.rod_actuator[r];
            let motion = self.actuators[g].motion(ctx.t1.max(0.0));
            for i in 0..rod.n {
                let x0 = [rod.q0[2 * i], rod.q0[2 * i + 1]];
                for a in 0..2 {
                    let k = 2 * i + a;
                    if rod.clamped[i] {
                        w.dq[k] = if ctx.dynamic {
                            motion.position_of(x0, mirror)[a] - w.q[k]
                        } else {
                            0.0
                        };
                    } else if ctx.dynamic {
                        w.dq[k] = predictor(w, i, k, ctx.dt);
                    } else {
                        w.dq[k] = 0.0;
                    }
                }
            }
        }
        for b in &mut self.bodies {
            b.contacts_saved.clone_from(&b.contacts);
            b.released.clear();
            for k in 0..3 {
                b.dx[k] = ctx.dt * b.v[k] + ctx.dt * ctx.dt * b.a[k];
            }
        }
        self.place_bodies(false);
        self.relinearise_carried(ctx);
    }

    /// Carried-over constraints: re-linearise at the positions at the start of the step; a
    /// node sliding on a fixed surface under BDF2 at the initial guess of its end position
    /// instead (the tangent line at the start leaves the end of a step on a curved surface
    /// O(dt²) off it, which makes the path first order; at the guess the offset is O(dt⁴)).
    fn relinearise_carried(&mut self, ctx: &StepCtx) {
        self.place_bodies(true);
        for r in 0..self.rods.len() {
            for i in 0..self.rods[r].n {
                if let Some(c) = self.work[r].contact[i] {
                    if c.law.is_some() {
                        let w = &self.work[r];
                        let p = [w.q[2 * i], w.q[2 * i + 1]];
                        self.work[r].contact[i] = self.law_hold_at(r, i, c.obstacle, p);
                        continue;
                    }
                    let w = &self.work[r];
                    let ahead = ctx.bdf2
                        && w.bdf.on
                        && w.bdf.hist[i]
                        && c.body.is_none()
                        && c.second.is_none()
                        && matches!(c.grip, crate::contact::Grip::Slide { .. });
                    let p = if ahead {
                        [w.q[2 * i] + w.dq[2 * i], w.q[2 * i + 1] + w.dq[2 * i + 1]]
                    } else {
                        [w.q[2 * i], w.q[2 * i + 1]]
                    };
                    let nc = self.relinearised(r, i, &c, p, true);
                    self.work[r].contact[i] = Some(nc);
                }
            }
            self.relinearise_edges_at_start(r);
            self.work[r].mark_edge_nodes();
        }
        for bi in 0..self.bodies.len() {
            self.relinearise_body_contacts(bi, ctx, true);
        }
        self.place_bodies(false);
    }

    /// Solve every rod (and body group) whose constraint set changed. Returns the Newton
    /// iterations spent.
    fn solve_pass<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        pass: u32,
        obs: &mut O,
    ) -> Result<u32, StepError> {
        let phase = match (ctx.dynamic, pass) {
            (false, _) => Phase::Static,
            (true, 0) => Phase::Predictor,
            _ => Phase::Corrector,
        };
        let mut iterations = 0u32;
        self.update_members();
        for r in 0..self.rods.len() {
            if !self.dirty[r] || self.is_member[r] || self.joints.network_of[r] != usize::MAX {
                continue;
            }
            iterations += self.solve_rod(ctx, r, phase, pass, obs)?;
        }
        for id in 0..self.joints.networks.len() {
            let rods = &self.joints.networks[id].rods;
            if rods.iter().any(|&r| self.is_member[r]) || !rods.iter().any(|&r| self.dirty[r]) {
                continue;
            }
            if rods.iter().any(|&r| !self.work[r].edges.is_empty()) {
                // Held by edge contacts: the edge rows and the joints in one dense system.
                let members = rods.clone();
                iterations +=
                    self.solve_coupled(ctx, &members, &[id], false, (phase, pass), obs)?;
            } else {
                iterations += self.solve_network(ctx, id, phase, pass, obs)?;
            }
        }
        if !self.bodies.is_empty() && self.group_dirty {
            iterations += self.solve_group(ctx, phase, pass, obs)?;
            self.place_bodies(false);
        }
        self.dirty.iter_mut().for_each(|d| *d = false);
        self.group_dirty = false;
        Ok(iterations)
    }

    fn solve_rod<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        r: usize,
        phase: Phase,
        pass: u32,
        obs: &mut O,
    ) -> Result<u32, StepError> {
        let rod = &self.rods[r];
        let w = &mut self.work[r];
        let res = if ctx.wants_iter {
            let (t, step) = (self.t, ctx.step);
            let mut cb = |it: IterationReport<'_>| {
                obs.on_event(&iteration_event(step, t, phase, pass, r, it));
            };
            newton::solve(rod, w, &ctx.opt, Some(&mut cb))
        } else {
            newton::solve(rod, w, &ctx.opt, None)
        };
        res.map_err(|fail| {
            self.rollback();
            StepError::Newton { rod: r, fail }
        })
    }

    /// A network of joined rods, solved together (src/solver/joints.rs).
    fn solve_network<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        id: usize,
        phase: Phase,
        pass: u32,
        obs: &mut O,
    ) -> Result<u32, StepError> {
        let res = if ctx.wants_iter {
            let (t, step) = (self.t, ctx.step);
            let mut cb = |r: usize, it: IterationReport<'_>| {
                obs.on_event(&iteration_event(step, t, phase, pass, r, it));
            };
            super::joints::solve_network(
                &mut self.joints,
                id,
                &self.rods,
                &mut self.work,
                &ctx.opt,
                Some(&mut cb),
            )
        } else {
            super::joints::solve_network(
                &mut self.joints,
                id,
                &self.rods,
                &mut self.work,
                &ctx.opt,
                None,
            )
        };
        res.map_err(|(rod, fail)| {
            self.rollback();
            StepError::Newton { rod, fail }
        })
    }

    /// The rods that touch a free body (with the networks they belong to), solved with the
    /// bodies.
    fn solve_group<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        phase: Phase,
        pass: u32,
        obs: &mut O,
    ) -> Result<u32, StepError> {
        let members: Vec<usize> = (0..self.rods.len())
            .filter(|&r| self.is_member[r])
            .collect();
        let nets: Vec<usize> = (0..self.joints.networks.len())
            .filter(|&id| self.is_member[self.joints.networks[id].rods[0]])
            .collect();
        self.solve_coupled(ctx, &members, &nets, true, (phase, pass), obs)
    }

    /// Rods `members` (with the networks `nets` among them) solved in one Newton with the free
    /// bodies (`with_bodies`) or with none (a network held by edge contacts).
    fn solve_coupled<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        members: &[usize],
        nets: &[usize],
        with_bodies: bool,
        (phase, pass): (Phase, u32),
        obs: &mut O,
    ) -> Result<u32, StepError> {
        let bodies: &mut [crate::world::Body] = if with_bodies {
            &mut self.bodies
        } else {
            &mut []
        };
        let mut group = Coupled {
            rods: &self.rods,
            work: &mut self.work,
            coupling: &mut self.coupling,
            members,
            bodies,
            scratch: &mut self.scratch,
            joints: &mut self.joints,
            networks: nets,
        };
        let res = if ctx.wants_iter {
            let (t, step) = (self.t, ctx.step);
            let mut cb = |r: usize, it: IterationReport<'_>| {
                obs.on_event(&iteration_event(step, t, phase, pass, r, it));
            };
            group.solve(&ctx.opt, Some(&mut cb))
        } else {
            group.solve(&ctx.opt, None)
        };
        res.map_err(|(rod, fail)| {
            self.rollback();
            StepError::Newton { rod, fail }
        })
    }

    /// Rods holding any node or segment against a free body join the body group; a network
    /// joins it whole (its joints are solved with the bodies).
    fn update_members(&mut self) {
        for r in 0..self.rods.len() {
            // A rod joins when it touches a body or a rod of its network does (no buffer:
            // the step loop allocates nothing).
            let m = match self.joints.network_of.get(r) {
                Some(&id) if id != usize::MAX => self.joints.networks[id]
                    .rods
                    .iter()
                    .any(|&q| self.touches_body(q)),
                _ => self.touches_body(r),
            };
            if m != self.is_member[r] {
                self.is_member[r] = m;
                self.group_dirty = true;
            }
            if m && self.dirty[r] {
                self.group_dirty = true;
            }
        }
    }

    /// Rod `r` holds a node or a segment against a free body, or presses one (compliant).
    fn touches_body(&self, r: usize) -> bool {
        let w = &self.work[r];
        w.contact
            .iter()
            .any(|c| c.is_some_and(|c| c.body.is_some()))
            || w.edges.iter().any(|e| e.body.is_some())
            || self.presses_body(r)
    }

    /// After the predictor: keep its positions for the recordings; split the step at the time
    /// of impact when asked.
    fn after_predictor(&mut self, ctx: &StepCtx, allow_split: bool) -> Result<(), StepError> {
        for r in 0..self.rods.len() {
            if ctx.wants_steps {
                self.out[r].q_pred.copy_from_slice(&self.work[r].qn);
            }
            if allow_split && ctx.dynamic {
                if let Some((theta, node)) = self.impact_fraction(r) {
                    if theta * ctx.dt >= self.min_split_dt(ctx.dt) {
                        self.rollback();
                        return Err(StepError::Split {
                            theta,
                            rod: r,
                            node,
                            release: false,
                        });
                    }
                }
            }
        }
        Ok(())
    }

    /// Time of release (with time of impact): split the step where a held node's reaction
    /// crosses zero or the friction cone, so that release is not located at step ends only.
    fn split_at_release(&mut self, ctx: &StepCtx) -> Result<(), StepError> {
        if let Some((theta, rod, node)) = self.release_fraction(ctx.dt) {
            self.rollback();
            return Err(StepError::Split {
                theta,
                rod,
                node,
                release: true,
            });
        }
        Ok(())
    }

    /// Adaptive stepping: reject the step when the error estimate exceeds the tolerance, or
    /// propose the next step size.
    pub(super) fn adapt(&mut self, dt: f64) -> Result<(), StepError> {
        let (err, err2) = self.error_estimate(dt);
        let mut factor = if err > 0.0 {
            (0.9 / err.sqrt()).clamp(0.2, 2.0)
        } else {
            2.0
        };
        if err2 > 0.0 {
            // Second-order nodes: local error O(dt³).
            factor = factor.min((0.9 / err2.cbrt()).clamp(0.2, 2.0));
        }
        let err = err.max(err2);
        let (dt_min, dt_max) = (self.scenario.solve.dt_min, self.scenario.solve.dt_max);
        if err > 1.0 && dt > dt_min * (1.0 + 1e-12) {
            self.rollback();
            return Err(StepError::Reject {
                dt: (dt * factor).max(dt_min),
            });
        }
        self.next_dt = (dt * factor).clamp(dt_min, dt_max);
        Ok(())
    }

    pub(super) fn rollback(&mut self) {
        for w in &mut self.work {
            w.contact.copy_from_slice(&w.contact_saved);
            w.law_slip.copy_from_slice(&w.law_slip_saved);
            w.clear_release_marks();
            w.edges.clone_from(&w.edges_saved);
            w.edge_released.clear();
            w.mark_edge_nodes();
        }
        for b in &mut self.bodies {
            b.contacts.clone_from(&b.contacts_saved);
            b.released.clear();
        }
        self.is_member.iter_mut().for_each(|m| *m = false);
        self.place_bodies(true);
    }

    /// Accept: advance the state, emit the step's end.
    pub(super) fn accept<O: Observer>(
        &mut self,
        ctx: &StepCtx,
        obs: &mut O,
        newton_iterations: u32,
        passes: u32,
    ) {
        if ctx.dynamic {
            self.energy_step(ctx);
        }
        let mut max_pen = self.stats.max_penetration;
        for r in 0..self.rods.len() {
            let merge = ctx.bdf2
                && ctx.stage == 0
                && self.split_step
                && ctx.dt < SLIVER * self.work[r].bdf.dt_prev;
            advance_rod(&self.rods[r], &mut self.work[r], ctx, merge);
        }
        self.remember_reactions();
        self.driven_velocities(ctx);
        self.accept_bodies(ctx);
        for r in 0..self.rods.len() {
            max_pen = max_pen
                .max(self.penetration(r))
                .max(self.segment_penetration(r));
        }
        self.stats.max_penetration = max_pen;
        self.stats.steps += 1;
        self.stats.newton_iterations += newton_iterations as u64;
        self.stats.jacobian_factorizations = self.work.iter().map(|w| w.factorizations).sum();
        self.stats.contact_passes += passes as u64;
        self.step = ctx.step;
        self.t = ctx.t1;
        self.stats.t = ctx.t1;
        self.last_dt = ctx.step_dt;
        self.check_drives(obs);
        if ctx.wants_steps {
            for r in 0..self.rods.len() {
                self.fill_outputs(r, if ctx.dynamic { ctx.dt } else { 0.0 }, false);
            }
            if ctx.stage == 2 {
                self.add_stage_impulses();
            }
            self.fill_contact_outputs(ctx.dt);
            self.emit_step_end(obs, ctx.step_dt, newton_iterations, passes);
        }
    }

    /// The energy balance of the step being accepted (see [`crate::energy::balance`]).
    pub(super) fn energy_step(&mut self, ctx: &StepCtx) {
        for r in 0..self.rods.len() {
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            newton::step_velocities(rod, w, ctx.dt);
            let mut t = StepTerms {
                elastic_before: w.energy_start,
                elastic_after: w.energy,
                ..StepTerms::default()
            };
            let mut grad_dq = 0.0;
            for i in 0..rod.n {
                let m = rod.mass[i];
                for k in 2 * i..2 * i + 2 {
                    let (dq, fd) = (w.dq[k], if w.damped { w.fd[k] } else { 0.0 });
                    grad_dq += w.grad[k] * dq;
                    t.damping += fd * dq;
                    if rod.clamped[i] {
                        t.drive += (w.grad[k] + fd) * dq;
                        continue;
                    }
                    let (u0, v1) = (w.u[k], w.v1[k]);
                    t.kinetic_before += 0.5 * m * u0 * u0;
                    t.kinetic_after += 0.5 * m * v1 * v1;
                    t.integrator += 0.5 * m * (v1 - u0) * (v1 - u0);
                    t.gravity -= w.fext[k] * dq;
                    if w.contact[i].is_some() || w.edge_nodes[i] {
                        t.contact += w.r[k] * dq;
                    }
                    // A joint's force on a free node: what a clamp puts in through the
                    // joint (between two free nodes the two sides cancel).
                    if let Some(f) = self.joints.force.get(r) {
                        t.drive += f[k] * dq;
                    }
                }
            }
            // The edge contacts' forces (out of the residual, which keeps the nodes' own).
            for e in &w.edges {
                for a in 0..2 {
                    let (f, i) = (e.node_force(a), e.segment + a);
                    t.contact += f[0] * w.dq[2 * i] + f[1] * w.dq[2 * i + 1];
                }
            }
            // B = E(q₀) − E(q₁) + ∇E(q₁)·Δq: the quadrature error of backward Euler's energy.
            t.integrator += w.energy_start - w.energy + grad_dq;
            w.energy_start = w.energy;
            self.stats.energy.add(&t, ctx.bdf2);
        }
    }

    /// A driven node's velocity is its actuator's exact velocity (not the backward difference
    /// of its positions, which depends on dt).
    pub(super) fn driven_velocities(&mut self, ctx: &StepCtx) {
        if !ctx.dynamic {
            return;
        }
        for r in 0..self.rods.len() {
            let (g, mirror) = self.rod_actuator[r];
            let motion = self.actuators[g].motion(ctx.t1);
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            for i in (0..rod.n).filter(|&i| rod.clamped[i]) {
                let v = motion.velocity_of([rod.q0[2 * i], rod.q0[2 * i + 1]], mirror);
                w.u[2 * i] = v[0];
                w.u[2 * i + 1] = v[1];
            }
        }
    }

    pub(super) fn accept_bodies(&mut self, ctx: &StepCtx) {
        for b in &mut self.bodies {
            for k in 0..3 {
                let v = b.dx[k] / ctx.dt;
                b.a[k] = (v - b.v[k]) / ctx.dt;
                b.v[k] = v;
            }
            b.pose = b.pose.moved(&b.dx);
            b.last_dx = b.dx;
            b.dx = [0.0; 3];
        }
        self.place_bodies(true);
    }

    /// Deepest penetration of any free node of rod `r` into any surface (m, ≥ 0).
    fn penetration(&self, r: usize) -> f64 {
        let rod = &self.rods[r];
        let w = &self.work[r];
        let s = self.rod_surfaces(r);
        let mut pen = 0.0f64;
        for i in 0..rod.n {
            if rod.clamped[i] {
                continue;
            }
            let p = [w.q[2 * i], w.q[2 * i + 1]];
            for k in 0..s.len() {
                if s.lower_bound(k, p) < 0.0 {
                    pen = pen.max(-s.query(k, p).distance);
                }
            }
        }
        pen
    }
}

/// Advance rod state over an accepted step: positions, velocities and accelerations (each
/// node by the row it took), and the BDF2 history the next step extrapolates. `merge`: the
/// step is a time-of-impact sliver (a split step much shorter than the step before it),
/// folded into the history instead of replacing it, so that the next step is BDF2 over
/// t_{k−2}, t_k, t_{k+1} (ω = dt / (dt_{k−1} + dt_sliver)) where it would otherwise exceed
/// BDF2's step ratio and fall back to backward Euler.
pub(super) fn advance_rod(
    rod: &crate::model::Rod,
    w: &mut newton::RodWork,
    ctx: &StepCtx,
    merge: bool,
) {
    for i in 0..rod.n {
        let second = w.second_order(i);
        for k in 2 * i..2 * i + 2 {
            let qn = w.q[k] + w.dq[k];
            let u0 = w.u[k];
            if !merge {
                w.bdf.a_prev[k] = w.a[k];
            }
            if second && w.bdf.trap {
                // Trapezoidal: u₁ = Δq/β − u, M (u₁ − u) = β (f + f₁) so a₁ = (u₁ − u)/β − a.
                let b = &w.bdf;
                let un = w.dq[k] / b.beta - u0;
                w.a[k] = (un - u0) / b.beta - w.a[k];
                w.u[k] = un;
            } else if second {
                let b = &w.bdf;
                let un = (w.dq[k] - b.alpha * b.dq_prev[k]) / b.beta;
                let hu = u0 + b.alpha * (u0 - b.u_prev[k]);
                w.a[k] = (un - hu) / b.beta;
                w.u[k] = un;
            } else if ctx.dynamic {
                let un = w.dq[k] / ctx.dt;
                w.a[k] = (un - w.u[k]) / ctx.dt;
                w.u[k] = un;
            } else {
                w.u[k] = 0.0;
            }
            if merge {
                w.bdf.dq_prev[k] += w.dq[k];
            } else if ctx.bdf2 {
                w.bdf.dq_prev[k] = w.dq[k];
                w.bdf.u_prev[k] = u0;
            }
            w.q[k] = qn;
        }
        w.bdf.second[i] = second;
        let (c0, c1) = (w.contact_saved[i], w.contact[i]);
        let smooth = newton::smooth_contact(c0, c1);
        // Held at both ends: smooth only once the node was held through the step
        // before too (the first held step after a landing stops it along the normal,
        // so its start velocity is the impact's and BDF2 would extrapolate the stop).
        let kept = smooth && (c1.is_none() || w.bdf.settled[i]);
        let released = second && newton::released_from_fixed(c0, c1);
        let hist = ctx.bdf2 && !rod.clamped[i] && (kept || released) && !w.edge_nodes[i];
        // Merged: smooth over the step before the sliver and over the sliver.
        w.bdf.hist[i] = hist && (!merge || w.bdf.hist[i]);
        w.bdf.settled[i] = smooth && c1.is_some() && (!merge || w.bdf.settled[i]);
    }
    w.bdf.dt_prev = match (ctx.bdf2, merge) {
        (false, _) => 0.0,
        (true, true) => w.bdf.dt_prev + ctx.dt,
        (true, false) => ctx.dt,
    };
    w.bdf.merged = merge;
    w.clear_release_marks();
}

/// One Newton iteration of rod `r` as the observers see it.
fn iteration_event<'a>(
    step: u64,
    t: f64,
    phase: Phase,
    pass: u32,
    r: usize,
    it: IterationReport<'a>,
) -> Event<'a> {
    Event::Iteration {
        step,
        t,
        phase,
        pass,
        iteration: it.iteration,
        rod: r,
        residual: it.residual,
        update: it.update,
        q: it.q,
    }
}
