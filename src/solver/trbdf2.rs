//! TR-BDF2 (`integrator = "tr_bdf2"`): one step of size dt is a trapezoidal stage from t to
//! t + γ dt, then a BDF2 stage over t, t + γ dt, t + dt (γ = 2 − √2, so both stages share
//! one Newton matrix scale: β = γ dt / 2 in both). Each stage is solved like a step (contact
//! passes, time of impact and release, per-node backward Euler rows where a node's contact
//! state changes); the error estimate, the step-size decision and the step's outputs are
//! the whole step's. A rejection or split after the first stage restores the state from
//! before it.

use super::step::{advance_rod, StepCtx};
use super::{Simulation, StepError};
use crate::events::{Event, Observer};
use crate::scenario::Stepping;

/// γ = 2 − √2: the BDF2 stage's step ratio (1 − γ)/γ = 1/√2, and its β equals the
/// trapezoidal stage's γ dt / 2.
pub const GAMMA: f64 = 2.0 - std::f64::consts::SQRT_2;

/// The state a rejected TR-BDF2 step returns to.
pub(super) struct StageStart {
    work: Vec<super::newton::RodWork>,
    bodies: Vec<crate::world::Body>,
    out: Option<Vec<super::RodOut>>,
    energy: crate::energy::balance::Balance,
    t: f64,
}

impl Simulation {
    /// One TR-BDF2 step of size `dt`.
    pub(super) fn try_tr_bdf2<O: Observer>(
        &mut self,
        dt: f64,
        allow_split: bool,
        obs: &mut O,
    ) -> Result<(), StepError> {
        let (wi, ws) = (obs.wants_iterations(), obs.wants_steps());
        let mut c1 = self.step_ctx(GAMMA * dt, 0.0, wi, ws);
        c1.stage = 1;
        c1.step_dt = dt;
        obs.on_event(&Event::StepBegin {
            step: c1.step,
            t: self.t,
            dt,
        });
        let start = self.stage_start(ws);
        let (it1, p1) = self
            .solve_stage(&c1, allow_split, obs)
            .map_err(|e| scaled_split(e, 0.0, GAMMA))?;
        self.accept_stage(&c1);
        let t0 = start.t;
        self.t = t0 + GAMMA * dt;
        let mut c2 = self.step_ctx((1.0 - GAMMA) * dt, 0.0, wi, ws);
        c2.stage = 2;
        c2.step_dt = dt;
        c2.t1 = t0 + dt;
        let res = self.solve_stage(&c2, allow_split, obs).and_then(|r| {
            if self.scenario.solve.stepping == Stepping::Adaptive {
                self.adapt(dt)?;
            }
            Ok(r)
        });
        match res {
            Ok((it2, p2)) => {
                self.accept(&c2, obs, it1 + it2, p1 + p2);
                Ok(())
            }
            Err(e) => {
                self.restore_stage_start(start);
                Err(scaled_split(e, GAMMA, 1.0 - GAMMA))
            }
        }
    }

    fn stage_start(&self, wants_steps: bool) -> StageStart {
        StageStart {
            work: self.work.clone(),
            bodies: self.bodies.clone(),
            out: wants_steps.then(|| self.out.clone()),
            energy: self.stats.energy.clone(),
            t: self.t,
        }
    }

    /// Back to the start of the step; the Jacobian count keeps the rejected step's work.
    fn restore_stage_start(&mut self, s: StageStart) {
        for (w, saved) in self.work.iter_mut().zip(s.work) {
            let f = w.factorizations;
            *w = saved;
            w.factorizations = f;
        }
        self.bodies = s.bodies;
        if let Some(out) = s.out {
            self.out = out;
        }
        self.stats.energy = s.energy;
        self.t = s.t;
        self.is_member.iter_mut().for_each(|m| *m = false);
        self.place_bodies(true);
    }

    /// Accept the trapezoidal stage: advance the state to t + γ dt (the BDF2 stage's history),
    /// its energy terms and, when steps are observed, its contact impulses.
    fn accept_stage(&mut self, ctx: &StepCtx) {
        self.energy_step(ctx);
        for r in 0..self.rods.len() {
            advance_rod(&self.rods[r], &mut self.work[r], ctx, false);
        }
        self.remember_reactions();
        self.driven_velocities(ctx);
        self.accept_bodies(ctx);
        if ctx.wants_steps {
            for r in 0..self.rods.len() {
                self.fill_outputs(r, ctx.dt, false);
                let o = &mut self.out[r];
                o.impulse_stage.copy_from_slice(&o.impulse);
            }
        }
    }

    /// The step's contact impulse is the two stages' together.
    pub(super) fn add_stage_impulses(&mut self) {
        for o in &mut self.out {
            for (j, j1) in o.impulse.iter_mut().zip(&o.impulse_stage) {
                *j += j1;
            }
        }
    }
}

/// A split found in a stage spanning [from, from + len] of the step, as a fraction of the
/// whole step.
fn scaled_split(e: StepError, from: f64, len: f64) -> StepError {
    match e {
        StepError::Split {
            theta,
            rod,
            node,
            release,
        } => StepError::Split {
            theta: from + len * theta,
            rod,
            node,
            release,
        },
        e => e,
    }
}
