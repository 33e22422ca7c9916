//! Implicit Euler + Newton for one 3D rod, with a banded solve: the unknowns x₀, θ₀, x₁, θ₁, …
//! of a bending/twisting stencil are 11 consecutive DOFs, so the Jacobian has half-bandwidth
//! 10 and a factorisation costs O(n). Static equilibria are found by a load ramp.
//!
//! Residual of a step (dynamic, c = 1/dt²; static, c = 0 and load factor λ):
//! r(q) = c M (q − qₙ − dt vₙ) + ∇E(q) − λ F, F = dead loads + M g on positions.
//! Fixed DOFs are placed on their targets and carry an identity row.

use super::energy::{advance_frame, node_energy, reference_twist, stretch, EdgeFrame};
use super::kernel;
use super::rod::{angle, pos, Rod3};
use super::symband::{BandSink, SymBand};
use crate::solver::banded::BandLu;

/// Why a 3D solve failed.
#[derive(Debug, Clone, PartialEq)]
pub struct Solve3Error {
    pub residual: f64,
    pub iterations: u32,
    pub reason: &'static str,
    /// Where the largest residual was: the finger's name and the node (None: not a rod's, or
    /// not known).
    pub at: Option<(String, usize)>,
}

impl std::fmt::Display for Solve3Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.at {
            Some((rod, node)) => write!(
                f,
                "rod {rod:?} node {node}: {} (residual {:.3e} N after {} iterations; the \
                 largest rod residual at that node)",
                self.reason, self.residual, self.iterations
            ),
            None => write!(
                f,
                "3D rod: {} (residual {:.3e} N after {} iterations)",
                self.reason, self.residual, self.iterations
            ),
        }
    }
}

/// One 3D rod in time: configuration, velocities, reference frames and loads.
#[derive(Debug, Clone)]
pub struct Sim3 {
    pub rod: Rod3,
    pub q: Vec<f64>,
    pub v: Vec<f64>,
    /// Reference frame of every edge and reference twist of every node at the current state.
    pub frames: Vec<EdgeFrame>,
    pub ref_twist: Vec<f64>,
    pub gravity: [f64; 3],
    /// Dead generalized forces per DOF (forces on positions, torques about the tangent on angles).
    pub load: Vec<f64>,
    pub fixed: Vec<bool>,
    /// Where the fixed DOFs are held: at the end of the next step (dynamic) or at full load
    /// (static). Defaults to the initial configuration.
    pub target: Vec<f64>,
    /// Residual tolerance relative to the force scale.
    pub force_tol: f64,
    pub max_iterations: u32,
    /// Kelvin–Voigt retardation time τ = tan δ / (2π f) of the material (s; 0: undamped).
    pub damping_time: f64,
    pub time: f64,
    pub newton_iterations: u64,
    /// Newton iterations whose Jacobian was not positive definite (solved by LU instead).
    pub lu_solves: u64,
    chol: SymBand,
    band: BandLu,
    grad: Vec<f64>,
    rhs: Vec<f64>,
    qn: Vec<f64>,
}

impl Sim3 {
    pub fn new(rod: Rod3) -> Sim3 {
        let nd = rod.dofs();
        Sim3 {
            q: rod.q0.clone(),
            v: vec![0.0; nd],
            frames: rod.frames0.clone(),
            ref_twist: rod.ref_twist0.clone(),
            gravity: [0.0; 3],
            load: vec![0.0; nd],
            fixed: vec![false; nd],
            target: rod.q0.clone(),
            force_tol: 1e-10,
            max_iterations: 40,
            damping_time: 0.0,
            time: 0.0,
            newton_iterations: 0,
            lu_solves: 0,
            chol: SymBand::new(nd, 10),
            band: BandLu::new(nd, 10, 10),
            grad: vec![0.0; nd],
            rhs: vec![0.0; nd],
            qn: rod.q0.clone(),
            rod,
        }
    }

    /// Clamp edge i: both its nodes and its angle are fixed where they are.
    pub fn clamp_edge(&mut self, i: usize) {
        for k in pos(i)..pos(i + 1) + 3 {
            self.fixed[k] = true;
            self.target[k] = self.q[k];
        }
    }

    /// External generalized force per DOF: dead loads plus gravity on positions.
    pub fn external(&self, k: usize) -> f64 {
        let g = if k % 4 == 3 { 0.0 } else { self.gravity[k % 4] };
        self.load[k] + self.rod.mass[k] * g
    }

    /// Elastic energy of configuration q relative to the current frames.
    pub fn elastic_energy(&self, q: &[f64]) -> f64 {
        let rod = &self.rod;
        let mut e = 0.0;
        for i in 0..rod.n - 1 {
            let (a, b) = (pos(i), pos(i + 1));
            let x = [q[a], q[a + 1], q[a + 2], q[b], q[b + 1], q[b + 2]];
            e += stretch(&x, rod.ea, rod.rest_length[i], &mut [0.0; 6], None);
        }
        for i in 1..rod.n - 1 {
            let x: [f64; 11] = q[pos(i - 1)..pos(i - 1) + 11].try_into().unwrap();
            let old = [&self.frames[i - 1], &self.frames[i]];
            e += node_energy(&x, old, self.ref_twist[i], &rod.elastic[i]);
        }
        e
    }

    /// Kinetic energy ½ vᵀ M v.
    pub fn kinetic_energy(&self) -> f64 {
        let m = &self.rod.mass;
        0.5 * self.v.iter().zip(m).map(|(v, m)| m * v * v).sum::<f64>()
    }

    fn force_scale(&self) -> f64 {
        let l = self.rod.length;
        let ext = (0..self.q.len()).fold(0.0f64, |a, k| a.max(self.external(k).abs()));
        ext.max(self.rod.ei1.max(self.rod.ei2) / (l * l))
    }

    /// The residual at `self.qn` into `self.rhs` (as −r, zero on fixed DOFs) and with `jac`
    /// the Jacobian into `self.chol`. Returns the largest free residual.
    fn residual(&mut self, c: f64, dt: f64, lambda: f64, jac: bool) -> f64 {
        let (f, b, r) = (&self.frames, &self.ref_twist, &self.rod);
        let band = if jac {
            self.chol.clear();
            Some(&mut self.chol)
        } else {
            None
        };
        assemble_into(r, f, b, &self.qn, &mut self.grad, band, &self.fixed);
        if self.damping_time > 0.0 && dt > 0.0 {
            let band = jac.then_some(&mut self.chol);
            let (tau, g) = (self.damping_time, &mut self.grad);
            damping_into(r, f, &self.qn, &self.q, dt, tau, g, band, &self.fixed);
        }
        let mut res = 0.0f64;
        for k in 0..self.q.len() {
            if self.fixed[k] {
                self.rhs[k] = 0.0;
                continue;
            }
            let m = self.rod.mass[k];
            let inertia = c * m * (self.qn[k] - self.q[k] - dt * self.v[k]);
            let rk = inertia + self.grad[k] - lambda * self.external(k);
            res = res.max(rk.abs());
            self.rhs[k] = -rk;
            if jac {
                self.chol.add(k, k, c * m);
            }
        }
        res
    }

    /// Newton on the residual with inertia coefficient c (0: static), load factor λ, starting
    /// from `self.qn` (fixed DOFs already on their targets). Returns the iterations. The first
    /// residual comes with its Jacobian; after an update the residual is evaluated alone and
    /// the Jacobian only when another update is needed.
    fn newton(&mut self, c: f64, dt: f64, lambda: f64) -> Result<u32, Solve3Error> {
        let tol = self.force_tol * self.force_scale();
        let floor = 1e-14 * self.rod.length;
        let nd = self.q.len();
        let mut it = 0u32;
        loop {
            let res = self.residual(c, dt, lambda, it == 0);
            if !res.is_finite() {
                return Err(fail(res, it, "non-finite residual"));
            }
            if res <= tol {
                return Ok(it);
            }
            if it >= self.max_iterations {
                return Err(fail(res, it, "Newton did not converge"));
            }
            if it > 0 {
                self.residual(c, dt, lambda, true);
            }
            if self.chol.factor().is_ok() {
                self.chol.solve(&mut self.rhs);
            } else if self.solve_lu(c, dt).is_err() {
                return Err(fail(res, it, "singular Jacobian"));
            }
            let mut upd = 0.0f64;
            for k in 0..nd {
                self.qn[k] += self.rhs[k];
                upd = upd.max(self.rhs[k].abs());
            }
            it += 1;
            self.newton_iterations += 1;
            if upd <= floor {
                return Ok(it);
            }
        }
    }

    /// The Newton update by LU with pivoting when the Jacobian is not positive definite (the
    /// Cholesky factor failed): reassemble into the general band, factor, solve `rhs`.
    fn solve_lu(&mut self, c: f64, dt: f64) -> Result<(), usize> {
        self.band.clear();
        let (f, b, r) = (&self.frames, &self.ref_twist, &self.rod);
        let mut g = std::mem::take(&mut self.grad);
        assemble(r, f, b, &self.qn, &mut g, Some(&mut self.band), &self.fixed);
        if self.damping_time > 0.0 && dt > 0.0 {
            let tau = self.damping_time;
            let band = Some(&mut self.band);
            damping_into(r, f, &self.qn, &self.q, dt, tau, &mut g, band, &self.fixed);
        }
        self.grad = g;
        for k in (0..self.q.len()).filter(|&k| !self.fixed[k]) {
            self.band.add(k, k, c * self.rod.mass[k]);
        }
        self.band.factor()?;
        self.band.solve(&mut self.rhs);
        self.lu_solves += 1;
        Ok(())
    }

    /// One implicit Euler step of size dt; fixed DOFs end the step on `target`.
    pub fn step(&mut self, dt: f64) -> Result<u32, Solve3Error> {
        let nd = self.q.len();
        for k in 0..nd {
            self.qn[k] = if self.fixed[k] {
                self.target[k]
            } else {
                self.q[k] + dt * self.v[k]
            };
        }
        let it = self.newton(1.0 / (dt * dt), dt, 1.0)?;
        for k in 0..nd {
            self.v[k] = (self.qn[k] - self.q[k]) / dt;
        }
        self.accept();
        self.time += dt;
        Ok(it)
    }

    /// Static equilibrium under the full loads (and fixed DOFs moved to `target`), reached by
    /// `steps` equal load increments; a failed increment is halved (at most 30 times).
    pub fn solve_static(&mut self, steps: usize) -> Result<(), Solve3Error> {
        let start: Vec<f64> = self.q.clone();
        let nd = self.q.len();
        let mut lambda = 0.0;
        let mut inc = 1.0 / steps.max(1) as f64;
        let mut halvings = 0;
        while lambda < 1.0 {
            let to = (lambda + inc).min(1.0);
            self.qn.copy_from_slice(&self.q);
            for k in 0..nd {
                if self.fixed[k] {
                    self.qn[k] = start[k] + to * (self.target[k] - start[k]);
                }
            }
            match self.newton(0.0, 0.0, to) {
                Ok(_) => {
                    self.accept();
                    lambda = to;
                }
                Err(e) => {
                    halvings += 1;
                    inc *= 0.5;
                    if halvings > 30 {
                        return Err(e);
                    }
                }
            }
        }
        self.v.fill(0.0);
        Ok(())
    }

    /// Take `qn` as the new state and advance the reference frames and twists onto it.
    fn accept(&mut self) {
        self.q.copy_from_slice(&self.qn);
        self.advance_frames();
    }

    /// Carry the reference frames and twists onto the current `q` (time-parallel transport
    /// from the previous step's frames).
    pub(crate) fn advance_frames(&mut self) {
        let n = self.rod.n;
        for i in 0..n - 1 {
            self.frames[i] = advance_frame(self.rod.edge(&self.q, i), &self.frames[i]);
        }
        for i in 1..n - 1 {
            let near = self.ref_twist[i];
            self.ref_twist[i] = reference_twist(&self.frames[i - 1], &self.frames[i], near);
        }
    }
}

fn fail(residual: f64, iterations: u32, reason: &'static str) -> Solve3Error {
    Solve3Error {
        residual,
        iterations,
        reason,
        at: None,
    }
}

/// Elastic energy of q (frames and reference twists of the start of the step), its gradient
/// into `grad` and, with `band`, its Hessian on the free DOFs (identity rows on `fixed` ones;
/// an empty `fixed` means all free).
pub fn assemble(
    rod: &Rod3,
    frames: &[EdgeFrame],
    ref_twist: &[f64],
    q: &[f64],
    grad: &mut [f64],
    band: Option<&mut BandLu>,
    fixed: &[bool],
) -> f64 {
    assemble_into(rod, frames, ref_twist, q, grad, band, fixed)
}

/// [`assemble`] into any band: the bending/twisting stencils by the hand-derived kernel
/// (src/rod3d/kernel.rs), stencils without fixed DOFs added as one dense block.
pub fn assemble_into<S: BandSink>(
    rod: &Rod3,
    frames: &[EdgeFrame],
    ref_twist: &[f64],
    q: &[f64],
    grad: &mut [f64],
    mut band: Option<&mut S>,
    fixed: &[bool],
) -> f64 {
    grad.fill(0.0);
    let free = |k: usize| fixed.is_empty() || !fixed[k];
    let mut energy = 0.0;
    let jac = band.is_some();
    if rod.n < 3 {
        // No bending stencil: the stretching elements alone.
        let (mut g7, mut h7) = ([0.0; 7], [[0.0; 7]; 7]);
        for i in 0..rod.n - 1 {
            g7.fill(0.0);
            h7.iter_mut().for_each(|r| r.fill(0.0));
            energy += add_stretch(rod, q, i, 0, &mut g7, jac.then_some(&mut h7));
            scatter(pos(i), &g7, &h7, grad, band.as_deref_mut(), &free);
        }
    }
    let (mut g11, mut h11) = ([0.0; 11], [[0.0; 11]; 11]);
    // Each edge belongs to two stencils: its frame is computed once, carried to the next.
    let edge = |i: usize| {
        let (a, b) = (pos(i), pos(i + 1));
        let e = [q[b] - q[a], q[b + 1] - q[a + 1], q[b + 2] - q[a + 2]];
        kernel::edge(e, &frames[i], q[angle(i)], jac)
    };
    let mut prev = edge(0);
    for i in 1..rod.n - 1 {
        let base = pos(i - 1);
        let next = edge(i);
        let th = [q[angle(i - 1)], q[angle(i)]];
        let (p, h) = (&rod.elastic[i], jac.then_some(&mut h11));
        energy += kernel::stencil_dofs(&prev, &next, th, ref_twist[i], p, &mut g11, h);
        // The stretching of edge i (and of edge 0 with the first stencil) in the same
        // block: one scatter per stencil.
        if i == 1 {
            energy += add_stretch(rod, q, 0, 0, &mut g11, jac.then_some(&mut h11));
        }
        energy += add_stretch(rod, q, i, 4, &mut g11, jac.then_some(&mut h11));
        scatter(base, &g11, &h11, grad, band.as_deref_mut(), &free);
        prev = next;
    }
    if let Some(b) = band {
        for (k, f) in fixed.iter().enumerate() {
            if *f {
                b.add(k, k, 1.0);
            }
        }
    }
    debug_assert!(angle(rod.n - 2) + 4 == q.len());
    energy
}

/// Add the stretching of edge i (energy, gradient and with `h` Hessian over x_i, x_{i+1}) to
/// a block whose DOFs start at x_i's offset `at` (the edge's angle between them untouched).
fn add_stretch<const N: usize>(
    rod: &Rod3,
    q: &[f64],
    i: usize,
    at: usize,
    g: &mut [f64; N],
    h: Option<&mut [[f64; N]; N]>,
) -> f64 {
    let (a, b) = (pos(i), pos(i + 1));
    let x = [q[a], q[a + 1], q[a + 2], q[b], q[b + 1], q[b + 2]];
    let (mut g6, mut h6) = ([0.0; 6], [[0.0; 6]; 6]);
    let want_h = h.is_some();
    let en = stretch(
        &x,
        rod.ea,
        rod.rest_length[i],
        &mut g6,
        want_h.then_some(&mut h6),
    );
    const AT: [usize; 6] = [0, 1, 2, 4, 5, 6];
    for (r, &ar) in AT.iter().enumerate() {
        g[at + ar] += g6[r];
    }
    if let Some(h) = h {
        for (r, &ar) in AT.iter().enumerate() {
            for (c, &ac) in AT.iter().enumerate() {
                h[at + ar][at + ac] += h6[r][c];
            }
        }
    }
    en
}

/// Kelvin–Voigt material damping with retardation time `tau`: adds the viscous force
/// τ Σ k ṡ ∇s of every element to `grad` (stretch ε with k = EA l̄; the curvatures κ₁, κ₂ and
/// the twist m of every interior node with EI₁/Δl, EI₂/Δl, GJ/Δl: the stiffnesses of
/// E = ½ k (s − s̄)²), ṡ = ∇s·v with v = (q − q_prev)/dt, and with `band` its Jacobian
/// τ k ∇s ∇sᵀ/dt on the free DOFs (symmetric, positive semi-definite; the change of ∇s is
/// left out, as in the planar solver). Returns the dissipated power Σ τ k ṡ² ≥ 0.
#[allow(clippy::too_many_arguments)]
pub fn damping_into<S: BandSink>(
    rod: &Rod3,
    frames: &[EdgeFrame],
    q: &[f64],
    q_prev: &[f64],
    dt: f64,
    tau: f64,
    grad: &mut [f64],
    band: Option<&mut S>,
    fixed: &[bool],
) -> f64 {
    let rate = |k: usize| (q[k] - q_prev[k], dt);
    damping_rates_into(rod, frames, q, &rate, tau, grad, band, fixed)
}

/// [`damping_into`] with the velocity of every DOF given by `rate`: `rate(k)` = (d, b) with
/// v_k = d / b (backward Euler: (q − q_prev, dt); a second-order integrator's row:
/// (q − e, β), src/rod3d/world/bdf3.rs). The Jacobian of an element whose DOFs have
/// different b takes √(b_a b_c) for the pair (a, c): symmetric, positive semi-definite, exact
/// when they agree; Newton converges to the same step either way.
#[allow(clippy::too_many_arguments)]
pub fn damping_rates_into<S: BandSink>(
    rod: &Rod3,
    frames: &[EdgeFrame],
    q: &[f64],
    rate: &impl Fn(usize) -> (f64, f64),
    tau: f64,
    grad: &mut [f64],
    mut band: Option<&mut S>,
    fixed: &[bool],
) -> f64 {
    let free = |k: usize| fixed.is_empty() || !fixed[k];
    let mut power = 0.0;
    let (mut f7, mut h7) = ([0.0; 7], [[0.0; 7]; 7]);
    for i in 0..rod.n - 1 {
        let (a, b) = (pos(i), pos(i + 1));
        let e = [q[b] - q[a], q[b + 1] - q[a + 1], q[b + 2] - q[a + 2]];
        let rest = rod.rest_length[i];
        let l = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        let mut g = [0.0; 7];
        for k in 0..3 {
            g[k] = -e[k] / (l * rest);
            g[4 + k] = e[k] / (l * rest);
        }
        let jac = band.is_some();
        f7.fill(0.0);
        if jac {
            h7.iter_mut().for_each(|r| r.fill(0.0));
        }
        let tau_k = tau * rod.ea * rest;
        power += viscous(&g, a, rate, tau_k, &mut f7, jac.then_some(&mut h7));
        scatter(a, &f7, &h7, grad, band.as_deref_mut(), &free);
    }
    let (mut f11, mut h11) = ([0.0; 11], [[0.0; 11]; 11]);
    for i in 1..rod.n - 1 {
        let base = pos(i - 1);
        let x: [f64; 11] = q[base..base + 11].try_into().unwrap();
        let gs = kernel::strain_gradients(&x, [&frames[i - 1], &frames[i]]);
        let p = &rod.elastic[i];
        let jac = band.is_some();
        f11.fill(0.0);
        if jac {
            h11.iter_mut().for_each(|r| r.fill(0.0));
        }
        for (g, k) in gs.iter().zip([p.ei1, p.ei2, p.gj]) {
            let h = jac.then_some(&mut h11);
            power += viscous(g, base, rate, tau * k, &mut f11, h);
        }
        scatter(base, &f11, &h11, grad, band.as_deref_mut(), &free);
    }
    power
}

/// Add one element's viscous force τk ṡ g (ṡ = g·v over the DOFs `base ..`, v from `vel`)
/// to `f` and with `h` its Jacobian τk g gᵀ/b. Returns the power τk ṡ².
fn viscous<const N: usize>(
    g: &[f64; N],
    base: usize,
    vel: &impl Fn(usize) -> (f64, f64),
    tau_k: f64,
    f: &mut [f64; N],
    h: Option<&mut [[f64; N]; N]>,
) -> f64 {
    let rate: f64 = (0..N)
        .map(|a| {
            let (d, b) = vel(base + a);
            g[a] * d / b
        })
        .sum();
    for a in 0..N {
        f[a] += tau_k * rate * g[a];
    }
    if let Some(h) = h {
        let bs: [f64; N] = std::array::from_fn(|a| vel(base + a).1);
        for a in 0..N {
            for c in 0..N {
                let b = if bs[a] == bs[c] {
                    bs[a]
                } else {
                    (bs[a] * bs[c]).sqrt()
                };
                h[a][c] += tau_k * g[a] * g[c] / b;
            }
        }
    }
    tau_k * rate * rate
}

/// Add the gradient and (on free rows and columns) Hessian of a stencil over the DOFs
/// `base .. base + N`.
fn scatter<const N: usize, S: BandSink>(
    base: usize,
    g: &[f64; N],
    h: &[[f64; N]; N],
    grad: &mut [f64],
    band: Option<&mut S>,
    free: &impl Fn(usize) -> bool,
) {
    for a in 0..N {
        grad[base + a] += g[a];
    }
    if let Some(b) = band {
        if (base..base + N).all(free) {
            b.add_block(base, h);
            return;
        }
        for a in (0..N).filter(|&a| free(base + a)) {
            for c in (0..N).filter(|&c| free(base + c)) {
                b.add(base + a, base + c, h[a][c]);
            }
        }
    }
}
