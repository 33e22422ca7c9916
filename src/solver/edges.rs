//! Edge contacts in the rod's Newton system: each holds its segment's point at weight s with
//! one multiplier (sliding) or two (stuck), bordered onto the filtered banded system.
//!
//! With A_j the rows of edge contact j (weights (1 − s) d and s d on its segment's two nodes,
//! d = n, and t while stuck), C_j its columns (the same with the force direction c: n and t
//! stuck, n − k t sliding), L the row filter and P the column filter of the node contacts
//! (src/solver/newton.rs), the step's equations for the update δ and the multipliers λ are
//!
//! ```text
//! K δ − Σ_j λ_j U_j = −L r,   U_j = L C_jᵀ      (the reactions λ_j C_jᵀ leave the balance)
//! V_j · δ = −g_j,             V_j = A_j P       (the held point lands on its line/anchor)
//! ```
//!
//! with K = L J P + s (I − P) the banded matrix the node contacts already give. By the Schur
//! complement on the banded factor: δ₀ = K⁻¹(−L r), Y_j = K⁻¹ U_j (one banded solve per
//! multiplier), (V Y) λ = −g − V δ₀, δ = δ₀ + Y λ; the contacts keep the multipliers the solve
//! applied (taken with the update's damping). The residual test is on the residual those
//! forces leave, L r − Σ λ U: the forces reported are the ones applied, and with the node
//! contacts' reactions (`w.r` keeps r̃ = r − Σ C_jᵀ λ_j, each node contact's own reaction) they
//! close each rod's momentum balance to the Newton residual of its free rows. (A rod solved
//! with free bodies takes the multipliers' increments in the bodies' dense system instead:
//! src/solver/edges_coupled.rs.)

use super::coupled::dense_solve;
use super::newton::{NewtonFailure, RodWork};
use crate::model::Rod;

/// A node's free index and its column and row parts of an edge multiplier.
pub(super) type NodePart = (usize, [f64; 2], [f64; 2]);

/// The (edge, unknown) pairs of a rod's edge contacts, in the order of their multipliers.
pub(super) fn unknowns(w: &RodWork) -> impl Iterator<Item = (usize, usize)> + '_ {
    w.edges
        .iter()
        .enumerate()
        .flat_map(|(j, e)| (0..e.unknowns()).map(move |u| (j, u)))
}

/// How many multipliers a rod's edge contacts have.
pub(super) fn count(w: &RodWork) -> usize {
    w.edges.iter().map(|e| e.unknowns()).sum()
}

/// Per node of edge contact j, multiplier u: its free index and the column u = L (w c) and
/// row v = P (w d) parts there (None for a driven node).
pub(super) fn parts(w: &RodWork, j: usize, u: usize) -> [Option<NodePart>; 2] {
    let e = w.edges[j];
    let ws = e.weights();
    let (c, d) = e.directions(u);
    let mut out = [None, None];
    for (a, slot) in out.iter_mut().enumerate() {
        let i = e.segment + a;
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let ct = w.contact[i];
        let uc = super::newton::rows(ws[a] * c[0], ws[a] * c[1], ct);
        let vr = super::newton::tangential(ws[a] * d[0], ws[a] * d[1], ct);
        *slot = Some((fi, [uc.0, uc.1], [vr.0, vr.1]));
    }
    out
}

/// The edge contacts' current forces out of the residual: r̃ = r − Σ (its node's share of F)
/// (after the eq. 2 residual and the compliant forces are in `w.r`).
pub fn apply_forces(w: &mut RodWork) {
    for e in &w.edges {
        for a in 0..2 {
            let f = e.node_force(a);
            let i = e.segment + a;
            w.r[2 * i] -= f[0];
            w.r[2 * i + 1] -= f[1];
        }
    }
}

/// The filtered residual the current multipliers leave, L r − Σ λ U (with −L r in `w.rhs`,
/// as `newton::residual` leaves it): its max-norm and worst node; with `write`, its negative
/// into `w.rhs` (the right-hand side for the multipliers' increments).
pub fn forces_into_rhs(rod: &Rod, w: &mut RodWork, write: bool) -> (f64, usize) {
    let mut v: Vec<f64> = w.rhs.iter().map(|x| -x).collect();
    for (j, e) in w.edges.iter().enumerate() {
        for u in 0..e.unknowns() {
            let lam = if e.is_stuck() { e.force[u] } else { e.force[0] };
            for (fi, uc, _) in parts(w, j, u).iter().flatten() {
                v[2 * fi] -= lam * uc[0];
                v[2 * fi + 1] -= lam * uc[1];
            }
        }
    }
    let (mut res, mut worst) = (0.0f64, 0usize);
    for i in 0..rod.n {
        let fi = w.free_index[i];
        if fi == usize::MAX {
            continue;
        }
        let x = v[2 * fi].abs().max(v[2 * fi + 1].abs());
        if x > res {
            res = x;
            worst = i;
        }
    }
    if write {
        for (r, x) in w.rhs.iter_mut().zip(&v) {
            *r = -x;
        }
    }
    (res, worst)
}

/// The largest constraint value of the edge contacts (m) at the iterate `w.qn` and the
/// bodies' displacements `body_dx`.
pub fn violation(w: &RodWork, body_dx: &[[f64; 3]]) -> f64 {
    unknowns(w)
        .map(|(j, u)| w.edges[j].residual(u, &w.qn, body_dx).abs())
        .fold(0.0, f64::max)
}

/// After `solve_k` (δ₀ = K⁻¹(−L r) in `w.rhs`): the multipliers λ into `w.edge_dlam` (totals:
/// `w.edge_totals`) and their part of the update, δ = δ₀ + Y λ (a rod solved alone: fixed
/// obstacles only).
pub fn border(w: &mut RodWork, res: f64, iterations: u32) -> Result<(), NewtonFailure> {
    let list: Vec<(usize, usize)> = unknowns(w).collect();
    let m = list.len();
    let dim = w.rhs.len();
    let all: Vec<_> = list.iter().map(|&(j, u)| parts(w, j, u)).collect();
    let mut ey = std::mem::take(&mut w.edge_y);
    ey.resize(m * dim, 0.0);
    for k in 0..m {
        let y = &mut ey[k * dim..(k + 1) * dim];
        y.fill(0.0);
        for (fi, u, _) in all[k].iter().flatten() {
            y[2 * fi] += u[0];
            y[2 * fi + 1] += u[1];
        }
        solve_k(w, y);
    }
    w.edge_y = ey;
    let mut s = vec![0.0; m * m];
    let mut rhs = vec![0.0; m];
    for k in 0..m {
        let (j, u) = list[k];
        rhs[k] = -w.edges[j].residual(u, &w.qn, &[]);
        for (fi, _, v) in all[k].iter().flatten() {
            rhs[k] -= v[0] * w.rhs[2 * fi] + v[1] * w.rhs[2 * fi + 1];
            for l in 0..m {
                let y = &w.edge_y[l * dim..];
                s[k * m + l] += v[0] * y[2 * fi] + v[1] * y[2 * fi + 1];
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
    for k in 0..m {
        for d in 0..dim {
            w.rhs[d] += w.edge_y[k * dim + d] * rhs[k];
        }
    }
    w.edge_dlam = rhs;
    w.edge_totals = true;
    Ok(())
}

/// The multipliers take the solve's values (`w.edge_dlam`: increments, or with
/// `w.edge_totals` the new totals) with the update's damping `scale`.
pub fn take_increments(w: &mut RodWork, scale: f64) {
    if w.edge_dlam.len() != count(w) {
        w.edge_dlam.clear();
        return;
    }
    let mut k = 0;
    for e in w.edges.iter_mut() {
        let m = e.unknowns();
        let mut d = [0.0; 2];
        for (u, du) in d.iter_mut().enumerate().take(m) {
            let now = if e.is_stuck() { e.force[u] } else { e.force[0] };
            *du = if w.edge_totals {
                w.edge_dlam[k + u] - now
            } else {
                w.edge_dlam[k + u]
            };
        }
        if w.edge_totals && scale == 1.0 {
            // Exactly the solve's multipliers.
            e.force[0] = w.edge_dlam[k];
            if e.is_stuck() {
                e.force[1] = w.edge_dlam[k + 1];
            } else {
                e.slide_friction();
            }
        } else {
            e.take_increments(&d[..m], scale);
        }
        k += m;
    }
    w.edge_dlam.clear();
    w.edge_totals = false;
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
        apply_sliding(rod, w, &p, hessian);
        w.pressings.push(p);
    }
}

/// Kinetic friction of a conforming contact's node j sliding on the fruit (its law slip):
/// −μ_k F_n s t at the node's share F_n of the fruit's force along the fruit's normal there.
/// (force on the node, ∂f/∂x_j (its own block: F_n's dependence on the other nodes is left
/// to the Newton iteration), and the moment R n × f about the fruit's centre with its
/// derivative, R the fruit's radius).
pub type Sliding = ([f64; 2], [[f64; 2]; 2], f64, [f64; 2]);

pub fn sliding(w: &RodWork, p: &crate::contact::conforming::Pressing, j: usize) -> Option<Sliding> {
    let sl = w.law_slip.get(j).copied().flatten()?;
    if sl.obstacle != p.obstacle {
        return None;
    }
    let c = w.compliant.iter().find(|c| c.obstacle == p.obstacle)?;
    let sh = p.node_share(j)?;
    let mu = c.coulomb.mu_k;
    // The node's part of its arc's kinetic force μ_k F_arc: its weight among the arc's
    // sliding nodes (the arc's force and the weights held fixed in the Jacobian).
    let g = p.regions.iter().find(|g| g.first <= j && j <= g.last)?;
    let wsum: f64 = (g.first..=g.last)
        .filter_map(|i| w.law_slip.get(i).copied().flatten())
        .filter(|s| s.obstacle == p.obstacle)
        .map(|s| s.weight)
        .sum();
    if wsum == 0.0 {
        return None;
    }
    let force = sl.weight / wsum * g.force;
    let (f, k) =
        crate::contact::compliant::kinetic_force(mu, sl.sign, force, sh.normal, [0.0; 2], sh.dturn);
    // R n × f = −R μ_k s F (the force held fixed in the Jacobian).
    let rm = c.law.r_fruit * mu * sl.sign;
    Some((f, k, -rm * force, [0.0; 2]))
}

/// The kinetic friction of a conforming contact's sliding nodes into the balance and the band.
fn apply_sliding(
    rod: &Rod,
    w: &mut RodWork,
    p: &crate::contact::conforming::Pressing,
    hessian: bool,
) {
    let last = (p.first + p.g.len() - 1).min(rod.n - 1);
    for j in p.first..=last {
        let fj = w.free_index[j];
        let Some((f, k, _, _)) = sliding(w, p, j).filter(|_| fj != usize::MAX) else {
            continue;
        };
        w.r[2 * j] -= f[0];
        w.r[2 * j + 1] -= f[1];
        if hessian {
            for x in 0..2 {
                for y in 0..2 {
                    w.band.add(2 * fj + x, 2 * fj + y, -k[x][y]);
                }
            }
        }
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
