//! Newton on every rod and body of the world at once, with the current contact sets.

use super::*;
use crate::rod3d::solver::{assemble_into, damping_into, damping_rates_into};
use crate::rod3d::symband::BandSink;
use crate::rod3d::system::band_range;

impl World3 {
    /// Largest force of the problem, the scale of the residual tolerance.
    fn force_scale(&self) -> f64 {
        let mut s: f64 = 0.0;
        for sim in &self.rods {
            let l = sim.rod.length;
            s = s.max(sim.rod.ei1.max(sim.rod.ei2) / (l * l));
            for k in 0..sim.q.len() {
                s = s.max(sim.external(k).abs());
            }
        }
        for b in &self.bodies {
            s = s.max(b.mass * self.gravity.norm()).max(b.force.norm());
        }
        s
    }

    /// Put every contact node on its constraint and every body at its displacement.
    fn place_guess(&mut self) {
        for b in &mut self.bodies {
            b.place();
        }
        for r in 0..self.rods.len() {
            for i in 0..self.rods[r].rod.n {
                if let Some(c) = self.contacts[r][i] {
                    let x = Self::node(&self.work[r].qn, i);
                    let p = Self::project(&c, &x, &self.body_dx(c.surface));
                    self.work[r].qn[pos(i)..pos(i) + 3].copy_from_slice(p.as_slice());
                }
            }
        }
    }

    /// What a prescribed local coordinate a of contact c follows: P with δu_a = P·δX.
    fn follow(c: &Contact3, q: &Matrix3<f64>, a: usize) -> Option<(usize, Vector6<f64>)> {
        let Surface3::Body(b) = c.surface else {
            return None;
        };
        let g: G3 = lever_map(&c.lever);
        Some((b, (q.row(a) * g).transpose()))
    }

    /// Rod r's residual in its contact bases with the prescribed coordinates eliminated, and
    /// with `jac` its Jacobian (in `work[r].band`, the border and the body rows); adds its rows
    /// of the body equations to `s` (`jac` only) and `fb`. Returns its largest free residual.
    fn linearise_rod(
        &mut self,
        r: usize,
        dt: f64,
        s: &mut DMatrix<f64>,
        fb: &mut DVector<f64>,
        jac: bool,
    ) -> f64 {
        self.bdf_rows(r);
        let w = &mut self.work[r];
        let contacts = &self.contacts[r];
        inertia_and_elasticity(&self.rods[r], w, dt, jac);
        super::edges3::add_edge_forces(w, &self.edges[r]);
        contact_bases(w, contacts, &mut self.reactions[r], jac);
        body_rows(w, contacts, s, fb, jac);
        kinetic_rows(w, contacts, jac);
        super::compliant3::law_rows(w, contacts, &self.bodies, jac);
        for &(i, _) in &w.bases {
            for a in contacts[i].as_ref().unwrap().held_axes() {
                let j = pos(i) + a;
                if jac {
                    let rows = band_range(w.rhs.len(), j);
                    // A coordinate that follows a body: its own column of the border.
                    let col = w.follow[j].map(|(b, p)| w.border.push(Weight::Body(b, p)));
                    w.border_col[j] = col.unwrap_or(usize::MAX);
                    let col = col.map(|k| w.border.col_mut(k));
                    w.band.eliminate(j, rows, col, &w.elim);
                }
                w.rhs[j] = 0.0;
            }
        }
        if jac {
            finish_kinetic_rows(w);
        }
        self.edge_rows(r, s, fb, jac);
        let w = &self.work[r];
        (0..w.rhs.len())
            .filter(|&k| !w.elim[k])
            .fold(0.0, |m, k| m.max(w.rhs[k].abs()))
    }

    /// The bodies' own equations (without contact forces) and their contacts' constraint rows;
    /// also Σ Gᵀ f of their last forces (for the convergence test). Into `sys`, in place.
    fn body_system(&self, dt: f64, sys: &mut BodySystem) {
        // The bodies' unknowns, then one per edge contact (src/rod3d/world/edges3.rs).
        let nx = 6 * self.bodies.len() + self.edge_count();
        if sys.s.nrows() != nx {
            sys.s = DMatrix::zeros(nx, nx);
            sys.fb = DVector::zeros(nx);
            sys.forces = DVector::zeros(nx);
        } else {
            sys.s.fill(0.0);
            sys.fb.fill(0.0);
            sys.forces.fill(0.0);
        }
        let (s, fb, forces, kkt) = (&mut sys.s, &mut sys.fb, &mut sys.forces, &mut sys.kkt);
        for (b, body) in self.bodies.iter().enumerate() {
            let (rb, jb) = body.residual(dt, &self.gravity);
            s.view_mut((6 * b, 6 * b), (6, 6)).copy_from(&jb);
            fb.rows_mut(6 * b, 6).copy_from(&-rb);
        }
        kkt.clear();
        for bc in &self.body_contacts {
            let g = lever_map(&bc.lever);
            let dx = self.bodies[bc.body].dx;
            let at = 6 * bc.body;
            if bc.law.is_some() {
                super::compliant3::body_law_rows(bc, &dx, s, fb, forces, kkt);
                continue;
            }
            let f = g.transpose() * bc.force;
            for e in 0..6 {
                forces[6 * bc.body + e] += f[e];
            }
            match bc.stuck {
                Some(mv) => {
                    let now = g * dx;
                    for a in 0..3 {
                        let j = g.row(a).into_owned();
                        kkt.push(at, j, -j, mv[a] - now[a]);
                    }
                }
                None => {
                    let j = bc.normal.transpose() * g;
                    let fdir = bc.normal - bc.dir * bc.coulomb.mu_k;
                    let col = -(fdir.transpose() * g);
                    kkt.push(at, j, col, bc.gap - (j * dx)[0]);
                }
            }
        }
    }

    /// Every rod's and body's residual (and with `jac` the bordered system) into `self.sys`:
    /// the bodies' block, its right-hand side and the bodies' contact rows. Returns the
    /// largest free residual.
    fn linearise(&mut self, dt: f64, jac: bool) -> f64 {
        let mut sys = std::mem::replace(&mut self.sys, BodySystem::empty());
        self.body_system(dt, &mut sys);
        let mut res: f64 = 0.0;
        for r in 0..self.rods.len() {
            res = res.max(self.linearise_rod(r, dt, &mut sys.s, &mut sys.fb, jac));
        }
        // fb = −(r_b + Σ Gᵀ R_node); the bodies' own contacts add their last forces.
        let nb = 6 * self.bodies.len();
        res = (0..nb).fold(res, |m, k| m.max((sys.fb[k] + sys.forces[k]).abs()));
        self.sys = sys;
        res
    }

    /// Newton with the current contact sets. Returns the iterations. Converged when every
    /// free residual is at most `force_tol` × the force scale, or when an update is at most
    /// `step_tol` × the rod length (the round-off floor), as the planar solver. The first
    /// residual comes with its Jacobian (nearly every pass needs an update); after an update
    /// the residual is evaluated alone and the Jacobian only when another update is needed.
    pub(super) fn newton(&mut self, dt: f64) -> Result<u32, Solve3Error> {
        self.place_guess();
        let tol = self.force_tol * self.force_scale();
        let length = self.rods.iter().map(|s| s.rod.length).fold(1e-3, f64::max);
        let floor = self.step_tol * length;
        let mut it = 0u32;
        loop {
            let res = self.linearise(dt, it == 0);
            if !res.is_finite() {
                return Err(self.located(fail(res, it, "non-finite residual")));
            }
            if res <= tol && (it > 0 || (self.sys.kkt.is_empty() && self.edge_count() == 0)) {
                return Ok(it);
            }
            if it >= self.max_iterations {
                return Err(self.located(fail(res, it, "Newton did not converge")));
            }
            if it > 0 {
                self.linearise(dt, true);
            }
            let upd = self
                .solve_and_update()
                .map_err(|m| self.located(fail(res, it, m)))?;
            it += 1;
            if upd <= floor {
                // At the round-off floor: accept, with the reactions of the final iterate.
                self.linearise(dt, false);
                return Ok(it);
            }
        }
    }
}

impl World3 {
    /// `e` with the finger and node of the largest free rod residual of the last
    /// linearisation (a NaN counts as the largest).
    fn located(&self, mut e: Solve3Error) -> Solve3Error {
        let mut worst: Option<(usize, usize, f64)> = None;
        for (r, w) in self.work.iter().enumerate() {
            for (k, v) in w.rhs.iter().enumerate() {
                let a = if v.is_nan() { f64::INFINITY } else { v.abs() };
                if !w.elim[k] && worst.is_none_or(|(_, _, m)| a > m) {
                    // DOFs x₀ θ₀ x₁ θ₁ …: 4 per node (θ_e with its first node).
                    worst = Some((r, k / 4, a));
                }
            }
        }
        e.at = worst.map(|(r, node, _)| (self.rod_names[r].clone(), node));
        e
    }
}

/// The inertia and elastic part of rod r's residual (`w.rhs` = −r) and with `jac` its
/// Jacobian c M + ∇²E (identity rows on fixed DOFs); resets the prescribed set to the
/// fixed DOFs.
fn inertia_and_elasticity(sim: &Sim3, w: &mut Work3, dt: f64, jac: bool) {
    let c = 1.0 / (dt * dt);
    let band = if jac {
        w.band.clear();
        Some(&mut w.band)
    } else {
        None
    };
    if w.bdf.active() {
        w.bdf.frames_at(sim, &w.qn);
    }
    let (rod, f, b) = if w.bdf.active() {
        (&sim.rod, &w.bdf.frames[..], &w.bdf.ref_twist[..])
    } else {
        (&sim.rod, &sim.frames[..], &sim.ref_twist[..])
    };
    assemble_into(rod, f, b, &w.qn, &mut w.grad, band, &sim.fixed);
    if sim.damping_time > 0.0 && w.bdf.active() {
        let band = jac.then_some(&mut w.band);
        let (qn, bd) = (&w.qn, &w.bdf);
        let rate = |k: usize| (qn[k] - bd.e[k], bd.b[k]);
        let tau = sim.damping_time;
        damping_rates_into(rod, f, qn, &rate, tau, &mut w.grad, band, &sim.fixed);
    } else if sim.damping_time > 0.0 {
        let band = jac.then_some(&mut w.band);
        let tau = sim.damping_time;
        damping_into(
            rod,
            f,
            &w.qn,
            &sim.q,
            dt,
            tau,
            &mut w.grad,
            band,
            &sim.fixed,
        );
    }
    if jac {
        w.border.clear();
    }
    for k in 0..sim.q.len() {
        w.elim[k] = sim.fixed[k];
        w.follow[k] = None;
        if sim.fixed[k] {
            w.rhs[k] = 0.0;
            continue;
        }
        let m = sim.rod.mass[k];
        let (c, inertia) = if w.bdf.active() {
            // The stage's row (src/rod3d/world/bdf3.rs): m (q − e − b w)/b².
            let (e, u, b) = (w.bdf.e[k], w.bdf.w[k], w.bdf.b[k]);
            let c = 1.0 / (b * b);
            (c, c * m * (w.qn[k] - e - b * u))
        } else {
            (c, c * m * (w.qn[k] - sim.q[k] - dt * sim.v[k]))
        };
        w.rhs[k] = -(inertia + w.grad[k] - sim.external(k));
        if jac {
            BandSink::add(&mut w.band, k, k, c * m);
        }
    }
}

/// Rotate every contact node's rows (and with `jac` its Jacobian block) into its contact
/// basis, record its reaction (world) and mark its held coordinates; `w.bases` lists them.
fn contact_bases(w: &mut Work3, contacts: &[Option<Contact3>], reactions: &mut [V3], jac: bool) {
    w.bases.clear();
    for (i, ct) in contacts.iter().enumerate() {
        let Some(ct) = ct else { continue };
        let (k0, q) = (pos(i), ct.basis());
        let rw = -V3::new(w.rhs[k0], w.rhs[k0 + 1], w.rhs[k0 + 2]);
        reactions[i] = rw;
        if jac {
            w.band.rotate_node(k0, &q);
        }
        let rl = -(q * rw);
        w.rhs[k0..k0 + 3].copy_from_slice(rl.as_slice());
        for a in ct.held_axes() {
            w.elim[k0 + a] = true;
            w.follow[k0 + a] = World3::follow(ct, &q, a);
        }
        w.bases.push((i, q));
    }
}

/// The reaction of every node touching a body, Gᵀ Qᵀ (local residual), into the body's
/// right-hand side; with `jac` its rows of the body equations (`w.rows`, and `s` for the
/// columns that follow a body).
fn body_rows(
    w: &mut Work3,
    contacts: &[Option<Contact3>],
    s: &mut DMatrix<f64>,
    fb: &mut DVector<f64>,
    jac: bool,
) {
    if jac {
        w.rows.clear();
    }
    for &(i, q) in &w.bases {
        let ct = contacts[i].as_ref().unwrap();
        let Surface3::Body(b) = ct.surface else {
            continue;
        };
        let k0 = pos(i);
        let wm = lever_map(&ct.lever).transpose() * q.transpose();
        let rl = V3::new(w.rhs[k0], w.rhs[k0 + 1], w.rhs[k0 + 2]);
        let add = wm * rl;
        for e in 0..6 {
            fb[6 * b + e] += add[e];
        }
        if !jac {
            continue;
        }
        for l in band_range(w.rhs.len(), k0) {
            let col = [0, 1, 2].map(|a| w.band.get(k0 + a, l));
            if col == [0.0; 3] {
                continue;
            }
            if !w.elim[l] {
                // One entry per body row: Σₐ (Gᵀ Qᵀ)ₑₐ A[k0 + a][l].
                for e in 0..6 {
                    let v = wm[(e, 0)] * col[0] + wm[(e, 1)] * col[1] + wm[(e, 2)] * col[2];
                    w.rows.push((6 * b + e, l, v));
                }
                continue;
            }
            for (a, &v) in col.iter().enumerate() {
                if v == 0.0 {
                    continue;
                }
                if let Some((b2, p)) = w.follow[l] {
                    for e in 0..6 {
                        for f in 0..6 {
                            s[(6 * b + e, 6 * b2 + f)] += wm[(e, a)] * v * p[f];
                        }
                    }
                }
            }
        }
    }
}

/// The kinetic rows t₁·R + μ_k n·R = 0 of rod r's sliding nodes: their right-hand sides and,
/// with `jac`, each node's normal row of the Jacobian (before the eliminations, which take
/// its prescribed columns out) into `w.kinetic`.
fn kinetic_rows(w: &mut Work3, contacts: &[Option<Contact3>], jac: bool) {
    if jac {
        // Their column lists go back to the pool (no allocation from step to step).
        w.kinetic_pool.extend(w.kinetic.drain(..).map(|k| k.n));
    }
    for &(i, _) in &w.bases {
        let ct = contacts[i].as_ref().unwrap();
        let mu = ct.kinetic();
        // A compliant contact's kinetic force is the law's (src/rod3d/world/compliant3.rs).
        if mu <= 0.0 || ct.law.is_some() {
            continue;
        }
        let k0 = pos(i);
        w.rhs[k0 + 1] += mu * w.rhs[k0];
        if jac {
            let mut n = w.kinetic_pool.pop().unwrap_or_default();
            n.clear();
            n.extend(
                band_range(w.rhs.len(), k0)
                    .map(|l| (l, w.band.get(k0, l)))
                    .filter(|&(_, v)| v != 0.0),
            );
            w.kinetic.push(KineticRow { row: k0 + 1, mu, n });
        }
    }
}

/// After the eliminations: a kinetic row keeps its free columns; a prescribed column that
/// follows a body goes to the t₁ row of that coordinate's border column (× μ), as the
/// symmetric part's did.
fn finish_kinetic_rows(w: &mut Work3) {
    for k in &mut w.kinetic {
        let (elim, follow, border) = (&w.elim, &w.follow, &mut w.border);
        let cols = &w.border_col;
        k.n.retain(|&(l, v)| {
            if !elim[l] {
                return true;
            }
            if follow[l].is_some() {
                border.col_mut(cols[l])[k.row] += k.mu * v;
            }
            false
        });
    }
}

impl World3 {
    /// Solve the bordered system of the last linearisation and apply the update. Returns the
    /// largest change.
    fn solve_and_update(&mut self) -> Result<f64, &'static str> {
        let mut blocks: Vec<RodBlock<'_>> = self
            .work
            .iter_mut()
            .map(|w| RodBlock {
                a: &w.band,
                kinetic: &w.kinetic,
                factor: &mut w.factor,
                rhs: &mut w.rhs,
                border: &w.border,
                z: &mut w.z,
                zw: &mut w.zw,
                rows: &w.rows,
            })
            .collect();
        let sys = &self.sys;
        solve_bordered(&mut blocks, &sys.s, &sys.fb, &sys.kkt, &mut self.dense)?;
        drop(blocks);
        let sol = std::mem::take(&mut self.dense.sol);
        let upd = self.apply_update(&sol);
        self.dense.sol = sol;
        Ok(upd)
    }

    /// Apply the solution `sol` (δX, then the bodies' contact multipliers) and every rod's
    /// y. Returns the largest change.
    fn apply_update(&mut self, sol: &[f64]) -> f64 {
        let nx = self.sys.fb.len();
        let (dx, lam) = sol.split_at(nx);
        let body = |b: usize| Vector6::from_column_slice(&dx[6 * b..6 * b + 6]);
        let mut upd: f64 = 0.0;
        for r in 0..self.rods.len() {
            let w = &mut self.work[r];
            let n = self.rods[r].rod.n;
            for k in 0..w.rhs.len() {
                if k % 4 != 3 && self.contacts[r][k / 4].is_some() {
                    continue;
                }
                let d = if w.elim[k] { 0.0 } else { w.rhs[k] };
                w.qn[k] += d;
                upd = upd.max(d.abs());
            }
            for i in 0..n {
                let Some(c) = self.contacts[r][i] else {
                    continue;
                };
                let (k0, q) = (pos(i), c.basis());
                let mut du = V3::zeros();
                for a in 0..3 {
                    du[a] = if !w.elim[k0 + a] {
                        w.rhs[k0 + a]
                    } else if let Some((b, p)) = w.follow[k0 + a] {
                        p.dot(&body(b))
                    } else {
                        0.0
                    };
                }
                let d = q.transpose() * du;
                for a in 0..3 {
                    w.qn[k0 + a] += d[a];
                }
                upd = upd.max(d.amax());
            }
        }
        for (b, bd) in self.bodies.iter_mut().enumerate() {
            bd.dx += body(b);
            bd.place();
        }
        self.update_edge_forces(dx);
        let mut k = 0;
        for bc in &mut self.body_contacts {
            if let Some(law) = bc.law {
                // The law's normal force at the new displacement, with the held tangential
                // multipliers (stuck) or the kinetic force (sliding).
                let (f, _) = law.force(bc.indentation(&self.bodies[bc.body].dx));
                bc.force = (bc.normal - bc.dir * bc.coulomb.mu_k) * f;
                if bc.stuck.is_some() {
                    let t = bc.tangents();
                    bc.force = bc.normal * f + t[0] * lam[k] + t[1] * lam[k + 1];
                    k += 2;
                }
                continue;
            }
            if bc.stuck.is_some() {
                bc.force = V3::new(lam[k], lam[k + 1], lam[k + 2]);
                k += 3;
            } else {
                bc.force = (bc.normal - bc.dir * bc.coulomb.mu_k) * lam[k];
                k += 1;
            }
        }
        upd
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
