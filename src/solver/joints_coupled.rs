//! Joined rods solved with the free bodies and edge contacts (src/solver/coupled.rs): the
//! joints' border unknowns join the bodies' small dense system, so a network touching a fruit
//! or held by edge contacts is one implicit step, as a single rod is.
//!
//! The border of a network (src/solver/joints.rs) has the unknowns z (the actual updates of
//! its border DOFs) and ΔΛ (the joints' multipliers' increments); the joints' forces enter the
//! members' rows as L U y, y = (W − ρ I) z + Gᵀ ΔΛ. With a member's update
//! δy = z₀ − Z δX + Y δλ − Q y (z₀ = Ã⁻¹(−L r̃), Z the body columns, Y the edge multipliers'
//! columns, Q = Ã⁻¹ L U one banded solve per border DOF), the rows of the dense system are
//!
//! ```text
//! body rows:   … + (W_U − D Q) y                   W_U: a body-held border node's reaction map
//! edge rows:   … − V Q y
//! z rows:      z + X y + (Uᵀ P Z − Uᵀ C) δX − Uᵀ P Y δλ = Uᵀ P z₀     (δx = P δy + C δX)
//! joint rows:  G z = −c
//! ```
//!
//! (X = Uᵀ P Q), y expanded into its z and ΔΛ columns. The bands carry ρ I on the border DOFs
//! before the body columns are taken (B = L (K + ρ) C), and y takes it back on the actual
//! updates z: the step is exactly the one without ρ.

use super::coupled::{maps, RodCoupling};
use super::edges::{count, parts, unknowns};
use super::edges_coupled::EdgeSystem;
use super::joints::{self, Joints, Network};
use super::newton::{self, RodWork};
use crate::model::Rod;

/// How many unknowns the networks `nets` add to the dense system (z and ΔΛ).
pub(super) fn unknown_count(js: &Joints, nets: &[usize]) -> usize {
    nets.iter()
        .map(|&id| {
            let n = &js.networks[id];
            2 * n.border.len() + 2 * n.joints.len()
        })
        .sum()
}

/// The joints' forces (with the springs' Hessians and ρ on the bands) into the members of
/// `nets`, after their residuals. Returns the largest joint violation (m).
pub(super) fn add_terms(
    js: &mut Joints,
    nets: &[usize],
    rods: &[Rod],
    works: &mut [RodWork],
) -> f64 {
    nets.iter()
        .map(|&id| joints::add_joint_terms(js, id, rods, works, true))
        .fold(0.0, f64::max)
}

/// The joints' forces at the final iterate (after `newton::finish_residual`).
pub(super) fn finish(js: &mut Joints, nets: &[usize], rods: &[Rod], works: &mut [RodWork]) {
    for &id in nets {
        joints::add_joint_terms(js, id, rods, works, false);
    }
}

/// Q = Ã⁻¹ L U and X, after every member's band is factored.
pub(super) fn columns(js: &mut Joints, nets: &[usize], works: &[RodWork]) {
    for &id in nets {
        joints::columns(&mut js.networks[id], works);
    }
}

/// Where the parts of the dense system are: `n` its size, `nb` the bodies' unknowns, the
/// edge multipliers from `nb`, the joints' unknowns from `at`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Layout {
    pub n: usize,
    pub nb: usize,
    pub at: usize,
}

/// What the dense system is filled from.
pub(super) struct Parts<'a> {
    pub works: &'a [RodWork],
    pub coupling: &'a [RodCoupling],
    pub edges: &'a EdgeSystem,
}

/// The networks' rows and columns into the dense system.
pub(super) fn fill(
    js: &Joints,
    nets: &[usize],
    p: &Parts<'_>,
    kkt: &mut [f64],
    rhs: &mut [f64],
    lay: Layout,
) {
    let mut at = lay.at;
    for &id in nets {
        let net = &js.networks[id];
        let k = 2 * net.border.len();
        let grid = Grid { net, js, lay, at };
        fill_body_rows(&grid, p, kkt);
        fill_edge_rows(&grid, p, kkt);
        fill_z_rows(&grid, p, kkt, rhs);
        for (e, &jk) in net.joints.iter().enumerate() {
            let j = &js.joints[jk];
            for a in 0..2 {
                let row = at + k + 2 * e + a;
                let wa = &p.works[j.rods[0]].qn;
                let wb = &p.works[j.rods[1]].qn;
                rhs[row] = -(wa[2 * j.nodes[0] + a] - wb[2 * j.nodes[1] + a]);
                if let Some(v) = net.dof(j.rods[0], j.nodes[0], a) {
                    kkt[row * lay.n + at + v] = 1.0;
                }
                if let Some(v) = net.dof(j.rods[1], j.nodes[1], a) {
                    kkt[row * lay.n + at + v] = -1.0;
                }
            }
        }
        at += k + 2 * net.joints.len();
    }
}

/// One network's place in the dense system.
struct Grid<'a> {
    net: &'a Network,
    js: &'a Joints,
    lay: Layout,
    at: usize,
}

impl Grid<'_> {
    /// Row `row` has coefficients `c` on y (one per border DOF): c (W − ρ I) into the z
    /// columns, c Gᵀ into the ΔΛ columns.
    fn add_y(&self, row: usize, c: &[f64], kkt: &mut [f64]) {
        let k = c.len();
        let n = self.lay.n;
        for (u, &cu) in c.iter().enumerate() {
            if cu == 0.0 {
                continue;
            }
            for v in 0..k {
                kkt[row * n + self.at + v] += cu * self.net.w[u * k + v];
            }
        }
        for (e, &jk) in self.net.joints.iter().enumerate() {
            let j = &self.js.joints[jk];
            for a in 0..2 {
                let mut s = 0.0;
                if let Some(v) = self.net.dof(j.rods[0], j.nodes[0], a) {
                    s += c[v];
                }
                if let Some(v) = self.net.dof(j.rods[1], j.nodes[1], a) {
                    s -= c[v];
                }
                kkt[row * n + self.at + k + 2 * e + a] += s;
            }
        }
    }
}

/// Body rows: (W_U − D Q) y.
fn fill_body_rows(g: &Grid<'_>, p: &Parts<'_>, kkt: &mut [f64]) {
    let k = 2 * g.net.border.len();
    let mut c = vec![0.0; k];
    for x in 0..g.lay.nb {
        for (u, cu) in c.iter_mut().enumerate() {
            let (r, i, _) = g.net.border[u / 2];
            let w = &p.works[r];
            let dim = 2 * w.nfree;
            let d = &p.coupling[r].d[x * dim..(x + 1) * dim];
            *cu = -d
                .iter()
                .zip(&g.net.cols[u])
                .map(|(a, b)| a * b)
                .sum::<f64>();
            if let Some(ct) = w.contact[i].filter(|c| c.body.is_some()) {
                let b = ct.body.map_or(0, |l| l.body);
                if x / 3 == b {
                    *cu += maps(&ct).1[x % 3][u % 2];
                }
            }
        }
        g.add_y(x, &c, kkt);
    }
}

/// Edge rows of the members: −V Q y.
fn fill_edge_rows(g: &Grid<'_>, p: &Parts<'_>, kkt: &mut [f64]) {
    let k = 2 * g.net.border.len();
    for &r in &g.net.rods {
        let w = &p.works[r];
        let Some(first) = p.edges.first_of(r).filter(|_| count(w) > 0) else {
            continue;
        };
        for (kk, (j, u)) in unknowns(w).enumerate() {
            let mut c = vec![0.0; k];
            for (fi, _, v) in parts(w, j, u).iter().flatten() {
                for (col, cc) in c.iter_mut().enumerate() {
                    if g.net.border[col / 2].0 != r {
                        continue;
                    }
                    let q = &g.net.cols[col];
                    *cc -= v[0] * q[2 * fi] + v[1] * q[2 * fi + 1];
                }
            }
            g.add_y(g.lay.nb + first + kk, &c, kkt);
        }
    }
}

/// z rows: z + X y + (Uᵀ P Z − Uᵀ C) δX − Uᵀ P Y δλ = Uᵀ P z₀.
fn fill_z_rows(g: &Grid<'_>, p: &Parts<'_>, kkt: &mut [f64], rhs: &mut [f64]) {
    let k = 2 * g.net.border.len();
    let (n, nb) = (g.lay.n, g.lay.nb);
    for u in 0..k {
        let row = g.at + u;
        let (r, i, fi) = g.net.border[u / 2];
        let a = u % 2;
        let w = &p.works[r];
        let ct = w.contact[i];
        let pick = |x: f64, y: f64| {
            let t = newton::tangential(x, y, ct);
            if a == 0 {
                t.0
            } else {
                t.1
            }
        };
        kkt[row * n + row] += 1.0;
        g.add_y(row, &g.net.x[u * k..(u + 1) * k], kkt);
        rhs[row] = pick(w.rhs[2 * fi], w.rhs[2 * fi + 1]);
        let dim = 2 * w.nfree;
        for x in 0..nb {
            let z = &p.coupling[r].b[x * dim..];
            kkt[row * n + x] += pick(z[2 * fi], z[2 * fi + 1]);
        }
        if let Some(c) = ct.filter(|c| c.body.is_some()) {
            let b = c.body.map_or(0, |l| l.body);
            let cm = maps(&c).0;
            for l in 0..3 {
                kkt[row * n + 3 * b + l] -= cm[a][l];
            }
        }
        if let Some(first) = p.edges.first_of(r) {
            for l in 0..count(w) {
                let y = &w.edge_y[l * dim..];
                kkt[row * n + nb + first + l] -= pick(y[2 * fi], y[2 * fi + 1]);
            }
        }
    }
}

/// The solved z and ΔΛ (`sol`, from the networks' first unknown) into the networks; each
/// member's update takes −Q y.
pub(super) fn take(js: &mut Joints, nets: &[usize], works: &mut [RodWork], sol: &[f64]) {
    let mut at = 0;
    let Joints {
        joints: list,
        networks,
        ..
    } = js;
    for &id in nets {
        let net = &mut networks[id];
        let len = 2 * net.border.len() + 2 * net.joints.len();
        net.rhs.copy_from_slice(&sol[at..at + len]);
        joints::corrections(net, list, works);
        at += len;
    }
}

/// The multipliers take their increments, damped by `scale`.
pub(super) fn take_multipliers(js: &mut Joints, nets: &[usize], scale: f64) {
    for &id in nets {
        joints::take_multipliers(js, id, scale);
    }
}
