//! Second-order integrators of the 3D world (`[solve] integrator = "bdf2" | "tr_bdf2"`).
//!
//! Every stage (a BDF2 step, or one of TR-BDF2's two stages) is solved like a backward Euler
//! step of its own length h (contact passes, bodies, frames), with each DOF's row written as
//! u = (q − e)/b and a = (u − w)/b:
//! - backward Euler: e = qₖ, w = uₖ, b = h;
//! - BDF2 (ω = h/h_prev, α = ω²/(1+2ω), β = h (1+ω)/(1+2ω)): e = qₖ + α Δq_prev,
//!   w = uₖ + α (uₖ − u_prev), b = β;
//! - trapezoidal (TR-BDF2's first stage, to t + γh): e = qₖ + β uₖ, w = uₖ + β aₖ, b = β = γh/2.
//!
//! The inertia residual is m (q − e − b w)/b², the damping velocity (q − e)/b. The history
//! is per DOF (positions and edge angles θ alike: θ is measured from the time-parallel
//! reference frames, which are carried along every stage as under backward Euler): Δq and u
//! of the last stage, and a = (u − w)/b at its end (= f/m on a free DOF, the trapezoid's aₖ).
//!
//! Contact rule: a node's position rows are backward Euler in a stage in which it has a
//! contact (node or edge contact, in any pass) and in the stage after one (no smooth history);
//! its edge angles keep the smooth rows (no constraint acts on θ). Fixed DOFs follow their
//! targets (TR-BDF2's first stage at the linear interpolation q + γ (target − q)); their
//! velocity is BDF2's in a BDF2 stage and backward Euler's in the trapezoidal one. Free
//! bodies are backward Euler in every stage (as in the planar solver). The first stage, and
//! a BDF2 stage more than 2× longer than the last, are backward Euler throughout.

use super::*;
use crate::rod3d::energy::{advance_frame, reference_twist, EdgeFrame};
use crate::scenario::Integrator;

/// γ = 2 − √2 of TR-BDF2.
pub const GAMMA: f64 = 2.0 - std::f64::consts::SQRT_2;

/// The kind of a stage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stage3 {
    Euler,
    Bdf2,
    Trap,
}

/// One rod's history and the rows of its current stage (allocated with the rod).
#[derive(Debug, Default)]
pub(super) struct Bdf3 {
    /// The rows in force at the last linearisation, per DOF.
    pub e: Vec<f64>,
    pub w: Vec<f64>,
    pub b: Vec<f64>,
    /// The smooth rows of the stage, per DOF (valid when `on`).
    se: Vec<f64>,
    sw: Vec<f64>,
    beta: f64,
    /// The stage's length and kind; `on` when its smooth rows are used at all.
    h: f64,
    kind: Option<Stage3>,
    on: bool,
    /// History: the last stage's Δq, the velocity before it, the acceleration at its end.
    dq_prev: Vec<f64>,
    u_prev: Vec<f64>,
    a: Vec<f64>,
    /// Per node: free through the whole last stage (a smooth history).
    hist: Vec<bool>,
    /// Per node: had a contact in some pass of this stage.
    touched: Vec<bool>,
    /// Length of the last stage (0: none yet).
    dt_prev: f64,
    /// The fixed DOFs' targets at the end of a TR-BDF2 step, and the rod's time at its start.
    target_end: Vec<f64>,
    t0: f64,
    /// The reference frames and twists carried onto the iterate (see [`Bdf3::frames_at`]).
    pub frames: Vec<EdgeFrame>,
    pub ref_twist: Vec<f64>,
}

impl Bdf3 {
    pub fn new(nd: usize, n: usize) -> Bdf3 {
        let v = vec![0.0; nd];
        Bdf3 {
            e: v.clone(),
            w: v.clone(),
            b: v.clone(),
            se: v.clone(),
            sw: v.clone(),
            dq_prev: v.clone(),
            u_prev: v.clone(),
            a: v.clone(),
            target_end: v,
            hist: vec![false; n],
            touched: vec![false; n],
            frames: Vec::with_capacity(n),
            ref_twist: vec![0.0; n],
            ..Bdf3::default()
        }
    }

    /// Whether the rows are this module's (any stage of a second-order integrator).
    pub fn active(&self) -> bool {
        self.kind.is_some()
    }

    /// Set up a stage of length h from the state (q, v) at its start.
    fn begin(&mut self, sim: &Sim3, kind: Stage3, h: f64) {
        self.kind = Some(kind);
        self.h = h;
        self.touched.fill(false);
        let ratio = h / self.dt_prev;
        self.on = match kind {
            Stage3::Euler => false,
            Stage3::Bdf2 => self.dt_prev > 0.0 && ratio <= 2.0,
            Stage3::Trap => self.dt_prev > 0.0,
        };
        if !self.on {
            return;
        }
        let (q, v) = (&sim.q, &sim.v);
        if kind == Stage3::Bdf2 {
            let alpha = ratio * ratio / (1.0 + 2.0 * ratio);
            self.beta = h * (1.0 + ratio) / (1.0 + 2.0 * ratio);
            for k in 0..q.len() {
                self.se[k] = q[k] + alpha * self.dq_prev[k];
                self.sw[k] = v[k] + alpha * (v[k] - self.u_prev[k]);
            }
        } else {
            self.beta = 0.5 * h;
            for k in 0..q.len() {
                self.se[k] = q[k] + self.beta * v[k];
                self.sw[k] = v[k] + self.beta * self.a[k];
            }
        }
    }

    /// The rows of this linearisation: smooth where the stage is on and the DOF may be,
    /// backward Euler elsewhere; marks the nodes with a contact as touched.
    fn rows(&mut self, sim: &Sim3, contacts: &[Option<Contact3>], edges: &[EdgeContact3]) {
        for e in edges {
            self.touched[e.segment] = true;
            self.touched[e.segment + 1] = true;
        }
        for (i, c) in contacts.iter().enumerate() {
            self.touched[i] |= c.is_some();
        }
        for k in 0..sim.q.len() {
            let smooth = self.on
                && if sim.fixed[k] {
                    self.kind == Some(Stage3::Bdf2)
                } else {
                    k % 4 == 3 || (self.hist[k / 4] && !self.touched[k / 4])
                };
            (self.e[k], self.w[k], self.b[k]) = if smooth {
                (self.se[k], self.sw[k], self.beta)
            } else {
                (sim.q[k], sim.v[k], self.h)
            };
        }
    }

    /// The reference frames and twists carried from the stage's start onto the iterate `qn`
    /// (as the accepted step will carry them), so that the elastic force is the gradient at
    /// the iterate's own frames. Evaluated with the start's frames, the force of a twisted,
    /// bending rod is off by O(Δq) (the transport's derivative depends on where it starts):
    /// an O(h) error of the force that would leave a second-order integrator first order.
    pub fn frames_at(&mut self, sim: &Sim3, qn: &[f64]) {
        let n = sim.rod.n;
        self.frames.clear();
        for i in 0..n - 1 {
            self.frames
                .push(advance_frame(sim.rod.edge(qn, i), &sim.frames[i]));
        }
        for i in 1..n - 1 {
            let near = sim.ref_twist[i];
            self.ref_twist[i] = reference_twist(&self.frames[i - 1], &self.frames[i], near);
        }
    }

    /// Accept the stage's end `qn`: velocities, accelerations and the history.
    fn accept(&mut self, sim: &mut Sim3, qn: &[f64]) {
        for k in 0..qn.len() {
            let u = (qn[k] - self.e[k]) / self.b[k];
            self.a[k] = (u - self.w[k]) / self.b[k];
            self.dq_prev[k] = qn[k] - sim.q[k];
            self.u_prev[k] = sim.v[k];
            sim.v[k] = u;
        }
        for (h, t) in self.hist.iter_mut().zip(&self.touched) {
            *h = !t;
        }
        self.dt_prev = self.h;
    }
}

impl World3 {
    /// Fill rod r's rows for this linearisation (second-order integrators only).
    pub(super) fn bdf_rows(&mut self, r: usize) {
        let w = &mut self.work[r];
        if w.bdf.active() {
            w.bdf.rows(&self.rods[r], &self.contacts[r], &self.edges[r]);
        }
    }

    /// Begin a stage of length h on every rod (second-order integrators only).
    pub(super) fn bdf_begin(&mut self, kind: Stage3, h: f64) {
        if self.integrator == Integrator::BackwardEuler {
            return;
        }
        for (sim, w) in self.rods.iter().zip(&mut self.work) {
            w.bdf.begin(sim, kind, h);
        }
    }

    /// The rods' velocities and histories at the end of a stage. Returns false under
    /// backward Euler (the caller's own update).
    pub(super) fn bdf_accept(&mut self) -> bool {
        if self.integrator == Integrator::BackwardEuler {
            return false;
        }
        for (sim, w) in self.rods.iter_mut().zip(&mut self.work) {
            w.bdf.accept(sim, &w.qn);
        }
        true
    }

    /// One TR-BDF2 step of size dt: the trapezoidal stage to t + γ dt (fixed DOFs at
    /// q + γ (target − q)), then BDF2 over t, t + γ dt, t + dt.
    pub(super) fn tr_bdf2(&mut self, dt: f64) -> Result<StepReport3, Solve3Error> {
        let t0 = self.time;
        for (sim, w) in self.rods.iter_mut().zip(&mut self.work) {
            let b = &mut w.bdf;
            b.t0 = sim.time;
            b.target_end.copy_from_slice(&sim.target);
            for k in 0..sim.q.len() {
                if sim.fixed[k] {
                    sim.target[k] = sim.q[k] + GAMMA * (b.target_end[k] - sim.q[k]);
                }
            }
        }
        let first = self.stage(GAMMA * dt, Stage3::Trap);
        for (sim, w) in self.rods.iter_mut().zip(&self.work) {
            sim.target.copy_from_slice(&w.bdf.target_end);
        }
        let r1 = first?;
        let r2 = self.stage((1.0 - GAMMA) * dt, Stage3::Bdf2)?;
        self.time = t0 + dt;
        for (sim, w) in self.rods.iter_mut().zip(&self.work) {
            sim.time = w.bdf.t0 + dt;
        }
        Ok(StepReport3 {
            passes: r1.passes + r2.passes,
            newton_iterations: r1.newton_iterations + r2.newton_iterations,
            added: r1.added + r2.added,
            released: r1.released + r2.released,
            switches: r1.switches + r2.switches,
        })
    }
}
