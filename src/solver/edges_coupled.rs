//! Edge contacts of the rods solved with the free bodies (src/solver/coupled.rs): their
//! multipliers join the small dense system of the bodies, as the 3D solver's do.
//!
//! For a member rod with its filtered band A, coupling columns B and body rows D (the node
//! contacts on bodies), edge multiplier u of contact j (column direction c, row direction d,
//! weights w_a on its segment's nodes a) adds
//!
//! ```text
//! rod rows:   A δy + B δX − U_u δλ_u = −L r̃          U_u = L (w c) at the two nodes
//! edge row:   V_u δy + E_u δX = −g_u                  V_u = P (w d),
//!             E_u = Σ_a w_a dᵀ C_a − [on body b] Gᵀ d  (C_a: how a body-held node follows)
//! body rows:  D δy + (c M + D C) δX + H_u δλ_u + … = −g_B,
//!             H_u = [on body b] Gᵀ c − Σ_a W_a (w_a c)  (W_a: a body-held node's reaction map)
//! ```
//!
//! g_B carries Gᵀ F of every edge force F on a body (−F acts on it at the contact point).
//! With δy = z − Z δX + Y δλ (Y_u = A⁻¹ U_u, one banded solve per multiplier) the multipliers'
//! rows and columns in the dense system are (E − V Z) δX + (V Y) δλ = −g − V z and
//! (H + D Y) δλ in the body rows: rods and bodies stay one implicit step.

use super::coupled::{maps, RodCoupling};
use super::edges::{count, parts, unknowns};
use super::newton::RodWork;
use crate::world::Body;

/// The edge multipliers of the member rods as unknowns of the bodies' dense system.
#[derive(Debug, Clone, Default)]
pub struct EdgeSystem {
    /// Per multiplier: its rod.
    rod: Vec<usize>,
    /// Per multiplier: its row's coefficients on every body's δX (E − V Z; nb each).
    row_x: Vec<f64>,
    /// Per multiplier: its column in every body's rows (H + D Y; nb each).
    col_x: Vec<f64>,
    /// Per rod with edges: (its first multiplier, how many, V Y row-major).
    blocks: Vec<(usize, usize, Vec<f64>)>,
    /// Per multiplier: −g − V z.
    rhs: Vec<f64>,
}

impl EdgeSystem {
    pub(super) fn clear(&mut self) {
        self.rod.clear();
        self.row_x.clear();
        self.col_x.clear();
        self.blocks.clear();
        self.rhs.clear();
    }

    /// How many multipliers.
    pub(super) fn len(&self) -> usize {
        self.rod.len()
    }

    /// The index of rod `r`'s first multiplier (its multipliers are consecutive).
    pub(super) fn first_of(&self, r: usize) -> Option<usize> {
        self.rod.iter().position(|&x| x == r)
    }
}

/// After the rod's band is factored, `w.rhs` holds z = A⁻¹(−L r̃) (the current forces out of
/// the right-hand side: `edges::forces_into_rhs`) and `cpl` holds Z and D (see
/// `coupled::schur`): the rod's edge multipliers into `sys` (Y into `w.edge_y`), and G^T F of
/// its edges on bodies into the bodies' residual `g`. Returns the largest constraint value of
/// its edge contacts (m).
pub fn linearise_rod(
    r: usize,
    w: &mut RodWork,
    cpl: &RodCoupling,
    bodies: &[Body],
    sys: &mut EdgeSystem,
    g: &mut [f64],
) -> f64 {
    let m = count(w);
    w.edge_dlam.clear();
    w.edge_totals = false;
    if m == 0 {
        return 0.0;
    }
    let nb = 3 * bodies.len();
    let dim = 2 * w.nfree;
    let dx: Vec<[f64; 3]> = bodies.iter().map(|b| b.dx).collect();
    let list: Vec<(usize, usize)> = unknowns(w).collect();
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
        super::edges::solve_k(w, y);
    }
    w.edge_y = ey;
    for e in w.edges.iter() {
        if let Some(l) = e.body {
            let a = e.body_row(e.total_force());
            (0..3).for_each(|k| g[3 * l.body + k] += a[k]);
        }
    }
    let first = sys.len();
    let mut block = vec![0.0; m * m];
    let mut violation = 0.0f64;
    for k in 0..m {
        let (j, u) = list[k];
        let gu = w.edges[j].residual(u, &w.qn, &dx);
        violation = violation.max(gu.abs());
        let (row, col) = body_parts(w, j, u, nb);
        let mut rhs = -gu;
        sys.row_x.extend_from_slice(&row);
        sys.col_x.extend_from_slice(&col);
        let at = sys.row_x.len() - nb;
        for (fi, _, v) in all[k].iter().flatten() {
            let (a, b) = (2 * fi, 2 * fi + 1);
            rhs -= v[0] * w.rhs[a] + v[1] * w.rhs[b];
            for x in 0..nb {
                let z = &cpl.b[x * dim..];
                sys.row_x[at + x] -= v[0] * z[a] + v[1] * z[b];
            }
            for l in 0..m {
                let y = &w.edge_y[l * dim..];
                block[k * m + l] += v[0] * y[a] + v[1] * y[b];
            }
        }
        let y = &w.edge_y[k * dim..(k + 1) * dim];
        for x in 0..nb {
            let d = &cpl.d[x * dim..(x + 1) * dim];
            sys.col_x[at + x] += d.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
        }
        sys.rhs.push(rhs);
        sys.rod.push(r);
    }
    sys.blocks.push((first, m, block));
    violation
}

/// Edge multiplier u of contact j: the parts of its row on the bodies' δX that do not pass
/// through the band (E: body-held nodes of the segment, the body the edge is on), and of its
/// column in the bodies' rows (H).
fn body_parts(w: &RodWork, j: usize, u: usize, nb: usize) -> (Vec<f64>, Vec<f64>) {
    let e = w.edges[j];
    let (c, d) = e.directions(u);
    let (mut row, mut col) = (vec![0.0; nb], vec![0.0; nb]);
    if let Some(l) = e.body {
        let (ad, ac) = (e.body_row(d), e.body_row(c));
        for k in 0..3 {
            row[3 * l.body + k] -= ad[k];
            col[3 * l.body + k] += ac[k];
        }
    }
    for (a, wa) in e.weights().into_iter().enumerate() {
        let i = e.segment + a;
        let Some(ct) = w.contact[i].filter(|c| c.body.is_some()) else {
            continue;
        };
        if w.free_index[i] == usize::MAX {
            continue;
        }
        let b = ct.body.map_or(0, |l| l.body);
        let (cm, wm) = maps(&ct);
        for k in 0..3 {
            row[3 * b + k] += wa * (d[0] * cm[0][k] + d[1] * cm[1][k]);
            col[3 * b + k] -= wa * (wm[k][0] * c[0] + wm[k][1] * c[1]);
        }
    }
    (row, col)
}

/// The multipliers' rows and columns into the dense system of size `n` (the bodies' nb
/// unknowns first, the multipliers after them).
pub fn fill(sys: &EdgeSystem, kkt: &mut [f64], rhs: &mut [f64], n: usize, nb: usize) {
    for k in 0..sys.len() {
        for x in 0..nb {
            kkt[(nb + k) * n + x] = sys.row_x[k * nb + x];
            kkt[x * n + nb + k] = sys.col_x[k * nb + x];
        }
        rhs[nb + k] = sys.rhs[k];
    }
    for (first, m, block) in &sys.blocks {
        for k in 0..*m {
            for l in 0..*m {
                kkt[(nb + first + k) * n + nb + first + l] = block[k * m + l];
            }
        }
    }
}

/// The solved increments `dlam` (one per multiplier, in order) to their rods
/// (`w.edge_dlam`, taken by the update).
pub fn take(sys: &EdgeSystem, dlam: &[f64], work: &mut [RodWork]) {
    for (&r, d) in sys.rod.iter().zip(dlam) {
        work[r].edge_dlam.push(*d);
    }
}

/// The multipliers' part of the rod's update: δy += Y δλ.
pub fn add_y(w: &mut RodWork) {
    let dim = w.rhs.len();
    for (k, d) in w.edge_dlam.iter().enumerate() {
        for (x, y) in w.rhs.iter_mut().zip(&w.edge_y[k * dim..(k + 1) * dim]) {
            *x += y * d;
        }
    }
}
