//! The Newton system of one 3D step with contacts: every rod's banded Jacobian in the local
//! contact bases of its contact nodes, the prescribed coordinates eliminated (identity rows),
//! and the free bodies' unknowns ΔX coupled in by a bordered solve (Schur complement):
//!
//! [A_r  B_r] [y_r]   [f_r]      A_r banded (one per rod), B_r the columns of the prescribed
//! [C_r  S  ] [δX ] = [f_b]      coordinates that follow a body (δu_j = P_j δX), C_r the rows
//!                                Gᵀ Qᵀ of the nodes touching a body (the reaction on the body).
//!
//! δX = (S − Σ C_r A_r⁻¹ B_r)⁻¹ (f_b − Σ C_r A_r⁻¹ f_r), then y_r = A_r⁻¹ (f_r − B_r δX).
//! A body's contacts with fixed obstacles add Lagrange multipliers to the small dense system.

use super::symband::SymBand;
use crate::solver::banded::BandLu;
use nalgebra::{DMatrix, DVector, Matrix3, Vector6};

/// Rotate node block `k0..k0+3` of band `a` into the basis whose rows are `q`: rows, then
/// columns (A ← Q A Qᵀ on that block row and column). Node blocks couple only with columns
/// k0 − 8 … k0 + 10 (three-node stencils, four DOFs per node), so the result stays in the band.
pub fn rotate_node(a: &mut BandLu, k0: usize, q: &Matrix3<f64>) {
    let n = a.dim();
    let (lo, hi) = (k0.saturating_sub(8), (k0 + 10).min(n - 1));
    for l in lo..=hi {
        let old = [a.get(k0, l), a.get(k0 + 1, l), a.get(k0 + 2, l)];
        for r in 0..3 {
            let v = q[(r, 0)] * old[0] + q[(r, 1)] * old[1] + q[(r, 2)] * old[2];
            a.add(k0 + r, l, v - old[r]);
        }
    }
    for l in lo..=hi {
        let old = [a.get(l, k0), a.get(l, k0 + 1), a.get(l, k0 + 2)];
        for c in 0..3 {
            let v = q[(c, 0)] * old[0] + q[(c, 1)] * old[1] + q[(c, 2)] * old[2];
            a.add(l, k0 + c, v - old[c]);
        }
    }
}

/// The rows around `k` that can couple with it (the band of a node block).
#[inline]
pub fn band_range(n: usize, k: usize) -> std::ops::RangeInclusive<usize> {
    let k0 = k - k % 4;
    k0.saturating_sub(8)..=(k0 + 10).min(n - 1)
}

/// Add `f` × row `from` to row `to` (a kinetic friction row), within the node's band.
pub fn add_row(a: &mut BandLu, to: usize, from: usize, f: f64) {
    for l in band_range(a.dim(), to) {
        let v = a.get(from, l);
        if v != 0.0 {
            a.add(to, l, f * v);
        }
    }
}

/// Make coordinate j prescribed: its column goes to the border (× `p`, when it follows a
/// body, for rows not in `elim`), then row and column become the identity's.
pub fn eliminate(
    a: &mut BandLu,
    j: usize,
    follow: Option<(usize, Vector6<f64>)>,
    elim: &[bool],
    border: &mut [Vec<f64>],
) {
    for l in band_range(a.dim(), j) {
        if l == j {
            continue;
        }
        let v = a.get(l, j);
        if v != 0.0 {
            if let Some((b, p)) = follow {
                if !elim[l] {
                    for c in 0..6 {
                        border[l][6 * b + c] += v * p[c];
                    }
                }
            }
            a.add(l, j, -v);
        }
        let w = a.get(j, l);
        if w != 0.0 {
            a.add(j, l, -w);
        }
    }
    let d = a.get(j, j);
    a.add(j, j, 1.0 - d);
}

/// One rod's part of the bordered system, factored.
pub struct RodBlock<'a> {
    pub a: &'a mut BandLu,
    /// Storage for the Cholesky factor of `a`, used when `symmetric` (no kinetic friction
    /// row) and `a` is positive definite; else `a` is factored by LU with pivoting.
    pub chol: &'a mut SymBand,
    pub symmetric: bool,
    pub rhs: &'a mut [f64],
    pub border: &'a [Vec<f64>],
    /// Storage for Z = A⁻¹ B (one column per body unknown), kept between calls.
    pub z: &'a mut Vec<Vec<f64>>,
    /// Rows of the body equations: (body row 0..6nb, column, value).
    pub rows: &'a [(usize, usize, f64)],
}

impl RodBlock<'_> {
    /// Factor A: by banded Cholesky when it is symmetric and positive definite (about a
    /// quarter of the work), else by LU.
    fn factor(&mut self) -> Result<(), &'static str> {
        if self.symmetric {
            self.chol.copy_lower(self.a);
            if self.chol.factor().is_ok() {
                return Ok(());
            }
            self.symmetric = false;
        }
        self.a.factor().map_err(|_| "singular Jacobian")
    }

    /// Solve A x = b in place with the factor.
    fn solve_in(&self, b: &mut [f64]) {
        if self.symmetric {
            self.chol.solve(b);
        } else {
            self.a.solve(b);
        }
    }
}

/// Solve the bordered system. `s` and `fb` are the bodies' block (with the D terms already in);
/// `kkt` are extra constraint rows on ΔX with their force columns: (row J, column K, value):
/// S δX + Σ K λ = f_b, J δX = v. Returns δX and λ; each rod's `rhs` becomes its y.
pub fn solve_bordered(
    rods: &mut [RodBlock<'_>],
    s: &DMatrix<f64>,
    fb: &DVector<f64>,
    kkt: &[(Vec<f64>, Vec<f64>, f64)],
) -> Result<(DVector<f64>, DVector<f64>), &'static str> {
    let nx = fb.len();
    for r in rods.iter_mut() {
        r.factor()?;
        let rhs = std::mem::take(&mut r.rhs);
        r.solve_in(rhs);
        r.rhs = rhs;
    }
    if nx == 0 {
        return Ok((DVector::zeros(0), DVector::zeros(0)));
    }
    let nk = kkt.len();
    let mut m = DMatrix::zeros(nx + nk, nx + nk);
    let mut f = DVector::zeros(nx + nk);
    m.view_mut((0, 0), (nx, nx)).copy_from(s);
    f.rows_mut(0, nx).copy_from(fb);
    for r in rods.iter_mut() {
        let n = r.rhs.len();
        // Z = A⁻¹ B, column by column (into storage kept from step to step).
        let mut zr = std::mem::take(&mut *r.z);
        zr.resize_with(nx, Vec::new);
        for (c, col) in zr.iter_mut().enumerate() {
            col.resize(n, 0.0);
            let mut any = false;
            for (l, row) in r.border.iter().enumerate() {
                col[l] = row[c];
                any |= row[c] != 0.0;
            }
            if any {
                r.solve_in(col);
            }
        }
        for &(row, l, v) in r.rows {
            f[row] -= v * r.rhs[l];
            for (c, col) in zr.iter().enumerate() {
                m[(row, c)] -= v * col[l];
            }
        }
        *r.z = zr;
    }
    for (i, (jrow, kcol, v)) in kkt.iter().enumerate() {
        for c in 0..nx {
            m[(nx + i, c)] = jrow[c];
            m[(c, nx + i)] = kcol[c];
        }
        f[nx + i] = *v;
    }
    let sol = m.lu().solve(&f).ok_or("singular body system")?;
    let dx = sol.rows(0, nx).into_owned();
    for r in rods.iter_mut() {
        for (c, col) in r.z.iter().enumerate() {
            if dx[c] != 0.0 {
                for (y, zc) in r.rhs.iter_mut().zip(col) {
                    *y -= zc * dx[c];
                }
            }
        }
    }
    Ok((dx, sol.rows(nx, nk).into_owned()))
}
