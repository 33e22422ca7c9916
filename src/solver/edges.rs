//! Edge contacts in the rod's Newton system: each is one equation on two nodes, bordered onto
//! the filtered banded system as a KKT multiplier.
//!
//! With A_j the row of edge contact j (weights (1 − s) n and s n on its segment's two nodes),
//! L the row filter and P the column filter of the node contacts (src/solver/newton.rs), the
//! step's equations are
//!
//! ```text
//! K δ − Σ_j λ_j U_j = −L r,   U_j = L A_jᵀ      (the reactions λ_j A_jᵀ leave the balance)
//! V_j · δ = −g_j,             V_j = A_j P       (the held point lands on its line)
//! ```
//!
//! with K = L J P + s (I − P) the banded matrix the node contacts already give. By the Schur
//! complement on the banded factor: δ₀ = K⁻¹(−L r), Y_j = K⁻¹ U_j (one banded solve per edge),
//! (V Y) λ = −g − V δ₀, δ = δ₀ + Y λ. The residual test uses the part of L r that no
//! multiplier explains: L r − U λ with λ the least-squares multipliers, which are also the
//! edge contacts' normal forces (N, positive when pressing) reported after convergence.

use super::coupled::dense_solve;
use super::newton::{NewtonFailure, RodWork};
use crate::model::Rod;

/// A node's free index and its column and row parts of an edge contact.
type NodePart = (usize, [f64; 2], [f64; 2]);

/// Per node of edge contact j: its free index and the column u = L (w n) and row v = P (w n)
/// parts there (None for a driven node).
fn parts(w: &RodWork, j: usize) -> [Option<NodePart>; 2] {
    let e = w.edges[j];
    let ws = e.weights();
    let mut out = [None, None];
    for (a, slot) in out.iter_mut().enumerate() {
        let i = e.segment + a;
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let f = [ws[a] * e.normal[0], ws[a] * e.normal[1]];
        let c = w.contact[i];
        let u = super::newton::rows(f[0], f[1], c);
        let v = super::newton::tangential(f[0], f[1], c);
        *slot = Some((fi, [u.0, u.1], [v.0, v.1]));
    }
    out
}

/// The filtered residual with the edge reactions taken out (least-squares multipliers into
/// `w.edge_force`), its max-norm and worst node, and the largest constraint violation (m).
/// Call after `newton::residual` (which leaves −L r in `w.rhs`).
pub fn residual(rod: &Rod, w: &mut RodWork) -> (f64, usize, f64) {
    let m = w.edges.len();
    let mut a = vec![0.0; m * m];
    let mut b = vec![0.0; m];
    let all: Vec<_> = (0..m).map(|j| parts(w, j)).collect();
    for j in 0..m {
        for (fi, u, _) in all[j].iter().flatten() {
            b[j] -= u[0] * w.rhs[2 * fi] + u[1] * w.rhs[2 * fi + 1];
            for k in 0..m {
                for (fk, uk, _) in all[k].iter().flatten() {
                    if fk == fi {
                        a[j * m + k] += u[0] * uk[0] + u[1] * uk[1];
                    }
                }
            }
        }
    }
    if !dense_solve(&mut a, &mut b, m) {
        b.fill(0.0);
    }
    let mut lr: Vec<f64> = w.rhs.iter().map(|x| -x).collect();
    for j in 0..m {
        for (fi, u, _) in all[j].iter().flatten() {
            lr[2 * fi] -= b[j] * u[0];
            lr[2 * fi + 1] -= b[j] * u[1];
        }
    }
    w.edge_force.clone_from(&b);
    let (mut res, mut worst) = (0.0f64, 0usize);
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let v = lr[2 * fi].abs().max(lr[2 * fi + 1].abs());
        if v > res {
            res = v;
            worst = i;
        }
    }
    let gmax = w
        .edges
        .iter()
        .map(|e| e.violation(&w.qn).abs())
        .fold(0.0, f64::max);
    (res, worst, gmax)
}

/// After `w.band.solve(&mut w.rhs)` (δ₀ in `w.rhs`): add the multipliers' part, δ = δ₀ + Y λ.
pub fn border(w: &mut RodWork, res: f64, iterations: u32) -> Result<(), NewtonFailure> {
    let m = w.edges.len();
    let dim = w.rhs.len();
    let all: Vec<_> = (0..m).map(|j| parts(w, j)).collect();
    let mut ey = std::mem::take(&mut w.edge_y);
    ey.resize(m * dim, 0.0);
    for j in 0..m {
        let y = &mut ey[j * dim..(j + 1) * dim];
        y.fill(0.0);
        for (fi, u, _) in all[j].iter().flatten() {
            y[2 * fi] += u[0];
            y[2 * fi + 1] += u[1];
        }
        solve_k(w, y);
    }
    w.edge_y = ey;
    let mut s = vec![0.0; m * m];
    let mut rhs = vec![0.0; m];
    for j in 0..m {
        rhs[j] = -w.edges[j].violation(&w.qn);
        for (fi, _, v) in all[j].iter().flatten() {
            rhs[j] -= v[0] * w.rhs[2 * fi] + v[1] * w.rhs[2 * fi + 1];
            for k in 0..m {
                let y = &w.edge_y[k * dim..];
                s[j * m + k] += v[0] * y[2 * fi] + v[1] * y[2 * fi + 1];
            }
        }
    }
    if !dense_solve(&mut s, &mut rhs, m) {
        let e = w.edges[0];
        return Err(NewtonFailure {
            node: e.segment,
            residual: res,
            reason: "singular edge-contact rows",
            iterations,
        });
    }
    for j in 0..m {
        for d in 0..dim {
            w.rhs[d] += w.edge_y[j * dim + d] * rhs[j];
        }
    }
    Ok(())
}

/// The edge contacts' forces of the final iterate (after `newton::finish_residual`, which
/// leaves `w.rhs` stale): −L r into `w.rhs`, then the least-squares multipliers.
pub fn refresh_forces(rod: &Rod, w: &mut RodWork) {
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let (rx, ry) = super::newton::rows(w.r[2 * i], w.r[2 * i + 1], w.contact[i]);
        w.rhs[2 * fi] = -rx;
        w.rhs[2 * fi + 1] = -ry;
    }
    residual(rod, w);
}

use super::Simulation;
use crate::contact::edge::{self, EdgeContact};
use crate::scenario::contact::ContactPoints;

impl Simulation {
    /// Whether rod `r`'s segments are tested (`[contact] points = "edges"`; not while the rod
    /// is solved with a free body, whose coupled system has no edge rows).
    pub(super) fn edges_on(&self, r: usize) -> bool {
        self.scenario.contact.points == ContactPoints::Edges
            && !self.is_member[r]
            && self.rods[r].n > 1
    }

    /// The segments of rod `r` (configuration `q`) that a fixed obstacle holds at an interior
    /// point: (segment, obstacle, weight, proximity), skipping pairs in `held`.
    pub(super) fn edge_candidates(
        &self,
        r: usize,
        q: &[f64],
        held: &[EdgeContact],
    ) -> Vec<(usize, usize, f64, crate::obstacle::Proximity)> {
        let rod = &self.rods[r];
        let s = self.rod_surfaces(r);
        let mut out = Vec::new();
        for i in 0..rod.n - 1 {
            // Two nodes held whole (stuck, or in corners) leave the segment no freedom for a
            // row of its own.
            let whole = |j: usize| self.work[r].contact[j].is_some_and(|c| c.holds_whole_node());
            if rod.clamped[i] || rod.clamped[i + 1] || (whole(i) && whole(i + 1)) {
                continue;
            }
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            for k in 0..s.len() {
                if self.body_of[k] != usize::MAX
                    || held.iter().any(|e| e.segment == i && e.obstacle == k)
                    || edge::lower_bound(&s, k, a, b) >= 0.0
                {
                    continue;
                }
                let (w, prox) = edge::closest_on_segment(&s, k, a, b);
                if prox.distance < 0.0 && edge::interior(w) {
                    out.push((i, k, w, prox));
                }
            }
        }
        out
    }

    /// Edge contacts carried into a step: re-linearised at the start positions (a point whose
    /// closest point moved onto a node is left to the node).
    pub(super) fn relinearise_edges_at_start(&mut self, r: usize) {
        let w = &self.work[r];
        if w.edges.is_empty() {
            return;
        }
        let s = self.rod_surfaces(r);
        let q = &w.q;
        let mut out = Vec::with_capacity(w.edges.len());
        for e in &w.edges {
            let i = e.segment;
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            let (wt, prox) = edge::closest_on_segment(&s, e.obstacle, a, b);
            if edge::interior(wt) {
                out.push(EdgeContact::at(e.obstacle, i, wt, &prox));
            }
        }
        self.work[r].edges = out;
    }

    /// Rod `r`'s edge contacts after a pass: released when the multiplier pulls,
    /// re-linearised where the pass left the segment inside, dropped when the deepest point
    /// slid onto a node; new interior penetrations added. Returns whether the set changed.
    pub(super) fn update_edges(&mut self, r: usize) -> bool {
        if !self.edges_on(r) {
            let had = !self.work[r].edges.is_empty();
            self.work[r].edges.clear();
            return had;
        }
        let relin_tol = 1e-10 * self.rods[r].length;
        let dynamic = self.scenario.solve.mode == crate::scenario::Mode::Dynamic;
        let s = self.rod_surfaces(r);
        let w = &self.work[r];
        let q = &w.qn;
        let mut released = Vec::new();
        let mut out = Vec::with_capacity(w.edges.len());
        let mut changed = false;
        for (j, e) in w.edges.iter().enumerate() {
            if w.edge_force.get(j).copied().unwrap_or(0.0) < 0.0 && !e.locked {
                released.push((e.segment, e.obstacle));
                changed = true;
                continue;
            }
            let i = e.segment;
            let whole = |j: usize| w.contact[j].is_some_and(|c| c.holds_whole_node());
            if whole(i) && whole(i + 1) {
                changed = true;
                continue;
            }
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            let (wt, prox) = edge::closest_on_segment(&s, e.obstacle, a, b);
            // Static mode: re-linearised by `follow_edges` (solver/statics.rs).
            if prox.distance >= -relin_tol || !dynamic {
                out.push(*e);
            } else if edge::interior(wt) {
                let ne = EdgeContact {
                    locked: e.locked,
                    ..EdgeContact::at(e.obstacle, i, wt, &prox)
                };
                changed |= ne != *e;
                out.push(ne);
            } else {
                changed = true;
            }
        }
        // Static mode: the increment's first entry is held first (solver/statics.rs).
        let fresh = if dynamic {
            self.edge_candidates(r, &self.work[r].qn, &out)
        } else {
            Vec::new()
        };
        let w = &mut self.work[r];
        w.edge_released.extend(released);
        for (i, k, wt, prox) in fresh {
            out.push(EdgeContact {
                locked: w.edge_released.contains(&(i, k)),
                ..EdgeContact::at(k, i, wt, &prox)
            });
            changed = true;
        }
        w.edges = out;
        w.edge_force.resize(w.edges.len(), 0.0);
        w.mark_edge_nodes();
        changed
    }

    /// The deepest point of rod `r`'s segments inside a rigid obstacle (m, ≥ 0) in edge
    /// mode (0 otherwise): what the nodes' penetration misses between them.
    pub(super) fn segment_penetration(&self, r: usize) -> f64 {
        if self.scenario.contact.points != ContactPoints::Edges || self.rods[r].n < 2 {
            return 0.0;
        }
        let s = self.rod_surfaces(r);
        let q = &self.work[r].q;
        let mut pen = 0.0f64;
        for i in 0..self.rods[r].n - 1 {
            if self.rods[r].clamped[i] || self.rods[r].clamped[i + 1] {
                continue;
            }
            let a = [q[2 * i], q[2 * i + 1]];
            let b = [q[2 * i + 2], q[2 * i + 3]];
            for k in 0..s.len() {
                if edge::lower_bound(&s, k, a, b) < 0.0 {
                    pen = pen.max(-edge::closest_on_segment(&s, k, a, b).1.distance);
                }
            }
        }
        pen
    }
}

/// A compliant fruit's force in edge mode: its pressure distributed along the prong and
/// integrated over the contact arcs (src/contact/conforming.rs), so the force does not depend
/// on where the nodes fall. The nodal forces (F / A) G_j join the balance; with `hessian` the
/// banded part of their stiffness, (F / A) ∂G_j/∂x_k, joins the band; the rank-one part, from
/// the resultant's dependence on the whole overlap area, joins the solve by Woodbury's formula
/// ([`prepare_conforming`], [`solve_k`]): the full Jacobian, Newton's quadratic rate.
pub fn press_compliant_edges(rod: &Rod, w: &mut RodWork, hessian: bool) {
    w.pressed.iter_mut().for_each(|p| *p = None);
    w.pressings.clear();
    for ci in 0..w.compliant.len() {
        let Some(p) = crate::contact::conforming::press(&w.compliant[ci], &w.qn, rod.n) else {
            continue;
        };
        apply_pressing(w, &p, hessian);
        w.pressings.push(p);
    }
}

/// Ready the rank-one parts of the conforming contacts' stiffness for [`solve_k`] (after the
/// band is factored): per fruit pressed, ∂r/∂x gains u vᵀ with u = −c G (rows filtered as the
/// band's, L u) and v = h = ∂A/∂x (columns filtered, P v), c = d(F/A)/dA. Woodbury:
/// Z = K⁻¹ U (one banded solve per fruit) and S = I + Vᵀ Z.
pub fn prepare_conforming(rod: &Rod, w: &mut RodWork) {
    let m = w.pressings.len();
    let dim = w.rhs.len();
    w.conform_z.clear();
    w.conform_v.clear();
    w.conform_s.clear();
    if m == 0 {
        return;
    }
    w.conform_z.resize(m * dim, 0.0);
    w.conform_v.resize(m * dim, 0.0);
    for (k, p) in w.pressings.iter().enumerate() {
        let c = p.rank_one();
        for (jj, (g, h)) in p.g.iter().zip(&p.h).enumerate() {
            let j = p.first + jj;
            let fj = w.free_index[j];
            if j >= rod.n || fj == usize::MAX {
                continue;
            }
            let u = super::newton::rows(-c * g[0], -c * g[1], w.contact[j]);
            let v = super::newton::tangential(h[0], h[1], w.contact[j]);
            w.conform_z[k * dim + 2 * fj] = u.0;
            w.conform_z[k * dim + 2 * fj + 1] = u.1;
            w.conform_v[k * dim + 2 * fj] = v.0;
            w.conform_v[k * dim + 2 * fj + 1] = v.1;
        }
        w.band.solve(&mut w.conform_z[k * dim..(k + 1) * dim]);
    }
    w.conform_s = vec![0.0; m * m];
    for a in 0..m {
        for b in 0..m {
            let va = &w.conform_v[a * dim..(a + 1) * dim];
            let zb = &w.conform_z[b * dim..(b + 1) * dim];
            let d: f64 = va.iter().zip(zb).map(|(x, y)| x * y).sum();
            w.conform_s[a * m + b] = d + if a == b { 1.0 } else { 0.0 };
        }
    }
}

/// x ← (K + U Vᵀ)⁻¹ x on the factored band K with the rank-one parts readied by
/// [`prepare_conforming`] (just K⁻¹ x when there are none).
pub fn solve_k(w: &RodWork, x: &mut [f64]) {
    w.band.solve(x);
    let m = w.conform_s.len().isqrt();
    if m == 0 || m * m != w.conform_s.len() {
        return;
    }
    let dim = x.len();
    let mut t: Vec<f64> = (0..m)
        .map(|a| {
            w.conform_v[a * dim..(a + 1) * dim]
                .iter()
                .zip(x.iter())
                .map(|(v, y)| v * y)
                .sum()
        })
        .collect();
    let mut s = w.conform_s.clone();
    if !dense_solve(&mut s, &mut t, m) {
        return;
    }
    for (a, ta) in t.iter().enumerate() {
        for (d, xd) in x.iter_mut().enumerate() {
            *xd -= w.conform_z[a * dim + d] * ta;
        }
    }
}

/// A fruit's nodal forces into the balance (r −= f), −∂f/∂x's banded part into the band.
fn apply_pressing(w: &mut RodWork, p: &crate::contact::conforming::Pressing, hessian: bool) {
    let last = p.first + p.g.len() - 1;
    for j in p.first..=last {
        let f = p.node_force(j);
        w.r[2 * j] -= f[0];
        w.r[2 * j + 1] -= f[1];
        let fj = w.free_index[j];
        if !hessian || fj == usize::MAX {
            continue;
        }
        for k in j.saturating_sub(1).max(p.first)..=(j + 1).min(last) {
            let fk = w.free_index[k];
            if fk == usize::MAX {
                continue;
            }
            let b = p.band_block(j, k);
            for x in 0..2 {
                for y in 0..2 {
                    w.band.add(2 * fj + x, 2 * fk + y, -b[x][y]);
                }
            }
        }
    }
}
