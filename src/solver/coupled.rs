//! One implicit step of the rods and the free bodies they touch, solved together.
//!
//! Unknowns: each rod's free DOFs (banded) and each free body's displacement ΔX = (Δc, Δθ).
//! A node held against a body moves with it: δx_i = δy_i + C_i δX, where δy_i has no part along
//! the held directions (the modified-mass filter) and C_i = n aᵀ (normal held, a = Gᵀn) or G
//! (held whole). Its reaction acts back on the body through W_i = Gᵀ(n − k t)nᵀ (sliding, k =
//! μ_k × slip sign) or Gᵀ (held whole). With A the filtered band of a rod, B = L K C its coupling
//! columns and D = Σ W_i K_{i,:} the body rows, Newton's system is
//!
//! ```text
//! [ A            B           ] [δy]   [ −L r ]
//! [ D    c M + Σ D C + …     ] [δX] = [ −g   ]
//! ```
//!
//! solved by the Schur complement on the banded factor: z = A⁻¹(−L r), Z = A⁻¹ B (three banded
//! solves per body), (c M + Σ D (C − Z)) δX = −g − Σ D z, δy = z − Z δX: O(N) per iteration.
//! A body's own contacts with fixed obstacles add equality rows on δX with their reactions as
//! multipliers (a small dense KKT system).

use super::edges_coupled::{self, EdgeSystem};
use super::joints::Joints;
use super::joints_coupled as jc;
use super::newton::{self, IterationReport, NewtonFailure, NewtonOptions, RodWork};
use crate::contact::body::{dot3, BodyContact};
use crate::contact::Constraint;
use crate::model::Rod;
use crate::world::Body;

/// Per-rod scratch for the coupling blocks, allocated once.
#[derive(Debug, Clone, Default)]
pub struct RodCoupling {
    /// B = L K C, 2·nfree × nb, column-major (then Z = A⁻¹ B in place).
    pub(super) b: Vec<f64>,
    /// D = Σ W_i K_{i,:}, nb × 2·nfree, row-major.
    pub(super) d: Vec<f64>,
}

/// Called with (rod, report) after every Newton update.
type OnIteration<'a> = &'a mut dyn FnMut(usize, IterationReport<'_>);

/// A KKT constraint row: (body, contact, 0 normal / 1 tangential, row a, force direction w).
type KktRow = (usize, usize, usize, [f64; 3], [f64; 3]);

/// Scratch of the body system.
#[derive(Debug, Clone, Default)]
pub struct BodyScratch {
    s: Vec<f64>,
    /// The bodies' residual (inertia, gravity, node reactions).
    g: Vec<f64>,
    /// Σ D z: the rods' part of the Schur right-hand side.
    gz: Vec<f64>,
    kkt: Vec<f64>,
    rhs: Vec<f64>,
    rows: Vec<KktRow>,
    dx: Vec<[f64; 3]>,
    /// The member rods' edge multipliers (src/solver/edges_coupled.rs).
    edges: EdgeSystem,
}

/// What the coupled solve works on.
pub struct Coupled<'a> {
    pub rods: &'a [Rod],
    pub work: &'a mut [RodWork],
    pub coupling: &'a mut [RodCoupling],
    /// The rods solved with the bodies.
    pub members: &'a [usize],
    pub bodies: &'a mut [Body],
    pub scratch: &'a mut BodyScratch,
    /// The joints, and the networks among the members (solved with them:
    /// src/solver/joints_coupled.rs).
    pub joints: &'a mut Joints,
    pub networks: &'a [usize],
}

/// A failure of the coupled solve: the rod (or `usize::MAX` for a body) and why.
pub type CoupledFailure = (usize, NewtonFailure);

impl Coupled<'_> {
    fn nb(&self) -> usize {
        3 * self.bodies.len()
    }

    fn body_dx(&self) -> Vec<[f64; 3]> {
        self.bodies.iter().map(|b| b.dx).collect()
    }

    /// Newton on rods and bodies together. `on_iter(rod, report)` after every update.
    pub fn solve(
        &mut self,
        opt: &NewtonOptions,
        mut on_iter: Option<OnIteration<'_>>,
    ) -> Result<u32, CoupledFailure> {
        let nb = self.nb();
        self.prepare(nb);
        let dx = self.body_dx();
        for &r in self.members {
            newton::place_on_targets(&self.rods[r], &mut self.work[r], &dx);
        }
        let mut iterations = 0u32;
        loop {
            let (converged, res, worst) = self.linearise(opt, iterations)?;
            if converged {
                return self.accept(res, iterations);
            }
            if iterations >= opt.max_iterations {
                return Err((
                    worst.0,
                    NewtonFailure {
                        node: worst.1,
                        residual: res,
                        reason: "Newton did not converge (rods and free bodies together)",
                        iterations,
                    },
                ));
            }
            self.solve_bodies(nb, res, iterations)?;
            iterations += 1;
            let small = self.apply_update(opt, res, iterations)?;
            if let Some(cb) = on_iter.as_deref_mut() {
                for &r in self.members {
                    let w = &mut self.work[r];
                    for k in 0..w.qn.len() {
                        w.qn[k] = w.q[k] + w.dq[k];
                    }
                    cb(
                        r,
                        IterationReport {
                            iteration: iterations,
                            residual: res,
                            update: 0.0,
                            q: &w.qn,
                        },
                    );
                }
            }
            if small {
                for &r in self.members {
                    newton::finish_residual(&self.rods[r], &mut self.work[r], opt);
                }
                jc::finish(self.joints, self.networks, self.rods, self.work);
                return self.accept(res, iterations);
            }
        }
    }

    fn prepare(&mut self, nb: usize) {
        for &r in self.members {
            let m = 2 * self.work[r].nfree;
            let c = &mut self.coupling[r];
            c.b.resize(m * nb, 0.0);
            c.d.resize(m * nb, 0.0);
        }
        let sc = &mut *self.scratch;
        sc.s.resize(nb * nb, 0.0);
        sc.g.resize(nb, 0.0);
        sc.gz.resize(nb, 0.0);
        sc.dx.resize(self.bodies.len(), [0.0; 3]);
    }

    /// The joints' tolerance: the smallest step tolerance of the networks' rods (m).
    fn joint_tol(&self, opt: &NewtonOptions) -> f64 {
        self.networks
            .iter()
            .flat_map(|&id| self.joints.networks[id].rods.iter())
            .map(|&r| opt.step_tol * self.work[r].length_scale)
            .fold(f64::INFINITY, f64::min)
    }

    fn accept(&self, res: f64, iterations: u32) -> Result<u32, CoupledFailure> {
        for &r in self.members {
            newton::all_finite(&self.work[r], res, iterations).map_err(|f| (r, f))?;
        }
        Ok(iterations)
    }

    /// Residuals and Jacobians of every member rod and body; the Schur complement of the rods
    /// into the body system. Returns (converged, largest residual, its rod and node).
    fn linearise(
        &mut self,
        opt: &NewtonOptions,
        iterations: u32,
    ) -> Result<(bool, f64, (usize, usize)), CoupledFailure> {
        let nb = self.nb();
        self.body_system_start(opt);
        let mut converged = true;
        let (mut res_max, mut worst) = (0.0f64, (usize::MAX, 0usize));
        let mut first = Vec::with_capacity(self.members.len());
        for &r in self.members {
            let w = &mut self.work[r];
            follow_bodies(w, self.bodies);
            first.push(
                newton::residual(&self.rods[r], w, opt, true, iterations).map_err(|f| (r, f))?,
            );
        }
        if !self.networks.is_empty() {
            let v = jc::add_terms(self.joints, self.networks, self.rods, self.work);
            converged &= v <= self.joint_tol(opt);
        }
        for mi in 0..self.members.len() {
            let r = self.members[mi];
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            let (mut res, mut node) = first[mi];
            if !w.edges.is_empty() {
                (res, node) = super::edges::forces_into_rhs(rod, w, true);
            } else if self
                .joints
                .network_of
                .get(r)
                .is_some_and(|&id| id != usize::MAX)
            {
                (res, node) = super::joints::rod_residual(rod, w);
            }
            if res > opt.force_tol * w.force_scale {
                converged = false;
            }
            if res > res_max {
                (res_max, worst) = (res, (r, node));
            }
            newton::add_mass(rod, w, opt);
            couple_blocks(rod, w, &mut self.coupling[r], self.scratch, nb);
            couple_compliant(rod, w, &mut self.coupling[r], self.scratch, nb);
            couple_conforming(rod, w, &mut self.coupling[r], self.scratch, nb);
            newton::filter_rows(rod, w);
            newton::filter_cols(rod, w, opt);
            newton::factor(w, res, iterations).map_err(|f| (r, f))?;
            super::edges::prepare_conforming(rod, w);
            let mut rhs = std::mem::take(&mut w.rhs);
            super::edges::solve_k(w, &mut rhs);
            w.rhs = rhs;
            schur(w, &mut self.coupling[r], self.scratch, nb);
            let sc = &mut *self.scratch;
            let v = edges_coupled::linearise_rod(
                r,
                w,
                &self.coupling[r],
                self.bodies,
                &mut sc.edges,
                &mut sc.g,
            );
            if v > opt.step_tol * w.length_scale {
                converged = false;
            }
        }
        jc::columns(self.joints, self.networks, self.work);
        press_bodies(self.bodies, self.scratch, nb);
        let (body_converged, body_res, body_worst) = self.body_residuals(opt, iterations)?;
        converged &= body_converged;
        if body_res > res_max {
            (res_max, worst) = (body_res, body_worst);
        }
        Ok((converged, res_max, worst))
    }

    /// The bodies' residuals (their contacts' reactions taken off) and whether each body's
    /// contacts hold their equations: (converged, largest residual, (usize::MAX, body)).
    fn body_residuals(
        &self,
        opt: &NewtonOptions,
        iterations: u32,
    ) -> Result<(bool, f64, (usize, usize)), CoupledFailure> {
        let mut converged = true;
        let (mut res_max, mut worst) = (0.0f64, (usize::MAX, 0usize));
        for (bi, b) in self.bodies.iter().enumerate() {
            let mut g = [
                self.scratch.g[3 * bi],
                self.scratch.g[3 * bi + 1],
                self.scratch.g[3 * bi + 2],
            ];
            let g_raw = g;
            for (ci, c) in b.contacts.iter().enumerate() {
                let mut lam = b.reaction.get(ci).copied().unwrap_or([0.0; 2]);
                if c.law.is_some() {
                    // Its law's normal force is in the bodies' residual already.
                    lam[0] = 0.0;
                }
                let (wn, wt) = force_directions(c);
                for k in 0..3 {
                    g[k] -= wn[k] * lam[0] + wt[k] * lam[1];
                }
                // The contact's own equations: on the surface (and not slipping when stuck);
                // a compliant contact's normal is its law's, already in the balance.
                let mut gap = if c.law.is_some() {
                    0.0
                } else {
                    (c.target - dot3(&c.row(c.normal), &b.dx)).abs()
                };
                if c.is_stuck() {
                    gap = gap.max((c.stick_target - dot3(&c.row(c.tangent()), &b.dx)).abs());
                }
                if gap > opt.step_tol * b.spec.radius || b.reaction.len() != b.contacts.len() {
                    converged = false;
                }
            }
            let res = g[0].abs().max(g[1].abs()).max(g[2].abs() / b.spec.radius);
            if !res.is_finite() || !g_raw.iter().all(|x| x.is_finite()) {
                return Err((usize::MAX, body_failure(bi, res, iterations)));
            }
            if res > opt.force_tol * b.force_scale {
                converged = false;
            }
            if res > res_max {
                (res_max, worst) = (res, (usize::MAX, bi));
            }
        }
        Ok((converged, res_max, worst))
    }

    /// S = c M, g = the bodies' inertial residual (rod terms are added by `couple_blocks`).
    fn body_system_start(&mut self, opt: &NewtonOptions) {
        let nb = self.nb();
        let sc = &mut *self.scratch;
        sc.s.iter_mut().for_each(|x| *x = 0.0);
        sc.edges.clear();
        for (bi, b) in self.bodies.iter().enumerate() {
            let g = b.inertial_residual(opt.c, opt.dt, opt.lambda);
            for k in 0..3 {
                sc.s[(3 * bi + k) * nb + 3 * bi + k] = opt.c * b.m[k];
                sc.g[3 * bi + k] = g[k];
                sc.gz[3 * bi + k] = 0.0;
            }
        }
    }

    /// Solve the body system with the bodies' own contacts as equality rows; the body updates
    /// go to `scratch.dx`, the contact reactions to each body.
    fn solve_bodies(&mut self, nb: usize, res: f64, iterations: u32) -> Result<(), CoupledFailure> {
        let sc = &mut *self.scratch;
        sc.rows.clear();
        for (bi, b) in self.bodies.iter().enumerate() {
            for (ci, c) in b.contacts.iter().enumerate() {
                let (wn, wt) = force_directions(c);
                let a = c.row(c.normal);
                if c.law.is_none() {
                    push_row(sc, bi, ci, 0, a, wn, b.spec.radius);
                }
                if c.is_stuck() {
                    push_row(sc, bi, ci, 1, c.row(c.tangent()), wt, b.spec.radius);
                }
            }
        }
        let m = sc.rows.len();
        let me = sc.edges.len();
        let at = nb + me + m;
        let n = at + jc::unknown_count(self.joints, self.networks);
        sc.kkt.clear();
        sc.kkt.resize(n * n, 0.0);
        sc.rhs.clear();
        sc.rhs.resize(n, 0.0);
        for i in 0..nb {
            for j in 0..nb {
                sc.kkt[i * n + j] = sc.s[i * nb + j];
            }
            sc.rhs[i] = -sc.g[i] - sc.gz[i];
        }
        edges_coupled::fill(&sc.edges, &mut sc.kkt, &mut sc.rhs, n, nb);
        for (j, (bi, ci, kind, a, w)) in sc.rows.iter().enumerate() {
            let j = me + j;
            for k in 0..3 {
                sc.kkt[(3 * bi + k) * n + nb + j] = -w[k];
                sc.kkt[(nb + j) * n + 3 * bi + k] = a[k];
            }
            let b = &self.bodies[*bi];
            let c = &b.contacts[*ci];
            let target = if *kind == 0 { c.target } else { c.stick_target };
            sc.rhs[nb + j] = target - dot3(a, &b.dx);
        }
        if !self.networks.is_empty() {
            let parts = jc::Parts {
                works: self.work,
                coupling: self.coupling,
                edges: &sc.edges,
            };
            let lay = jc::Layout { n, nb, at };
            jc::fill(
                self.joints,
                self.networks,
                &parts,
                &mut sc.kkt,
                &mut sc.rhs,
                lay,
            );
        }
        if !dense_solve(&mut sc.kkt, &mut sc.rhs, n) {
            return Err((usize::MAX, body_failure(0, res, iterations)));
        }
        edges_coupled::take(&sc.edges, &sc.rhs[nb..nb + me], self.work);
        jc::take(self.joints, self.networks, self.work, &sc.rhs[at..]);
        for (bi, b) in self.bodies.iter_mut().enumerate() {
            sc.dx[bi] = [sc.rhs[3 * bi], sc.rhs[3 * bi + 1], sc.rhs[3 * bi + 2]];
            // A compliant contact keeps its law's normal force (set by `press_bodies`).
            let kept: Vec<f64> = (0..b.contacts.len())
                .map(|ci| b.reaction.get(ci).map_or(0.0, |r| r[0]))
                .collect();
            b.reaction.clear();
            b.reaction.resize(b.contacts.len(), [0.0; 2]);
            for (ci, c) in b.contacts.iter().enumerate() {
                if c.law.is_some() {
                    b.reaction[ci][0] = kept[ci];
                }
            }
        }
        for (j, (bi, ci, kind, _, _)) in sc.rows.iter().enumerate() {
            self.bodies[*bi].reaction[*ci][*kind] = sc.rhs[nb + me + j];
        }
        Ok(())
    }

    /// δy = z − Z δX on every member rod, damped alike for rods and bodies; returns whether
    /// every update is at the round-off floor.
    fn apply_update(
        &mut self,
        opt: &NewtonOptions,
        res: f64,
        iterations: u32,
    ) -> Result<bool, CoupledFailure> {
        let nb = self.nb();
        let dx = self.scratch.dx.clone();
        let mut scale = 1.0f64;
        for &r in self.members {
            let w = &mut self.work[r];
            let m = 2 * w.nfree;
            let z = &self.coupling[r].b;
            for (k, d) in dx.iter().flatten().enumerate().take(nb) {
                for i in 0..m {
                    w.rhs[i] -= z[k * m + i] * d;
                }
            }
            edges_coupled::add_y(w);
            let full = newton::largest_update(&self.rods[r], w, &dx, res, iterations)
                .map_err(|f| (r, f))?;
            if w.max_update > 0.0 && full > w.max_update {
                scale = scale.min(w.max_update / full);
            }
        }
        jc::take_multipliers(self.joints, self.networks, scale);
        let mut small = true;
        for &r in self.members {
            let rod = &self.rods[r];
            let w = &mut self.work[r];
            let upd =
                newton::update(rod, w, Some(scale), &dx, res, iterations).map_err(|f| (r, f))?;
            small &= upd <= opt.step_tol * w.length_scale;
        }
        for (b, d) in self.bodies.iter_mut().zip(&dx) {
            for k in 0..3 {
                b.dx[k] += scale * d[k];
            }
            let moved = (scale * d[0]).abs().max((scale * d[1]).abs());
            small &=
                moved.max((scale * d[2]).abs() * b.spec.radius) <= opt.step_tol * b.spec.radius;
        }
        Ok(small)
    }
}

fn body_failure(body: usize, res: f64, iterations: u32) -> NewtonFailure {
    NewtonFailure {
        node: body,
        residual: res,
        reason: "the free body's equations could not be solved",
        iterations,
    }
}

/// The compliant contacts of the bodies with fixed obstacles (a fruit on a table): the normal
/// reaction is the law's F(δ) at the current displacement, δ = target − a·ΔX, kept as the
/// contact's normal reaction; the bodies' residual gains −F w_n and the body system its
/// stiffness, ∂(−F w_n)/∂ΔX = F′ w_n aᵀ.
fn press_bodies(bodies: &mut [Body], sc: &mut BodyScratch, nb: usize) {
    for (bi, b) in bodies.iter_mut().enumerate() {
        b.reaction.resize(b.contacts.len(), [0.0; 2]);
        for (ci, c) in b.contacts.iter().enumerate() {
            if c.law.is_none() {
                continue;
            }
            let (f, k) = c.law_force(&b.dx);
            b.reaction[ci][0] = f;
            let (wn, _) = force_directions(c);
            let a = c.row(c.normal);
            for r in 0..3 {
                sc.g[3 * bi + r] -= f * wn[r];
                for l in 0..3 {
                    sc.s[(3 * bi + r) * nb + 3 * bi + l] += k * wn[r] * a[l];
                }
            }
        }
    }
}

/// Generalised directions of a body contact's normal and tangential reactions: the normal
/// reaction of a sliding contact carries its kinetic friction, R_n (n − k t).
fn force_directions(c: &BodyContact) -> ([f64; 3], [f64; 3]) {
    let (a, b) = (c.row(c.normal), c.row(c.tangent()));
    let k = match c.grip {
        crate::contact::Grip::Slide { sign } => c.coulomb.mu_k * sign,
        _ => 0.0,
    };
    ([a[0] - k * b[0], a[1] - k * b[1], a[2] - k * b[2]], b)
}

/// Add a constraint row unless it repeats the rows already there (two vertices of a flat side
/// stuck on a table constrain the same tangential motion): Gram–Schmidt with the rotation
/// scaled by the body's size.
fn push_row(
    sc: &mut BodyScratch,
    bi: usize,
    ci: usize,
    kind: usize,
    a: [f64; 3],
    w: [f64; 3],
    rho: f64,
) {
    let scaled = |v: &[f64; 3]| [v[0], v[1], v[2] / rho];
    let mut v = scaled(&a);
    let norm0 = dot3(&v, &v).sqrt();
    let mut basis: Vec<[f64; 3]> = Vec::new();
    for (b, _, _, ra, _) in sc.rows.iter() {
        if *b != bi {
            continue;
        }
        let mut u = scaled(ra);
        for e in &basis {
            let p = dot3(&u, e);
            (0..3).for_each(|k| u[k] -= p * e[k]);
        }
        let l = dot3(&u, &u).sqrt();
        if l > 1e-9 {
            basis.push([u[0] / l, u[1] / l, u[2] / l]);
        }
    }
    for e in &basis {
        let p = dot3(&v, e);
        (0..3).for_each(|k| v[k] -= p * e[k]);
    }
    if dot3(&v, &v).sqrt() > 1e-9 * norm0 {
        sc.rows.push((bi, ci, kind, a, w));
    }
}

/// The coupling blocks of one rod before its band is filtered: B = L K C (rows of nodes near a
/// body contact), D = Σ W_i K_{i,:}, and into the body system S += D C and g += Σ W_i r_i.
fn couple_blocks(rod: &Rod, w: &RodWork, cpl: &mut RodCoupling, sc: &mut BodyScratch, nb: usize) {
    let m = 2 * w.nfree;
    cpl.b.iter_mut().for_each(|x| *x = 0.0);
    cpl.d.iter_mut().for_each(|x| *x = 0.0);
    for i in 0..rod.n {
        let fi = w.free_index[i];
        let Some(c) = w.contact[i].filter(|c| c.body.is_some() && fi != usize::MAX) else {
            continue;
        };
        let (ci, wi) = maps(&c);
        let b = c.body.map_or(0, |l| l.body);
        let ri = [w.r[2 * i], w.r[2 * i + 1]];
        for k in 0..3 {
            sc.g[3 * b + k] += wi[k][0] * ri[0] + wi[k][1] * ri[1];
        }
        for j in i.saturating_sub(2)..(i + 3).min(rod.n) {
            let fj = w.free_index[j];
            if fj == usize::MAX {
                continue;
            }
            let kji = block(w, fj, fi);
            let kij = block(w, fi, fj);
            // B rows of node j: L_j K_{j,i} C_i.
            for k in 0..3 {
                let col = [
                    kji[0][0] * ci[0][k] + kji[0][1] * ci[1][k],
                    kji[1][0] * ci[0][k] + kji[1][1] * ci[1][k],
                ];
                let (x, y) = newton::rows(col[0], col[1], w.contact[j]);
                cpl.b[(3 * b + k) * m + 2 * fj] += x;
                cpl.b[(3 * b + k) * m + 2 * fj + 1] += y;
            }
            // D columns of node j: W_i K_{i,j}; and S += W_i K_{i,j} C_j for held nodes j.
            for k in 0..3 {
                let dk = [
                    wi[k][0] * kij[0][0] + wi[k][1] * kij[1][0],
                    wi[k][0] * kij[0][1] + wi[k][1] * kij[1][1],
                ];
                cpl.d[(3 * b + k) * m + 2 * fj] += dk[0];
                cpl.d[(3 * b + k) * m + 2 * fj + 1] += dk[1];
                if let Some(cj) = w.contact[j].filter(|c| c.body.is_some()) {
                    let (cjm, _) = maps(&cj);
                    let bj = cj.body.map_or(0, |l| l.body);
                    for l in 0..3 {
                        sc.s[(3 * b + k) * nb + 3 * bj + l] +=
                            dk[0] * cjm[0][l] + dk[1] * cjm[1][l];
                    }
                }
            }
        }
    }
}

/// Move the compliant fruits a rod presses into with their bodies' trial poses.
fn follow_bodies(w: &mut RodWork, bodies: &[Body]) {
    for c in &mut w.compliant {
        if let Some(b) = c.body.and_then(|b| bodies.get(b)) {
            c.center = b.trial_pose().c;
        }
    }
}

/// The coupling of the compliant fruits carried by free bodies (node contacts): node i pressed
/// into a fruit on body b feels f = F(δ) n (plus −μ_k F s t while it slides), a function of
/// x_i − c_b alone for a circle (its rotation moves nothing), so ∂f/∂c = −∂f/∂x = −K. The
/// node's rows gain ∂r_i/∂c = K (B, filtered as the band's rows); the body feels −f at its
/// surface point c + R n: g += (f, R n × f) (the normal force's moment is zero), with rows
/// ∂g/∂x_i = H (D, H = [K; ∂τ/∂x]) and ∂g/∂c = −H (S). A node also held against a body (a
/// friction hold) moves with it (S += H C_i), and its reaction W_i r_i changes with the fruit's
/// centre (S += W_i K).
fn couple_compliant(
    rod: &Rod,
    w: &RodWork,
    cpl: &mut RodCoupling,
    sc: &mut BodyScratch,
    nb: usize,
) {
    if w.edge_mode || !w.compliant.iter().any(|c| c.body.is_some()) {
        return;
    }
    let m = 2 * w.nfree;
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        for c in &w.compliant {
            let Some((b, g, h)) = newton::fruit_force(w, i, c) else {
                continue;
            };
            for row in 0..3 {
                sc.g[3 * b + row] += g[row];
                for l in 0..2 {
                    sc.s[(3 * b + row) * nb + 3 * b + l] -= h[row][l];
                    cpl.d[(3 * b + row) * m + 2 * fi + l] += h[row][l];
                }
            }
            for col in 0..2 {
                let (x, y) = newton::rows(h[0][col], h[1][col], w.contact[i]);
                cpl.b[(3 * b + col) * m + 2 * fi] += x;
                cpl.b[(3 * b + col) * m + 2 * fi + 1] += y;
            }
            let Some(ci) = w.contact[i].filter(|c| c.body.is_some()) else {
                continue;
            };
            let (cm, wm) = maps(&ci);
            let bj = ci.body.map_or(0, |l| l.body);
            for row in 0..3 {
                for l in 0..3 {
                    sc.s[(3 * b + row) * nb + 3 * bj + l] +=
                        h[row][0] * cm[0][l] + h[row][1] * cm[1][l];
                }
                for l in 0..2 {
                    sc.s[(3 * bj + row) * nb + 3 * b + l] +=
                        wm[row][0] * h[0][l] + wm[row][1] * h[1][l];
                }
            }
        }
    }
}

/// The coupling of a conforming compliant contact (edge mode) with the free body that carries
/// the fruit: the nodal forces f_j = (F/A) G_j depend on the nodes and on the fruit's centre
/// c only through x − c, so ∂f_j/∂c = −Σ_k ∂f_j/∂x_k, with ∂f_j/∂x_k = (F/A) ∂G_j/∂x_k (the
/// band's blocks) + c_A G_j h_kᵀ (the rank-one part). The nodes' rows gain ∂r_j/∂c =
/// Σ_k ∂f_j/∂x_k (B), the body feels −Σ_j f_j through its centre (radial pressure: no
/// moment): g += Σ_j f_j, D = Σ_j ∂f_j/∂x_k, S −= Σ_k D_k.
fn couple_conforming(
    rod: &Rod,
    w: &RodWork,
    cpl: &mut RodCoupling,
    sc: &mut BodyScratch,
    nb: usize,
) {
    let m = 2 * w.nfree;
    for p in &w.pressings {
        let Some(b) = w
            .compliant
            .iter()
            .find(|c| c.obstacle == p.obstacle)
            .and_then(|c| c.body)
        else {
            continue;
        };
        let last = (p.first + p.g.len() - 1).min(rod.n - 1);
        let ca = p.rank_one();
        // Σ_j G_j and Σ_k h_k (the rank-one part's sums).
        let (mut sg, mut sh) = ([0.0; 2], [0.0; 2]);
        for (g, h) in p.g.iter().zip(&p.h) {
            for a in 0..2 {
                sg[a] += g[a];
                sh[a] += h[a];
            }
        }
        let mut total = [[0.0; 2]; 2];
        for j in p.first..=last {
            let f = p.node_force(j);
            let (gj, hj) = (p.g[j - p.first], p.h[j - p.first]);
            // Σ_k ∂f_j/∂x_k (node j's rows of B) and Σ_i ∂f_i/∂x_j (node j's columns of D).
            let mut row_sum = [[0.0; 2]; 2];
            let mut col_sum = [[0.0; 2]; 2];
            for k in j.saturating_sub(1).max(p.first)..=(j + 1).min(last) {
                let (bj, bk) = (p.band_block(j, k), p.band_block(k, j));
                for x in 0..2 {
                    for y in 0..2 {
                        row_sum[x][y] += bj[x][y];
                        col_sum[x][y] += bk[x][y];
                    }
                }
            }
            for x in 0..2 {
                sc.g[3 * b + x] += f[x];
                for y in 0..2 {
                    row_sum[x][y] += ca * gj[x] * sh[y];
                    col_sum[x][y] += ca * sg[x] * hj[y];
                    total[x][y] += col_sum[x][y];
                }
            }
            let fj = w.free_index[j];
            if fj == usize::MAX {
                continue;
            }
            for col in 0..2 {
                let (x, y) = newton::rows(row_sum[0][col], row_sum[1][col], w.contact[j]);
                cpl.b[(3 * b + col) * m + 2 * fj] += x;
                cpl.b[(3 * b + col) * m + 2 * fj + 1] += y;
                for a in 0..2 {
                    cpl.d[(3 * b + col) * m + 2 * fj + a] += col_sum[col][a];
                }
            }
        }
        for x in 0..2 {
            for y in 0..2 {
                sc.s[(3 * b + x) * nb + 3 * b + y] -= total[x][y];
            }
        }
        couple_sliding(rod, w, p, b, cpl, sc, nb);
    }
}

/// The kinetic friction of a conforming contact's sliding nodes on a free body: the body
/// feels −f_k at its surface point R n_j, g += (f_k, R n_j × f_k); with the node's own block
/// K, ∂g/∂x_j = [K; ∂τ] and ∂g/∂c = −[K; ∂τ], ∂r_j/∂c = K.
fn couple_sliding(
    rod: &Rod,
    w: &RodWork,
    p: &crate::contact::conforming::Pressing,
    b: usize,
    cpl: &mut RodCoupling,
    sc: &mut BodyScratch,
    nb: usize,
) {
    let m = 2 * w.nfree;
    let last = (p.first + p.g.len() - 1).min(rod.n - 1);
    for j in p.first..=last {
        let Some((f, k, tau, dtau)) = super::edges::sliding(w, p, j) else {
            continue;
        };
        let h = [k[0], k[1], dtau];
        let g = [f[0], f[1], tau];
        let fj = w.free_index[j];
        for row in 0..3 {
            sc.g[3 * b + row] += g[row];
            for l in 0..2 {
                sc.s[(3 * b + row) * nb + 3 * b + l] -= h[row][l];
                if fj != usize::MAX {
                    cpl.d[(3 * b + row) * m + 2 * fj + l] += h[row][l];
                }
            }
        }
        if fj == usize::MAX {
            continue;
        }
        for col in 0..2 {
            let (x, y) = newton::rows(k[0][col], k[1][col], w.contact[j]);
            cpl.b[(3 * b + col) * m + 2 * fj] += x;
            cpl.b[(3 * b + col) * m + 2 * fj + 1] += y;
        }
    }
}

/// C (2×3: how the body moves the node) and W (3×2: how the node's reaction acts on the body)
/// of a node held against a body.
pub(super) fn maps(c: &Constraint) -> ([[f64; 3]; 2], [[f64; 2]; 3]) {
    let (_, g) = c.body_columns().unwrap_or((0, [[0.0; 2]; 3]));
    // G as rows: G[a][k] = g[k][a].
    let gm = [[g[0][0], g[1][0], g[2][0]], [g[0][1], g[1][1], g[2][1]]];
    if c.holds_whole_node() {
        let w = [
            [gm[0][0], gm[1][0]],
            [gm[0][1], gm[1][1]],
            [gm[0][2], gm[1][2]],
        ];
        return (gm, w);
    }
    let (n, t, k) = (c.normal, c.tangent(), c.kinetic());
    let a = [
        n[0] * gm[0][0] + n[1] * gm[1][0],
        n[0] * gm[0][1] + n[1] * gm[1][1],
        n[0] * gm[0][2] + n[1] * gm[1][2],
    ];
    let cm = [
        [n[0] * a[0], n[0] * a[1], n[0] * a[2]],
        [n[1] * a[0], n[1] * a[1], n[1] * a[2]],
    ];
    let f = [n[0] - k * t[0], n[1] - k * t[1]];
    // W = Gᵀ f nᵀ.
    let mut w = [[0.0; 2]; 3];
    for (kk, row) in w.iter_mut().enumerate() {
        let gf = gm[0][kk] * f[0] + gm[1][kk] * f[1];
        *row = [gf * n[0], gf * n[1]];
    }
    (cm, w)
}

/// The 2×2 block of the (unfiltered) band between free nodes fi (rows) and fj (columns).
#[inline]
fn block(w: &RodWork, fi: usize, fj: usize) -> [[f64; 2]; 2] {
    let b = &w.band;
    [
        [b.get(2 * fi, 2 * fj), b.get(2 * fi, 2 * fj + 1)],
        [b.get(2 * fi + 1, 2 * fj), b.get(2 * fi + 1, 2 * fj + 1)],
    ]
}

/// After the rod's band is factored and `w.rhs` holds z = A⁻¹(−L r): Z = A⁻¹ B in place of B,
/// S −= D Z, gz += D z (the body system's right-hand side is −g − D z).
fn schur(w: &RodWork, cpl: &mut RodCoupling, sc: &mut BodyScratch, nb: usize) {
    let m = 2 * w.nfree;
    for k in 0..nb {
        let col = &mut cpl.b[k * m..(k + 1) * m];
        if col.iter().any(|x| *x != 0.0) {
            super::edges::solve_k(w, col);
        }
    }
    for i in 0..nb {
        let drow = &cpl.d[i * m..(i + 1) * m];
        let mut dz = 0.0;
        for (p, q) in drow.iter().zip(&w.rhs) {
            dz += p * q;
        }
        sc.gz[i] += dz;
        for k in 0..nb {
            let col = &cpl.b[k * m..(k + 1) * m];
            let mut s = 0.0;
            for (p, q) in drow.iter().zip(col) {
                s += p * q;
            }
            sc.s[i * nb + k] -= s;
        }
    }
}

/// Gaussian elimination with partial pivoting on a small dense row-major system; false when
/// singular or not finite.
pub fn dense_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for col in 0..n {
        let p = (col..n)
            .max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))
            .unwrap_or(col);
        let piv = a[p * n + col];
        if piv == 0.0 || !piv.is_finite() {
            return false;
        }
        if p != col {
            for k in 0..n {
                a.swap(p * n + k, col * n + k);
            }
            b.swap(p, col);
        }
        for i in col + 1..n {
            let f = a[i * n + col] / piv;
            if f != 0.0 {
                for k in col..n {
                    a[i * n + k] -= f * a[col * n + k];
                }
                b[i] -= f * b[col];
            }
        }
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    b.iter().all(|x| x.is_finite())
}
