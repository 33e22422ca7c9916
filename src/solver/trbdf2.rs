//! TR-BDF2 (`integrator = "tr_bdf2"`): one step of size dt is a trapezoidal stage from t to
//! t + γ dt, then a BDF2 stage over t, t + γ dt, t + dt (γ = 2 − √2, so both stages share
//! one Newton matrix scale: β = γ dt / 2 in both). Each stage is solved like a step (contact
//! passes, time of impact and release, per-node backward Euler rows where a node's contact
//! state changes); the error estimate, the step-size decision and the step's outputs are
//! the whole step's. A rejection or split after the first stage restores the state from
//! before it.

use super::newton::{Constraint, RodWork};
use super::step::{advance_rod, StepCtx};
use super::{Simulation, StepError};
use crate::contact::body::BodyContact;
use crate::contact::edge::EdgeContact;
use crate::events::{Event, Observer};
use crate::scenario::Stepping;
use crate::world::body::Pose;
use crate::world::Body;

/// γ = 2 − √2: the BDF2 stage's step ratio (1 − γ)/γ = 1/√2, and its β equals the
/// trapezoidal stage's γ dt / 2.
pub const GAMMA: f64 = 2.0 - std::f64::consts::SQRT_2;

/// The state a rejected TR-BDF2 step returns to: what a stage changes, copied into buffers
/// allocated at the first TR-BDF2 step (no allocation in the step loop).
#[derive(Debug, Default)]
pub(super) struct StageStart {
    rods: Vec<RodStart>,
    bodies: Vec<BodyStart>,
    /// The step-end outputs (saved only when steps are observed; `impulse_hist` and the
    /// reactions are the next step's history).
    out: Vec<super::RodOut>,
    out_saved: bool,
    energy: crate::energy::balance::Balance,
    t: f64,
}

/// One rod's part of [`StageStart`]: its state at the step's start, its contact sets, the
/// reactions the time of release interpolates, and its BDF2 history. The rest of
/// [`RodWork`] is scratch that every stage sets before it reads it.
#[derive(Debug, Default)]
struct RodStart {
    q: Vec<f64>,
    u: Vec<f64>,
    a: Vec<f64>,
    contact: Vec<Option<Constraint>>,
    contact_saved: Vec<Option<Constraint>>,
    edges: Vec<EdgeContact>,
    edges_saved: Vec<EdgeContact>,
    edge_nodes: Vec<bool>,
    energy: f64,
    energy_start: f64,
    rn_end: Vec<f64>,
    cone_end: Vec<f64>,
    dq_prev: Vec<f64>,
    u_prev: Vec<f64>,
    a_prev: Vec<f64>,
    hist: Vec<bool>,
    settled: Vec<bool>,
    second: Vec<bool>,
    dt_prev: f64,
    merged: bool,
    on: bool,
    trap: bool,
    alpha: f64,
    beta: f64,
    c: f64,
    omega: f64,
}

impl RodStart {
    fn new(w: &RodWork) -> Self {
        let n = w.contact.len();
        let mut s = RodStart {
            edges: Vec::with_capacity(n),
            edges_saved: Vec::with_capacity(n),
            ..RodStart::default()
        };
        s.save(w);
        s
    }

    fn save(&mut self, w: &RodWork) {
        let b = &w.bdf;
        self.q.clone_from(&w.q);
        self.u.clone_from(&w.u);
        self.a.clone_from(&w.a);
        self.contact.clone_from(&w.contact);
        self.contact_saved.clone_from(&w.contact_saved);
        self.edges.clone_from(&w.edges);
        self.edges_saved.clone_from(&w.edges_saved);
        self.edge_nodes.clone_from(&w.edge_nodes);
        self.rn_end.clone_from(&w.rn_end);
        self.cone_end.clone_from(&w.cone_end);
        self.dq_prev.clone_from(&b.dq_prev);
        self.u_prev.clone_from(&b.u_prev);
        self.a_prev.clone_from(&b.a_prev);
        self.hist.clone_from(&b.hist);
        self.settled.clone_from(&b.settled);
        self.second.clone_from(&b.second);
        (self.energy, self.energy_start) = (w.energy, w.energy_start);
        (self.dt_prev, self.merged, self.on, self.trap) = (b.dt_prev, b.merged, b.on, b.trap);
        (self.alpha, self.beta, self.c, self.omega) = (b.alpha, b.beta, b.c, b.omega);
    }

    fn restore(&self, w: &mut RodWork) {
        w.q.copy_from_slice(&self.q);
        w.u.copy_from_slice(&self.u);
        w.a.copy_from_slice(&self.a);
        w.contact.copy_from_slice(&self.contact);
        w.contact_saved.copy_from_slice(&self.contact_saved);
        w.edges.clone_from(&self.edges);
        w.edges_saved.clone_from(&self.edges_saved);
        w.edge_nodes.copy_from_slice(&self.edge_nodes);
        w.rn_end.copy_from_slice(&self.rn_end);
        w.cone_end.copy_from_slice(&self.cone_end);
        w.clear_release_marks();
        let b = &mut w.bdf;
        b.dq_prev.copy_from_slice(&self.dq_prev);
        b.u_prev.copy_from_slice(&self.u_prev);
        b.a_prev.copy_from_slice(&self.a_prev);
        b.hist.copy_from_slice(&self.hist);
        b.settled.copy_from_slice(&self.settled);
        b.second.copy_from_slice(&self.second);
        (w.energy, w.energy_start) = (self.energy, self.energy_start);
        (b.dt_prev, b.merged, b.on, b.trap) = (self.dt_prev, self.merged, self.on, self.trap);
        (b.alpha, b.beta, b.c, b.omega) = (self.alpha, self.beta, self.c, self.omega);
    }
}

/// One free body's part of [`StageStart`].
#[derive(Debug, Default)]
struct BodyStart {
    pose: Pose,
    v: [f64; 3],
    a: [f64; 3],
    dx: [f64; 3],
    last_dx: [f64; 3],
    contacts: Vec<BodyContact>,
    contacts_saved: Vec<BodyContact>,
    reaction: Vec<[f64; 2]>,
    released: Vec<(usize, usize)>,
}

impl BodyStart {
    fn save(&mut self, b: &Body) {
        (self.pose, self.v, self.a, self.dx, self.last_dx) = (b.pose, b.v, b.a, b.dx, b.last_dx);
        self.contacts.clone_from(&b.contacts);
        self.contacts_saved.clone_from(&b.contacts_saved);
        self.reaction.clone_from(&b.reaction);
        self.released.clone_from(&b.released);
    }

    fn restore(&self, b: &mut Body) {
        (b.pose, b.v, b.a, b.dx, b.last_dx) = (self.pose, self.v, self.a, self.dx, self.last_dx);
        b.contacts.clone_from(&self.contacts);
        b.contacts_saved.clone_from(&self.contacts_saved);
        b.reaction.clone_from(&self.reaction);
        b.released.clone_from(&self.released);
    }
}

impl super::RodOut {
    /// Copy every output array from `o` (same rod, same lengths).
    fn copy_from(&mut self, o: &Self) {
        self.reaction.copy_from_slice(&o.reaction);
        self.impulse.copy_from_slice(&o.impulse);
        self.drive_force.copy_from_slice(&o.drive_force);
        self.normal.copy_from_slice(&o.normal);
        self.obstacle.copy_from_slice(&o.obstacle);
        self.normal2.copy_from_slice(&o.normal2);
        self.obstacle2.copy_from_slice(&o.obstacle2);
        self.in_contact.copy_from_slice(&o.in_contact);
        self.stress.copy_from_slice(&o.stress);
        self.gap.copy_from_slice(&o.gap);
        self.q_pred.copy_from_slice(&o.q_pred);
        self.impulse_hist.copy_from_slice(&o.impulse_hist);
        self.impulse_stage.copy_from_slice(&o.impulse_stage);
    }
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
        self.save_stage_start(ws);
        let (it1, p1) = self
            .solve_stage(&c1, allow_split, obs)
            .map_err(|e| scaled_split(e, 0.0, GAMMA))?;
        self.accept_stage(&c1);
        let t0 = self.stage_start.t;
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
                self.restore_stage_start();
                Err(scaled_split(e, GAMMA, 1.0 - GAMMA))
            }
        }
    }

    /// Copy the state at the step's start into the rollback buffers (allocated at the first
    /// TR-BDF2 step, reused after that).
    fn save_stage_start(&mut self, wants_steps: bool) {
        let s = &mut self.stage_start;
        if s.rods.len() != self.work.len() || s.bodies.len() != self.bodies.len() {
            s.rods = self.work.iter().map(RodStart::new).collect();
            s.bodies = self.bodies.iter().map(|_| BodyStart::default()).collect();
            s.out = self.rods.iter().map(|r| super::RodOut::new(r.n)).collect();
        }
        for (sv, w) in s.rods.iter_mut().zip(&self.work) {
            sv.save(w);
        }
        for (sv, b) in s.bodies.iter_mut().zip(&self.bodies) {
            sv.save(b);
        }
        s.out_saved = wants_steps;
        if wants_steps {
            for (sv, o) in s.out.iter_mut().zip(&self.out) {
                sv.copy_from(o);
            }
        }
        s.energy.clone_from(&self.stats.energy);
        s.t = self.t;
    }

    /// Back to the start of the step; the Jacobian count keeps the rejected step's work.
    fn restore_stage_start(&mut self) {
        let s = &self.stage_start;
        for (w, sv) in self.work.iter_mut().zip(&s.rods) {
            sv.restore(w);
        }
        for (b, sv) in self.bodies.iter_mut().zip(&s.bodies) {
            sv.restore(b);
        }
        if s.out_saved {
            for (o, sv) in self.out.iter_mut().zip(&s.out) {
                o.copy_from(sv);
            }
        }
        self.stats.energy.clone_from(&s.energy);
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
